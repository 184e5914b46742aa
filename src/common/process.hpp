// What the operating system says of this process's memory.
#pragma once

namespace ces {

// This process's peak resident set (Linux: VmHWM) and its resident set now
// (VmRSS), in bytes; 0 where /proc/self/status does not say.
double peak_resident_bytes();
double resident_bytes();

}  // namespace ces
