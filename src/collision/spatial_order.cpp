#include "collision/spatial_order.hpp"

#include <algorithm>

namespace ces {
namespace {
// Interleaves the low 21 bits of x with two zero bits after each.
std::uint64_t spread_bits(std::uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}
}  // namespace

void SpatialOrder::apply(const Model& model, Particles& particles) {
  const Particles& p = particles;
  const std::size_t n = p.size();
  if (n < std::max<std::size_t>(2, model.reorder_min_particles)) return;
  Vec3 lo = p.position[0];
  double reach = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    lo = lo.cwiseMin(p.position[i]);
    reach = std::max(reach, bounding_radius(model, p, i));
  }
  // Cells of a particle diameter: a cell's particles touch each other.
  const double cell = reach > 0.0 ? 2.0 * reach : 1.0;
  sort_keys_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 q = (p.position[i] - lo) / cell;
    auto axis = [&](int a) {  // (a non-finite coordinate goes to cell 0)
      return spread_bits(std::uint64_t(q[a] >= 0.0 ? std::min(q[a], 2097151.0) : 0.0));
    };
    sort_keys_[i] = {axis(0) | axis(1) << 1 | axis(2) << 2, p.id[i], std::uint32_t(i)};
  }
  // By cell, then id: the order depends on the state only, not on threads.
  std::sort(sort_keys_.begin(), sort_keys_.end(), [](const SortKey& a, const SortKey& b) {
    return a.cell != b.cell ? a.cell < b.cell : a.id < b.id;
  });
  order_.resize(n);
  for (std::size_t j = 0; j < n; ++j) order_[j] = sort_keys_[j].index;
  particles.permute(order_, scratch_);
}

}  // namespace ces
