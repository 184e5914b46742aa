// When the engine's loops fork threads.
#pragma once
#include <cstddef>

namespace ces {

// Loops over fewer items (particles, contacts, bodies) than this run on one
// thread: below it OpenMP's fork and join cost more than the threads save.
inline constexpr std::ptrdiff_t kParallelMin = 256;

}  // namespace ces
