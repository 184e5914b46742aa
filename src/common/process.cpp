#include "common/process.hpp"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <string>

namespace ces {
namespace {

// The number of kB after "key:" in /proc/self/status.
double status_bytes(const std::string& key) {
  std::ifstream in("/proc/self/status");
  const std::string prefix = key + ":";
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(prefix, 0) != 0) continue;
    const double kib = std::strtod(line.c_str() + prefix.size(), nullptr);
    return kib > 0.0 ? 1024.0 * kib : 0.0;
  }
  return 0.0;
}

}  // namespace

double peak_resident_bytes() { return status_bytes("VmHWM"); }

// From /proc/self/statm (sizes in pages, the resident set second): one
// short line, read every step by the step log.
double resident_bytes() {
  std::ifstream in("/proc/self/statm");
  double size = 0.0, pages = 0.0;
  if (!(in >> size >> pages) || !(pages > 0.0)) return 0.0;
  return pages * double(::sysconf(_SC_PAGESIZE));
}

}  // namespace ces
