// The contact list: one entry per touching (or nearly touching) pair of
// spheres / sphere and surface, in a deterministic order, with a persistent
// key so impulses can be carried from one step to the next.
#pragma once
#include <compare>
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
  void append(const Contacts& other);
  // Keeps entries first + k for which keep[k], in order, and drops the rest.
  void compact_tail(std::size_t first, const std::vector<std::uint8_t>& keep);
};

}  // namespace ces
