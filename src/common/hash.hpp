// Fixed hashes: the same numbers on every platform and standard library, so
// seeds and scene fingerprints never depend on where a run happens.
#pragma once
#include <cstdint>
#include <string_view>

namespace ces {

// splitmix64's finaliser (Steele, Lea, Flood 2014): every input bit moves
// every output bit.
inline std::uint64_t mix64(std::uint64_t x) {
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// One step of splitmix64: the finaliser of x advanced by the golden gamma.
inline std::uint64_t splitmix64(std::uint64_t x) { return mix64(x + 0x9E3779B97F4A7C15ull); }

// FNV-1a, 64 bits; from `h`, the hash of the text before this one, it
// goes on hashing text written in parts.
inline std::uint64_t fnv1a(std::string_view text, std::uint64_t h = 0xCBF29CE484222325ull) {
  for (const char c : text) {
    h ^= std::uint8_t(c);
    h *= 0x100000001B3ull;
  }
  return h;
}

}  // namespace ces
