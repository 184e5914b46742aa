// What a mesh file's header promises, against what its size can hold.
#pragma once
#include <string>

namespace ces::geo {

// For a PLY or OFF file, a message when the elements its header counts
// need more bytes than the file has ("" otherwise, and for other formats):
// a header of a few bytes can promise half a billion vertices, which the
// reader would allocate and wait for before it finds them missing.
std::string promised_beyond_size(const std::string& path);

}  // namespace ces::geo
