// The contact list: one entry per touching (or nearly touching) pair of
// spheres / sphere and surface, in a deterministic order, each with its
// persistent key (model/contact_memory.hpp).
#pragma once
#include <cstdint>
#include <vector>

#include "common/math.hpp"
#include "model/contact_memory.hpp"
#include "model/model.hpp"

namespace ces {

// Solver bodies are numbered particles first (0..np-1), then machine bodies
// (np..np+nb-1). Normal points from A to B; gap < 0 is overlap.
struct Contacts {
  std::vector<std::int32_t> body_a, body_b;
  std::vector<Vec3> normal;
  std::vector<Vec3> point;       // midway between the two surfaces
  std::vector<double> gap;
  std::vector<double> radius;    // smaller sphere radius of the pair
  // The pair of materials (MaterialTable::pair_index): friction,
  // restitution and yield are MaterialTable::surfaces of it.
  std::vector<std::uint32_t> surfaces;
  std::vector<ContactKey> key;

  std::size_t size() const { return gap.size(); }
  void clear();
  void push(int a, int b, const Vec3& n, const Vec3& p, double g, double r,
            std::uint32_t surface_pair, const ContactKey& k);
  void resize(std::size_t n);
  // Writes `other`'s contacts at [at, at + other.size()), which must exist.
  void copy_at(std::size_t at, const Contacts& other);
};

}  // namespace ces
