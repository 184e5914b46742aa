// Random numbers that are the same on every platform and standard library:
// the bits of std::mt19937_64 are specified, its distributions are not.
#pragma once
#include <random>

namespace ces {

// 53 random bits to [0, 1).
inline double uniform01(std::mt19937_64& rng) { return double(rng() >> 11) * 0x1.0p-53; }

}  // namespace ces
