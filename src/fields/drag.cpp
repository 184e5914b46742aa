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

void DragStage::apply(Particles& p) const {
  const auto n = std::ptrdiff_t(p.size());
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (std::ptrdiff_t s = 0; s < n; ++s) {
    const auto i = std::size_t(s);
    const double radius = equal_volume_radius(p.mass[i] / density_[std::size_t(p.material[i])]);
    p.force[i] += drag_force(spec_, p.velocity[i], radius);
  }
}

}  // namespace ces::fields
