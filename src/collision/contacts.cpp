#include "collision/contacts.hpp"

#include <algorithm>
#include <array>

#include "common/parallel.hpp"

namespace ces {

void Contacts::clear() {
  body_a.clear();
  body_b.clear();
  normal.clear();
  point.clear();
  gap.clear();
  radius.clear();
  friction.clear();
  restitution.clear();
  key.clear();
}

void Contacts::push(int a, int b, const Vec3& n, const Vec3& p, double g, double r,
                    double mu, double e, const ContactKey& k) {
  body_a.push_back(a);
  body_b.push_back(b);
  normal.push_back(n);
  point.push_back(p);
  gap.push_back(g);
  radius.push_back(r);
  friction.push_back(mu);
  restitution.push_back(e);
  key.push_back(k);
}

void Contacts::resize(std::size_t n) {
  body_a.resize(n);
  body_b.resize(n);
  normal.resize(n);
  point.resize(n);
  gap.resize(n);
  radius.resize(n);
  friction.resize(n);
  restitution.resize(n);
  key.resize(n);
}

namespace {
template <class T>
void put(std::vector<T>& to, std::size_t at, const std::vector<T>& from) {
  std::copy(from.begin(), from.end(), to.begin() + std::ptrdiff_t(at));
}
}  // namespace

void Contacts::copy_at(std::size_t at, const Contacts& o) {
  put(body_a, at, o.body_a);
  put(body_b, at, o.body_b);
  put(normal, at, o.normal);
  put(point, at, o.point);
  put(gap, at, o.gap);
  put(radius, at, o.radius);
  put(friction, at, o.friction);
  put(restitution, at, o.restitution);
  put(key, at, o.key);
}

namespace {
// splitmix64's finaliser: every input bit moves every output bit.
std::uint64_t mix(std::uint64_t x) {
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
}  // namespace

std::size_t ContactMemory::home(const ContactKey& key) const {
  const std::uint64_t features = std::uint64_t{key.feature_a} << 32 | key.feature_b;
  return std::size_t(mix(key.a ^ mix(key.b ^ mix(features)))) & mask_;
}

void ContactMemory::assign(const std::vector<ContactKey>& keys, std::vector<Vec3>& values) {
  // Copied in parallel: 2.4 MB at 1e5 contacts, which one thread copied
  // while the other waited.
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
  // probe waiting for its own (46 ns a key at 1e5 contacts without).
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
