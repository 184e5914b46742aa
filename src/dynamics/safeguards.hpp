// What the step does after the solve so that an inexact solution cannot do
// harm (dynamics/safeguards.cpp says why each exists):
//  1. energy: a solve stopped at its cap whose impulses would create
//     kinetic energy has them scaled back along the segment to zero;
//  2. walls: contacts with walls the impulses leave violated are finished,
//     body by body (the wall guard);
//  3. sliding lift: sliding contacts with walls lose the relaxed cone's
//     normal velocity mu |v_t|;
//  4. spin: a clump in contact turns at most so far per step that its
//     spheres leave the linearised rows by a tenth of a radius.
#pragma once
#include <cstdint>
#include <vector>

#include "dynamics/ccp.hpp"
#include "model/model.hpp"
#include "model/state.hpp"
#include "model/stats.hpp"

namespace ces {

// Per-shape limits and per-body flags, kept between steps so that a step
// allocates nothing once the run has peaked.
class SafeguardScratch {
 public:
  std::vector<double> max_turn;  // per shape: rad per step in contact
  bool has_clumps = false;
  std::vector<std::uint32_t> guarded;  // contacts of capped clumps, in order
  std::vector<std::uint8_t> capped;    // per solver body: spin capped this step
  std::vector<std::uint8_t> locked;    // per solver body: guarded in translation only
  std::vector<Vec3> base_v, base_w;    // the velocities of the joints' impulses
  std::vector<std::uint8_t> moved;     // per solver body: a guard changed its impulses
  std::vector<std::uint32_t> moved_bodies;  // those bodies, in order
  explicit SafeguardScratch(const Model& model);
};

// The safeguards in the order above. gamma and bodies.v, w: the solve's
// impulses and their velocities, changed in place.
void apply_safeguards(const Model& model, const Particles& particles, const CcpProblem& problem,
                      SafeguardScratch& scratch, Span gamma, SolverBodies& bodies,
                      StepStats& stats);

}  // namespace ces
