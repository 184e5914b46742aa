#include "model/contact_memory.hpp"

#include <algorithm>
#include <array>

#include "common/hash.hpp"
#include "common/parallel.hpp"

namespace ces {

std::uint64_t ContactMemory::hash(const ContactKey& key) {
  const std::uint64_t features = std::uint64_t{key.feature_a} << 32 | key.feature_b;
  return mix64(key.a ^ mix64(key.b ^ mix64(features)));
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

// Linear probing filled in parallel: a thread claims the first empty slot
// of its key's probe sequence. Slots only go from empty to full, so every
// key ends up reachable from its home past full slots only, and a lookup
// finds the same value whatever the layout. Of a repeated key the slot
// keeps the first stored (a smaller index wins), as a serial fill would.
void ContactMemory::build_table() const {
  std::size_t capacity = 16;
  while (capacity < 2 * keys_.size()) capacity *= 2;
  slots_.resize(capacity);
  mask_ = capacity - 1;
  const auto slots = std::ptrdiff_t(capacity);
#pragma omp parallel for schedule(static) if (slots > kParallelMin)
  for (std::ptrdiff_t s = 0; s < slots; ++s) slots_[std::size_t(s)] = kEmpty;
  // The slots are written at random: each is prefetched kAhead keys before
  // its key is placed, so that the cache misses overlap instead of each
  // probe waiting for its own.
  constexpr std::size_t kAhead = 16, kBlock = 4096;
  const std::size_t n = keys_.size(), blocks = chunk_count(n, kBlock);
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::size_t b = 0; b < blocks; ++b) {
    std::array<std::uint64_t, kAhead> ahead;
    const std::size_t begin = b * kBlock, end = std::min(n, begin + kBlock);
    auto prefetch = [&](std::size_t k) {
      ahead[k % kAhead] = hash(keys_[k]);
      __builtin_prefetch(&slots_[ahead[k % kAhead] & mask_], 1);
    };
    for (std::size_t k = begin; k < std::min(end, begin + kAhead); ++k) prefetch(k);
    for (std::size_t k = begin; k < end; ++k) {
      const std::uint64_t h = ahead[k % kAhead];
      if (k + kAhead < end) prefetch(k + kAhead);
      place(h, std::uint32_t(k));
    }
  }
}

void ContactMemory::place(std::uint64_t hash, std::uint32_t k) const {
  for (std::size_t slot = hash & mask_;;) {
    std::atomic_ref<std::uint64_t> ref(slots_[slot]);
    std::uint64_t held = ref.load(std::memory_order_relaxed);
    const bool empty = held == kEmpty;
    if (!empty && !holds(held, hash, keys_[k])) {
      slot = (slot + 1) & mask_;
      continue;
    }
    if (!empty && std::uint32_t(held) < k) return;  // the same key, stored first
    if (ref.compare_exchange_strong(held, slot_value(hash, k), std::memory_order_relaxed)) return;
  }
}

void ContactMemory::index() const {
  if (built_.load(std::memory_order_acquire) || keys_.empty()) return;
  const std::lock_guard<std::mutex> lock(build_);
  if (built_.load(std::memory_order_relaxed)) return;
  build_table();
  built_.store(true, std::memory_order_release);
}

const Vec3* ContactMemory::find(const ContactKey& key) const {
  std::size_t cursor = keys_.size();
  return find(key, cursor);
}

const Vec3* ContactMemory::find_at(const ContactKey& key, std::size_t& cursor) const {
  if (cursor < keys_.size() && keys_[cursor] == key) return &values_[cursor++];
  return nullptr;
}

const Vec3* ContactMemory::find(const ContactKey& key, std::size_t& cursor) const {
  // At the cursor or a few keys past it: the contacts the last step had
  // and this one lost are passed over without a lookup in the table.
  const std::size_t near = std::min(keys_.size(), cursor + kLookAhead);
  for (std::size_t k = cursor; k < near; ++k)
    if (keys_[k] == key) {
      cursor = k + 1;
      return &values_[k];
    }
  if (keys_.empty()) return nullptr;
  index();
  const std::uint64_t h = hash(key);
  for (std::size_t s = h & mask_; slots_[s] != kEmpty; s = (s + 1) & mask_)
    if (holds(slots_[s], h, key)) {
      const std::uint32_t k = std::uint32_t(slots_[s]);
      cursor = std::size_t(k) + 1;
      return &values_[k];
    }
  return nullptr;
}

}  // namespace ces
