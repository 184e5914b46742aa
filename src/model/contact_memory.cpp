#include "model/contact_memory.hpp"

#include <algorithm>
#include <array>

#include "common/hash.hpp"
#include "common/parallel.hpp"

namespace ces {

std::size_t ContactMemory::home(const ContactKey& key) const {
  const std::uint64_t features = std::uint64_t{key.feature_a} << 32 | key.feature_b;
  return std::size_t(mix64(key.a ^ mix64(key.b ^ mix64(features)))) & mask_;
}

void ContactMemory::assign(const std::vector<ContactKey>& keys, std::vector<Vec3>& values) {
  // Copied in parallel: 24 bytes a key, which one thread would copy while
  // the others wait.
  keys_.resize(keys.size());
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(keys.size()) > kParallelMin)
  for (std::ptrdiff_t k = 0; k < std::ptrdiff_t(keys.size()); ++k)
    keys_[std::size_t(k)] = keys[std::size_t(k)];
  values_.swap(values);
  built_.store(false, std::memory_order_release);
}

void ContactMemory::build_table() const {
  std::size_t capacity = 16;
  while (capacity < 2 * keys_.size()) capacity *= 2;
  slots_.assign(capacity, kEmpty);
  mask_ = capacity - 1;
  // The slots are written at random: each is prefetched kAhead keys before
  // its key is placed, so that the cache misses overlap instead of each
  // probe waiting for its own.
  constexpr std::size_t kAhead = 16;
  std::array<std::size_t, kAhead> ahead;
  const std::size_t n = keys_.size();
  auto prefetch = [&](std::size_t k) {
    ahead[k % kAhead] = home(keys_[k]);
    __builtin_prefetch(&slots_[ahead[k % kAhead]], 1);
  };
  for (std::size_t k = 0; k < std::min(n, kAhead); ++k) prefetch(k);
  for (std::size_t k = 0; k < n; ++k) {
    std::size_t slot = ahead[k % kAhead];
    if (k + kAhead < n) prefetch(k + kAhead);
    while (slots_[slot] != kEmpty) slot = (slot + 1) & mask_;
    slots_[slot] = std::uint32_t(k);
  }
}

const Vec3* ContactMemory::find(const ContactKey& key) const {
  std::size_t cursor = keys_.size();
  return find(key, cursor);
}

const Vec3* ContactMemory::find(const ContactKey& key, std::size_t& cursor) const {
  if (cursor < keys_.size() && keys_[cursor] == key) return &values_[cursor++];
  if (keys_.empty()) return nullptr;
  if (!built_.load(std::memory_order_acquire)) {
    const std::lock_guard<std::mutex> lock(build_);
    if (!built_.load(std::memory_order_relaxed)) {
      build_table();
      built_.store(true, std::memory_order_release);
    }
  }
  for (std::size_t s = home(key); slots_[s] != kEmpty; s = (s + 1) & mask_)
    if (keys_[slots_[s]] == key) {
      cursor = slots_[s] + 1;
      return &values_[slots_[s]];
    }
  return nullptr;
}

}  // namespace ces
