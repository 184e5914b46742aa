// VTK XML PolyData files (.vtp), binary: the XML names each array, and the
// arrays' bytes follow in one appended, raw block, each array compressed
// with zlib in blocks of 32 KiB (header: UInt64 block count, block size,
// last block's size, then each block's compressed size), as VTK's
// vtkXMLPolyDataWriter writes them with its zlib compressor. ParaView and
// VTK read them; equal arrays give equal bytes.
#pragma once
#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace ces::output {

static_assert(std::endian::native == std::endian::little,
              "the .vtp files say byte_order=\"LittleEndian\"");

// VTK's name of an array element type.
template <class T>
constexpr const char* vtk_type() {
  if constexpr (std::is_same_v<T, double>) return "Float64";
  else if constexpr (std::is_same_v<T, float>) return "Float32";
  else if constexpr (std::is_same_v<T, std::int32_t>) return "Int32";
  else if constexpr (std::is_same_v<T, std::int64_t>) return "Int64";
  else if constexpr (std::is_same_v<T, std::uint64_t>) return "UInt64";
  else static_assert(sizeof(T) == 0, "no VTK type for this element type");
}

// Where an array goes in the file.
enum class VtkSection { Field, PointData, CellData, Points, Verts, Polys };

// One .vtp file of a single piece, built array by array.
class VtpFile {
 public:
  explicit VtpFile(std::size_t points) : points_(points) {}

  // `components` values per tuple, tuples in order.
  template <class T>
  void add(VtkSection section, const std::string& name, int components, std::span<const T> values) {
    add_bytes(section, name, vtk_type<T>(), components, values.size() / std::size_t(components),
              {reinterpret_cast<const char*>(values.data()), values.size_bytes()});
  }
  template <class T>
  void add(VtkSection section, const std::string& name, int components,
           const std::vector<T>& values) {
    add(section, name, components, std::span<const T>(values));
  }
  // A String array: one text per tuple.
  void add_strings(VtkSection section, const std::string& name,
                   const std::vector<std::string>& values);
  // Names the array ParaView shows first: `attribute` is "Scalars" or
  // "Vectors" of the PointData or CellData.
  void set_active(VtkSection section, const char* attribute, const std::string& name);

  // Each point a vertex cell.
  void add_vertex_per_point();
  // Polygons: polygon k has the points connectivity[offsets[k - 1] .. offsets[k]).
  void add_polygons(const std::vector<std::int64_t>& connectivity,
                    const std::vector<std::int64_t>& offsets);

  // The file's bytes.
  std::string finish() const;

 private:
  void add_bytes(VtkSection section, const std::string& name, const char* type, int components,
                 std::size_t tuples, std::string_view bytes);

  std::size_t points_, verts_ = 0, polys_ = 0;
  std::string attributes_[6];  // of each section's element
  std::string xml_[6];         // the <DataArray> elements of each section
  std::string appended_;       // the compressed arrays, one after the other
};

}  // namespace ces::output
