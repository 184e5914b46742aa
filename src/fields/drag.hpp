// Air drag on the particles, from each particle's velocity relative to
// still air: a force stage (sim/world.hpp runs it after this step's
// collision and before its solve). A sphere cluster feels the drag of its
// equal-volume sphere, r = (3V/4π)^⅓ with V = mass / density (a drawn flake's
// own volume, not its contact geometry's), at its centre of mass. Every
// particle is updated by its own loop iteration, so forces are bitwise the
// same for any thread count.
#pragma once
#include <vector>

#include "fields/charge.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces::fields {

enum class DragLaw { Stokes, SchillerNaumann };

// Drag from the particle's velocity relative to still air (docs/physics.md §6).
struct DragSpec {
  Air air;  // density and viscosity (its permittivity is not used here)
  DragLaw law = DragLaw::SchillerNaumann;
};

// Adds each particle's drag to its force (the forces stage). Reads the
// particles' velocity, mass and material; writes their force.
class DragStage {
 public:
  // Throws std::invalid_argument for a non-positive viscosity or density.
  DragStage(DragSpec spec, const Model& model);
  // Adds each particle's drag for a step of h; returns how many had it
  // held to stopping them against the air within the step (see drag.cpp).
  std::size_t apply(Particles& particles, double h) const;

 private:
  DragSpec spec_;
  std::vector<double> density_;  // per material
};

}  // namespace ces::fields
