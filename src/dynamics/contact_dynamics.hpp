// The contact dynamics of a step, as four stages over the state:
//   assemble   the bodies' free motion and the cone complementarity problem
//              of this step's contacts and joints, warm-started from the last
//              step's impulses;
//   solve      the problem (dynamics/solvers.hpp);
//   safeguards what a solve stopped at its cap must not do (create energy,
//              leave a particle in a wall), the relaxed cone's sliding lift
//              on walls, and the spin of clumps (dynamics/safeguards.hpp);
//              then the walls a particle would cross beyond its envelope,
//              where no contact was listed (dynamics/unlisted_walls.hpp);
//   integrate  semi-implicit Euler from the new velocities, and the impulses
//              remembered for the next step's warm start.
// Under ContactModel::DEM, assemble also applies the penalty contact forces
// (dynamics/dem.hpp) and the problem keeps only the joints' rows.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include "collision/contacts.hpp"
#include "dynamics/ccp.hpp"
#include "dynamics/dem.hpp"
#include "dynamics/joints.hpp"
#include "dynamics/safeguards.hpp"
#include "dynamics/solvers.hpp"
#include "model/model.hpp"
#include "model/state.hpp"
#include "model/stats.hpp"

namespace ces {

class ContactDynamics {
 public:
  ContactDynamics(const Model& model, const Bodies& bodies);

  // Reads the state's particles, bodies and warm-start memory; writes the
  // step's penetration and joint drift into stats.
  void assemble(const Model& model, State& state, const Contacts& contacts, StepStats& stats);
  void solve(const Model& model, StepStats& stats);
  // envelope: each particle's, within which its contacts were listed.
  void safeguard(const Model& model, const State& state, std::span<const double> envelope,
                 StepStats& stats);
  // Writes the particles' and dynamic bodies' motion, and the warm start.
  void integrate(const Model& model, State& state, const Contacts& contacts);

  // Last step's impulses: 3 per contact (normal, t1, t2), then bilateral rows.
  ConstSpan impulses() const { return gamma_; }

 private:
  void build_solver_bodies(const Model& model, const State& state);
  void measure_penetration(const Model& model, const Particles& particles,
                           const Contacts& contacts, StepStats& stats) const;

  std::vector<JointFrame> joint_frames_;
  SafeguardScratch safeguards_;
  SolverBodies solver_bodies_;
  CcpProblem problem_;
  std::vector<BilateralRow> rows_;
  SolverWorkspace workspace_;
  std::vector<double> gamma_;
  std::vector<Vec3> impulse_scratch_;
  DemContacts dem_;
};

}  // namespace ces
