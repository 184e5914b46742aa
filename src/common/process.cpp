#include "common/process.hpp"

#include <fstream>
#include <string>

namespace ces {
namespace {

double status_bytes(const std::string& key) {
  std::ifstream in("/proc/self/status");
  const std::string prefix = key + ":";
  for (std::string line; std::getline(in, line);)
    if (line.rfind(prefix, 0) == 0) return 1024.0 * std::stod(line.substr(prefix.size()));  // kB
  return 0.0;
}

}  // namespace

double peak_resident_bytes() { return status_bytes("VmHWM"); }
double resident_bytes() { return status_bytes("VmRSS"); }

}  // namespace ces
