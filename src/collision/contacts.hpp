// The contact list: one entry per touching (or nearly touching) pair of
// spheres / sphere and surface, in a deterministic order, with a persistent
// key so impulses can be carried from one step to the next.
#pragma once
#include <atomic>
#include <compare>
#include <mutex>
#include <cstdint>
#include <vector>

#include "common/math.hpp"

namespace ces {

// Persistent identity of a contact: the two objects (particle ids, or
// kBodyTag | body index for machine bodies) and the feature on each (the
// sphere of a cluster, the face/edge/vertex of a mesh).
struct ContactKey {
  std::uint64_t a = 0, b = 0;
  std::uint32_t feature_a = 0, feature_b = 0;
  auto operator<=>(const ContactKey&) const = default;
};
inline constexpr std::uint64_t kBodyTag = std::uint64_t{1} << 63;

// Solver bodies are numbered particles first (0..np-1), then machine bodies
// (np..np+nb-1). Normal points from A to B; gap < 0 is overlap.
struct Contacts {
  std::vector<std::int32_t> body_a, body_b;
  std::vector<Vec3> normal;
  std::vector<Vec3> point;       // midway between the two surfaces
  std::vector<double> gap;
  std::vector<double> radius;    // smaller sphere radius of the pair
  std::vector<double> friction;
  std::vector<double> restitution;
  std::vector<ContactKey> key;

  std::size_t size() const { return gap.size(); }
  void clear();
  void push(int a, int b, const Vec3& n, const Vec3& p, double g, double r,
            double mu, double e, const ContactKey& k);
  void resize(std::size_t n);
  // Writes `other`'s contacts at [at, at + other.size()), which must exist.
  void copy_at(std::size_t at, const Contacts& other);
};

// A vector per contact, kept from one step to the next and found by key:
// the warm start's impulses, DEM's tangential springs. Lookups try the
// key's place in the last step's order first (a cursor); those that miss go
// to a hash table (linear probing, at most half full), built on the first
// miss: O(n) for n keys, where sorting them cost n log n a step on one
// thread (the collider emits contacts in particle-index order, which the
// spatial reordering makes unlike key order: in ces_pcb at 2 threads that
// sort took 4.5 % of the main thread's time while the other waited). A
// key finds its value whatever order the keys were stored in, so what a
// step finds does not depend on threads.
class ContactMemory {
 public:
  // Replaces the contents by keys[k] -> values[k]. The keys are distinct
  // (the collider's are; a repeated one finds one of its values, the same
  // for any thread count). The values are swapped in, not copied: `values`
  // comes back holding the memory's previous buffer, for the caller to
  // fill next step without allocating.
  void assign(const std::vector<ContactKey>& keys, std::vector<Vec3>& values);
  const Vec3* find(const ContactKey& key) const;  // nullptr: not stored
  // The same, trying first the key stored at `cursor` and moving it past
  // the key found: a scan in the order the keys were stored reads them in
  // sequence and never builds the table (a bed at rest), where hashed
  // lookups cost a cache miss each (75 ns at 3e5 contacts). Safe to call
  // from several threads at once.
  const Vec3* find(const ContactKey& key, std::size_t& cursor) const;
  std::size_t size() const { return keys_.size(); }

 private:
  static constexpr std::uint32_t kEmpty = ~std::uint32_t{0};
  std::size_t home(const ContactKey& key) const;
  void build_table() const;
  std::vector<ContactKey> keys_;  // in the order stored
  std::vector<Vec3> values_;
  // The hash table, made by the first lookup that misses its cursor.
  mutable std::vector<std::uint32_t> slots_;  // index into keys_, or kEmpty
  mutable std::size_t mask_ = 0;
  mutable std::atomic<bool> built_{false};
  mutable std::mutex build_;
};

}  // namespace ces
