// Paths as the commands that take them from a scene or a study name them.
#pragma once
#include <filesystem>

namespace ces {

// A path made absolute against the working directory ("" is that directory
// itself), with no '.' or '..' left in it. Links stay: a scene's includes
// and name come from the path it is given.
inline std::filesystem::path absolute_path(const std::filesystem::path& p) {
  return std::filesystem::absolute(p.empty() ? std::filesystem::path(".") : p).lexically_normal();
}

}  // namespace ces
