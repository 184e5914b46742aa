// Wall-clock time for the stage timers and progress lines.
#pragma once
#include <chrono>

namespace ces {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace ces
