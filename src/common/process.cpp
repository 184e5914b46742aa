#include "common/process.hpp"

#include <fcntl.h>
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
// short line, read every step by the step log, so the file stays open and
// is read from its start into the stack, with no allocation in the step.
double resident_bytes() {
  static const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
  char text[128];
  const ssize_t got = fd < 0 ? -1 : ::pread(fd, text, sizeof text - 1, 0);
  if (got <= 0) return 0.0;
  text[got] = '\0';
  char* rest = nullptr;
  std::strtod(text, &rest);  // the total size, before the resident set
  const double pages = std::strtod(rest, nullptr);
  return pages > 0.0 ? pages * double(::sysconf(_SC_PAGESIZE)) : 0.0;
}

}  // namespace ces
