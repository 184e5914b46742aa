#include "output/energy.hpp"

#include <algorithm>
#include <cmath>

namespace ces::output {

double rotational_energy(const Quat& q, const Vec3& inertia, const Vec3& w) {
  const Vec3 wb = q.conjugate() * w;
  return 0.5 * wb.dot(inertia.cwiseProduct(wb));
}

MechanicalEnergy mechanical_energy(const Model& m, const State& state) {
  const Particles& p = state.particles;
  MechanicalEnergy e;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double kinetic = 0.5 * p.mass[i] * p.velocity[i].squaredNorm() +
                           rotational_energy(p.orientation[i], p.inv_inertia[i].cwiseInverse(),
                                             p.angular_velocity[i]);
    const double potential = -p.mass[i] * m.gravity.dot(p.position[i]);
    // A non-finite particle is about to be removed and reported as lost
    // ("non-finite state"); counted here, it would turn every sum into NaN.
    if (!std::isfinite(kinetic + potential)) continue;
    e.kinetic += kinetic;
    e.potential += potential;
  }
  const Bodies& b = state.bodies;
  for (std::size_t k = 0; k < m.bodies.size(); ++k) {
    const RigidBody& body = m.bodies[k];
    if (body.kind != BodyKind::Dynamic) continue;
    e.kinetic += 0.5 * body.mass * b.velocity[k].squaredNorm() +
                 rotational_energy(b.pose[k].orientation, body.inertia, b.angular_velocity[k]);
    e.potential -= body.mass * m.gravity.dot(b.pose[k].position);
  }
  return e;
}

std::string why_not_passive(const Simulation& sim) {
  if (sim.electrostatics) return "electric forces do work";
  if (!sim.model->motors.empty()) return "motors do work";
  for (const RigidBody& b : sim.model->bodies) {
    if (b.kind == BodyKind::Kinematic && b.motion.moves())
      return "kinematic body '" + b.name + "' moves: the work of its contacts is not tracked";
  }
  return "";
}

EnergyLedger::EnergyLedger(const Simulation& sim, const State& state) : model_(sim.model.get()) {
  balance_.not_passive = why_not_passive(sim);
  balance_.initial = balance_.final = last_ = mechanical_energy(*model_, state).total();
}

void EnergyLedger::after(Stage stage, const State& state) {
  if (stage == Stage::Feed) after_feeds(state);
  if (stage == Stage::Integrate) before_collectors(state);
  if (stage == Stage::Collect) after_collectors(state);
}

void EnergyLedger::after_feeds(const State& state) {
  const double e = mechanical_energy(*model_, state).total();
  balance_.fed += e - last_;
  last_ = e;
}

void EnergyLedger::before_collectors(const State& state) {
  const MechanicalEnergy e = mechanical_energy(*model_, state);
  dynamics_ += e.total() - last_;
  lowest_ = std::min(lowest_, dynamics_);
  balance_.max_gain = std::max(balance_.max_gain, dynamics_ - lowest_);
  balance_.peak_kinetic = std::max(balance_.peak_kinetic, e.kinetic);
  last_ = e.total();
}

void EnergyLedger::after_collectors(const State& state) {
  const double e = mechanical_energy(*model_, state).total();
  balance_.removed += last_ - e;
  last_ = balance_.final = e;
  balance_.dissipated = balance_.initial + balance_.fed - balance_.removed - balance_.final;
}

void EnergyLedger::save(ByteWriter& out) const {
  const EnergyBalance& b = balance_;
  for (const double v : {b.initial, b.fed, b.removed, b.final, b.dissipated, b.max_gain,
                         b.peak_kinetic, last_, dynamics_, lowest_})
    out.value(v);
}

void EnergyLedger::load(ByteReader& in) {
  EnergyBalance& b = balance_;
  for (double* v : {&b.initial, &b.fed, &b.removed, &b.final, &b.dissipated, &b.max_gain,
                    &b.peak_kinetic, &last_, &dynamics_, &lowest_})
    in.value(*v);
}

}  // namespace ces::output
