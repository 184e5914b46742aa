#include "geometry/mesh_header.hpp"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace ces::geo {
namespace {

// The fewest bytes a PLY property takes: two in ASCII (a digit and a
// space), its type's size in binary (a list: its count's).
double property_bytes(bool ascii, const std::string& type) {
  if (ascii) return 2.0;
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1.0;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2.0;
  if (type == "double" || type == "float64") return 8.0;
  return 4.0;
}

// The fewest bytes the elements a PLY header counts take (0 where the
// header cannot be read: the reader then says what is wrong).
double ply_bytes(std::istream& in) {
  std::string line, word;
  bool ascii = true;
  double total = 0.0, count = 0.0, per_element = 0.0;
  while (std::getline(in, line) && line.rfind("end_header", 0) != 0) {
    std::istringstream words(line);
    words >> word;
    if (word == "format") {
      words >> word;
      ascii = word == "ascii";
    } else if (word == "element") {
      total += count * per_element;
      words >> word >> count;
      per_element = 0.0;
    } else if (word == "property") {
      words >> word;
      if (word == "list") words >> word;  // the count's type
      per_element += property_bytes(ascii, word);
    }
    if (!words && word != "property") return 0.0;
  }
  return total + count * per_element;
}

// OFF: a vertex line takes at least "0 0 0\n", a face line "0\n".
double off_bytes(std::istream& in) {
  std::string magic;
  double vertices = 0.0, faces = 0.0;
  if (!(in >> magic >> vertices >> faces)) return 0.0;
  return 6.0 * vertices + 2.0 * faces;
}

}  // namespace

std::string promised_beyond_size(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string magic(3, '\0');
  if (!in.read(magic.data(), 3)) return "";
  in.seekg(0);
  const double needed = magic == "ply" ? ply_bytes(in) : magic == "OFF" ? off_bytes(in) : 0.0;
  const auto size = double(std::filesystem::file_size(path));
  if (!(needed > size)) return "";
  std::ostringstream message;
  message << "its header promises elements of at least " << needed << " bytes, and the file has "
          << size;
  return message.str();
}

}  // namespace ces::geo
