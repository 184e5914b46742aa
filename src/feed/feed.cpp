#include "feed/feed.hpp"

#include <algorithm>
#include <cmath>

namespace ces {

const DrawnShape::Rung& DrawnShape::rung(double thickness, double extent) const {
  const double aspect = thickness / extent;
  const Rung* best = &ladder.front();
  for (const Rung& r : ladder)
    if (std::abs(std::log(r.aspect / aspect)) < std::abs(std::log(best->aspect / aspect))) best = &r;
  return *best;
}

double DrawnShape::volume(double t, double extent) const {
  if (kind == Kind::Flake) return 0.25 * kPi * extent * extent * t;
  const double length = std::max(extent, t);  // a rod shorter than thick is a sphere
  return 0.25 * kPi * t * t * (length - t) + kPi * t * t * t / 6.0;
}

double DrawnShape::largest_bounding_radius(const std::vector<ParticleShape>& shapes) const {
  const double largest = extent.quantile_by_number(1.0);
  double radius = 0.0;
  for (const Rung& r : ladder)
    radius = std::max(radius, largest / r.extent * shapes.at(std::size_t(r.shape)).bounding_radius);
  return radius;
}

// A disc (diameter w, thickness t): w²/8 about its normal, w²/16 + t²/12
// across. A rod as a cylinder (diameter t, length L): t²/8 about its axis,
// t²/16 + L²/12 across. The flake shape's normal is its principal axis of
// largest inertia, the rod's axis that of the smallest.
Vec3 DrawnShape::unit_inertia(double t, double extent, const Vec3& shape_unit_inertia) const {
  int special = 0;
  for (int k = 1; k < 3; ++k) {
    const bool pick = kind == Kind::Flake ? shape_unit_inertia[k] > shape_unit_inertia[special]
                                          : shape_unit_inertia[k] < shape_unit_inertia[special];
    if (pick) special = k;
  }
  Vec3 out;
  for (int k = 0; k < 3; ++k) {
    if (kind == Kind::Flake)
      out[k] = k == special ? extent * extent / 8.0 : extent * extent / 16.0 + t * t / 12.0;
    else
      out[k] = k == special ? t * t / 8.0 : t * t / 16.0 + extent * extent / 12.0;
  }
  return out;
}

}  // namespace ces
