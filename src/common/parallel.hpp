// When the engine's loops fork threads.
#pragma once
#include <cstddef>

namespace ces {

// Loops over fewer items (particles, contacts, bodies) than this run on one
// thread: below it OpenMP's fork and join cost more than the threads save.
inline constexpr std::ptrdiff_t kParallelMin = 256;

// A T on cache lines of its own, for the per-chunk buffers that threads
// fill side by side (dynamic schedules hand neighbouring chunks to
// different threads). A std::vector's header is 24 bytes: packed, the
// neighbours' headers shared lines, and every push_back moved a line
// between the cores. The broadphase's sweep of a 34,000-sphere bed took
// 3.5-4.0 ms on two threads against 3.3 on one; 1.8 ms with this.
template <class T>
struct alignas(64) OwnLine : T {};

}  // namespace ces
