// What a contact carries from one step to the next (the warm start's
// impulses, DEM's tangential springs), found by the contact's persistent key.
// Part of the state: a checkpoint holds it.
#pragma once
#include <atomic>
#include <compare>
#include <cstdint>
#include <mutex>
#include <vector>

#include "common/math.hpp"

namespace ces {

// Persistent identity of a contact: the two objects (particle ids, or
// kBodyTag | body index for machine bodies) and the feature on each (the
// sphere of a cluster; its plate's face or rim as kPlateFeature or
// kRimFeature, or its hull's edge k as kEdgeFeature | k; the
// face/edge/vertex of a mesh).
struct ContactKey {
  std::uint64_t a = 0, b = 0;
  std::uint32_t feature_a = 0, feature_b = 0;
  auto operator<=>(const ContactKey&) const = default;
};
inline constexpr std::uint64_t kBodyTag = std::uint64_t{1} << 63;
inline constexpr std::uint32_t kPlateFeature = 0xFFFFFFFFu;
inline constexpr std::uint32_t kRimFeature = 0xFFFFFFFEu;
inline constexpr std::uint32_t kEdgeFeature = 0x80000000u;

// A vector per contact, kept from one step to the next and found by key:
// the warm start's impulses, DEM's tangential springs. Lookups try the
// key's place in the last step's order first (a cursor); those that miss go
// to a hash table (linear probing, at most half full), built on the first
// miss: O(n) for n keys, where sorting them would cost n log n a step on
// one thread while the others wait (the collider emits contacts in
// particle-index order, which the spatial reordering makes unlike key
// order). A key finds its value whatever order the keys were stored in, so
// what a step finds does not depend on threads.
class ContactMemory {
 public:
  // Replaces the contents by keys[k] -> values[k]. The keys are distinct
  // (the collider's are; a repeated one finds one of its values, the same
  // for any thread count). The values are swapped in, not copied: `values`
  // comes back holding the memory's previous buffer, for the caller to
  // fill next step without allocating.
  void assign(const std::vector<ContactKey>& keys, std::vector<Vec3>& values);
  const Vec3* find(const ContactKey& key) const;  // nullptr: not stored
  // The same, trying first the keys stored at `cursor` and the few after
  // it, and moving it past the key found: a scan in the order the keys
  // were stored reads them in sequence and never builds the table (a bed
  // at rest), where hashed lookups cost a cache miss each. Safe to call
  // from several threads at once.
  const Vec3* find(const ContactKey& key, std::size_t& cursor) const;
  // The key stored at `cursor`'s value (and the cursor past it), or
  // nullptr: the key may still be stored elsewhere (find). Never builds
  // the table.
  const Vec3* find_at(const ContactKey& key, std::size_t& cursor) const;
  // Builds the hash table now, on the threads, if it is not built: for a
  // caller about to look up keys that missed their cursors from a parallel
  // loop, where the first miss would build it on one thread while the
  // others wait.
  void index() const;
  std::size_t size() const { return keys_.size(); }
  const std::vector<ContactKey>& keys() const { return keys_; }
  const std::vector<Vec3>& values() const { return values_; }

 private:
  // A slot holds a key's index into keys_ in its low half and the high
  // half of the key's hash in its high half: a probe passes over a slot
  // of another key on the hashes alone, without reading keys_ (a cache
  // miss each).
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
  static constexpr std::size_t kLookAhead = 8;  // keys find(key, cursor) tries in order
  static std::uint64_t hash(const ContactKey& key);
  static std::uint64_t slot_value(std::uint64_t hash, std::uint32_t k) {
    return (hash & ~std::uint64_t{0xffffffff}) | k;
  }
  // Whether a slot holds `key`, whose hash is `hash`: keys_ is read only
  // where the hashes' high halves agree.
  bool holds(std::uint64_t value, std::uint64_t hash, const ContactKey& key) const {
    return (value ^ hash) >> 32 == 0 && keys_[std::uint32_t(value)] == key;
  }
  void build_table() const;
  // Puts key k in the first slot from its home on that is empty or holds
  // the same key stored later.
  void place(std::uint64_t hash, std::uint32_t k) const;
  std::vector<ContactKey> keys_;  // in the order stored
  std::vector<Vec3> values_;
  // The hash table, made by the first lookup that misses its cursor.
  mutable std::vector<std::uint64_t> slots_;  // slot_value, or kEmpty
  mutable std::size_t mask_ = 0;
  mutable std::atomic<bool> built_{false};
  mutable std::mutex build_;
};

}  // namespace ces
