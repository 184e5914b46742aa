#include "output/vtk_xml.hpp"

#include <zlib.h>

#include <numeric>
#include <stdexcept>

#include "common/parallel.hpp"
#include "output/format.hpp"

namespace ces::output {
namespace {

constexpr std::size_t kBlock = 32768;  // uncompressed bytes per block, as VTK's writer

template <class T>
void append_raw(std::string& out, T value) {
  char bytes[sizeof value];
  std::memcpy(bytes, &value, sizeof value);
  out.append(bytes, sizeof value);
}

// The header and the compressed blocks of one array.
std::string compress_array(std::string_view bytes) {
  const std::size_t blocks = chunk_count(bytes.size(), kBlock);
  std::string data;
  std::vector<std::uint64_t> sizes;
  std::vector<Bytef> buffer(compressBound(kBlock));
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::string_view block = bytes.substr(b * kBlock, kBlock);
    uLongf size = uLongf(buffer.size());
    if (compress2(buffer.data(), &size, reinterpret_cast<const Bytef*>(block.data()),
                  uLong(block.size()), Z_DEFAULT_COMPRESSION) != Z_OK)
      throw std::runtime_error("zlib failed to compress a trajectory array");
    data.append(reinterpret_cast<const char*>(buffer.data()), size);
    sizes.push_back(size);
  }
  std::string out;
  append_raw<std::uint64_t>(out, blocks);
  append_raw<std::uint64_t>(out, kBlock);
  append_raw<std::uint64_t>(out, bytes.size() % kBlock);  // 0: the last block is whole
  for (const std::uint64_t s : sizes) append_raw(out, s);
  return out + data;
}

const char* section_tag(VtkSection s) {
  switch (s) {
    case VtkSection::Field: return "FieldData";
    case VtkSection::PointData: return "PointData";
    case VtkSection::CellData: return "CellData";
    case VtkSection::Points: return "Points";
    case VtkSection::Verts: return "Verts";
    case VtkSection::Polys: return "Polys";
  }
  return "";
}

}  // namespace

void VtpFile::add_bytes(VtkSection section, const std::string& name, const char* type,
                        int components, std::size_t tuples, std::string_view bytes) {
  std::string& xml = xml_[int(section)];
  xml += "        <DataArray type=\"";
  xml += type;
  xml += "\" Name=\"" + xml_escape(name) + "\" NumberOfComponents=\"";
  append_number(xml, components);
  if (section == VtkSection::Field) {  // field data has no points to count its tuples
    xml += "\" NumberOfTuples=\"";
    append_number(xml, std::uint64_t(tuples));
  }
  xml += "\" format=\"appended\" offset=\"";
  append_number(xml, std::uint64_t(appended_.size()));
  xml += "\"/>\n";
  appended_ += compress_array(bytes);
}

void VtpFile::add_strings(VtkSection section, const std::string& name,
                          const std::vector<std::string>& values) {
  std::string bytes;
  for (const std::string& v : values) bytes.append(v).push_back('\0');
  add_bytes(section, name, "String", 1, values.size(), bytes);
}

void VtpFile::set_active(VtkSection section, const char* attribute, const std::string& name) {
  attributes_[int(section)] += std::string(" ") + attribute + "=\"" + xml_escape(name) + "\"";
}

void VtpFile::add_vertex_per_point() {
  std::vector<std::int64_t> connectivity(points_), offsets(points_);
  std::iota(connectivity.begin(), connectivity.end(), std::int64_t{0});
  std::iota(offsets.begin(), offsets.end(), std::int64_t{1});
  add(VtkSection::Verts, "connectivity", 1, connectivity);
  add(VtkSection::Verts, "offsets", 1, offsets);
  verts_ = points_;
}

void VtpFile::add_polygons(const std::vector<std::int64_t>& connectivity,
                           const std::vector<std::int64_t>& offsets) {
  add(VtkSection::Polys, "connectivity", 1, connectivity);
  add(VtkSection::Polys, "offsets", 1, offsets);
  polys_ = offsets.size();
}

std::string VtpFile::finish() const {
  std::string out =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
      "header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">\n"
      "  <PolyData>\n";
  if (!xml_[int(VtkSection::Field)].empty())
    out += "    <FieldData>\n" + xml_[int(VtkSection::Field)] + "    </FieldData>\n";
  out += "    <Piece NumberOfPoints=\"";
  append_number(out, std::uint64_t(points_));
  out += "\" NumberOfVerts=\"";
  append_number(out, std::uint64_t(verts_));
  out += "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"";
  append_number(out, std::uint64_t(polys_));
  out += "\">\n";
  for (const VtkSection s : {VtkSection::PointData, VtkSection::CellData, VtkSection::Points,
                             VtkSection::Verts, VtkSection::Polys}) {
    const std::string& xml = xml_[int(s)];
    if (xml.empty()) continue;
    out += std::string("      <") + section_tag(s) + attributes_[int(s)] + ">\n" + xml +
           "      </" + section_tag(s) + ">\n";
  }
  out += "    </Piece>\n  </PolyData>\n  <AppendedData encoding=\"raw\">\n   _";
  out += appended_;
  out += "\n  </AppendedData>\n</VTKFile>\n";
  return out;
}

}  // namespace ces::output
