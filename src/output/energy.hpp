// Energy balance of a run (summary.json "energy").
//
// E = kinetic (translation + rotation) + gravitational potential (-m g.x) of
// the particles and the dynamic bodies. Measured three times a step, so the
// feeds and the collectors, which add and remove energy with their
// particles, are kept apart from the dynamics:
//   fed      += E after the feeds      - E at the end of the previous step
//   dynamics += E before the collectors - E after the feeds
//   removed  += E before the collectors - E after them
// In a passive scene (nothing moves a body or pushes a particle: no moving
// kinematic body, no motor, no electric force; gravity is conservative and
// air drag only takes energy) the exact dynamics can only lose energy
// (friction, inelastic impacts, drag): the running sum of `dynamics` never
// rises. Its largest rise over any stretch of the run (not only from the
// start, where early losses would hide later gains) is the energy the
// numerics created: stabilisation pushing overlaps apart, a solver stopped
// early, explicit DEM springs. Not counted: the elastic energy in DEM
// springs, so under DEM a rebound gives back what the compression took and
// the rise is an upper bound of the numerical gain.
// Elsewhere the balance is "n/a", with the reason.
#pragma once
#include <string>

#include "common/serial.hpp"
#include "model/model.hpp"
#include "model/state.hpp"
#include "model/stats.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

struct EnergyBalance {
  std::string not_passive;  // why the balance does not apply; empty if it does
  double initial = 0.0, fed = 0.0, removed = 0.0, final = 0.0;  // J
  double dissipated = 0.0;    // initial + fed - removed - final (J)
  double max_gain = 0.0;      // largest rise of the dynamics' running sum (J, >= 0)
  double peak_kinetic = 0.0;  // largest kinetic energy at a step's end (J)
  // max_gain / peak_kinetic: the gain against the energy in motion.
  double max_gain_relative() const { return peak_kinetic > 0.0 ? max_gain / peak_kinetic : 0.0; }
};

// Kinetic and potential energy of the particles and dynamic bodies (J),
// leaving out particles whose state is no longer finite.
struct MechanicalEnergy {
  double kinetic = 0.0, potential = 0.0;
  double total() const { return kinetic + potential; }
};
MechanicalEnergy mechanical_energy(const Model& model, const State& state);

// Rotational kinetic energy of a body with principal inertia `inertia`
// (body frame, orientation q) turning at world angular velocity w.
double rotational_energy(const Quat& q, const Vec3& inertia, const Vec3& w);

// Why a scene is not passive ("kinematic body 'drum' moves"), or "".
std::string why_not_passive(const Simulation& sim);

class EnergyLedger {
 public:
  EnergyLedger(const Simulation& sim, const State& state);
  // Measures where the balance needs it: after the feed stage, and on both
  // sides of the collect stage (after integrate, after collect).
  void after(Stage stage, const State& state);
  const EnergyBalance& balance() const { return balance_; }

  // The sums so far, for checkpoints.
  void save(ByteWriter& out) const;
  void load(ByteReader& in);

 private:
  void after_feeds(const State& state);
  void before_collectors(const State& state);
  void after_collectors(const State& state);

  const Model* model_;
  EnergyBalance balance_;
  double last_ = 0.0;      // E at the last measurement
  double dynamics_ = 0.0;  // running sum of the dynamics' change
  double lowest_ = 0.0;    // its lowest value so far
};

}  // namespace ces::output
