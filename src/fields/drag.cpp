#include "fields/drag.hpp"

#include <cstddef>
#include <stdexcept>

#include "common/parallel.hpp"

namespace ces::fields {
namespace {

Vec3 drag_force(const DragSpec& spec, const Vec3& velocity, double radius) {
  if (spec.law == DragLaw::Stokes) return stokes_drag(velocity, radius, spec.air);
  return schiller_naumann_drag(velocity, radius, spec.air);
}

}  // namespace

DragStage::DragStage(DragSpec spec, const Model& model) : spec_(spec) {
  if (!(spec_.air.viscosity > 0.0 && spec_.air.density > 0.0))
    throw std::invalid_argument("drag: air viscosity and density must be positive");
  for (const Material& m : model.materials.materials()) density_.push_back(m.density);
}

// The drag is explicit: over a step longer than a particle's relaxation
// time (Stokes: ρ d² / 18η, 0.4 ms for a 10 µm PVC grain in air) it would
// turn the particle round against the air, further each step, and throw it
// out at km/s. Held to stopping it against the air in the step, the
// particle stays bounded (its settling speed is then g h, not g τ, which
// the run's warning says); a particle whose drag does not overshoot, every
// particle of the separator scenes, keeps its force to the bit.
std::size_t DragStage::apply(Particles& p, double h) const {
  const auto n = std::ptrdiff_t(p.size());
  std::size_t held = 0;
#pragma omp parallel for schedule(static) reduction(+ : held) if (n > kParallelMin)
  for (std::ptrdiff_t s = 0; s < n; ++s) {
    const auto i = std::size_t(s);
    const double radius = equal_volume_radius(p.mass[i] / density_[std::size_t(p.material[i])]);
    Vec3 f = drag_force(spec_, p.velocity[i], radius);
    const double change = h * f.norm(), speed = p.mass[i] * p.velocity[i].norm();
    if (change > speed) {
      f *= speed / change;
      ++held;
    }
    p.force[i] += f;
  }
  return held;
}

}  // namespace ces::fields
