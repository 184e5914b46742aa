#include "dynamics/contact_dynamics.hpp"

#include <algorithm>
#include <cmath>

#include "common/parallel.hpp"
#include "dynamics/safeguards.hpp"
#include "dynamics/solvers.hpp"
#include "dynamics/unlisted_walls.hpp"

namespace ces {
namespace {

Mat3 world_inverse_inertia(const Quat& q, const Vec3& inv_principal) {
  const Mat3 R = q.toRotationMatrix();
  return R * inv_principal.asDiagonal() * R.transpose();
}

// Exponential map: rotate q by the world angular velocity w over h.
Quat advance(const Quat& q, const Vec3& w, double h) {
  const double angle = w.norm() * h;
  if (angle == 0.0) return q;
  return (Quat(Eigen::AngleAxisd(angle, w.normalized())) * q).normalized();
}

// No contacts for the problem: under DEM the contact forces are already in
// v_free and the problem keeps only the joints' rows.
const Contacts kNoContacts;

// The DEM stability margin: the step against the smallest Rayleigh time.
constexpr double kRayleighFraction = 0.2;

// A body whose motion the solve's impulses do not change: a static or
// kinematic body, or a sleeping particle (dynamics/sleep.hpp).
void prescribed_body(SolverBodies& B, std::size_t i, const Vec3& v, const Vec3& w) {
  B.v[i] = B.v_free[i] = v;
  B.w[i] = B.w_free[i] = w;
  B.inv_mass[i] = 0.0;
  B.inv_inertia[i].setZero();
}

}  // namespace

ContactDynamics::ContactDynamics(const Model& model, const Bodies& bodies)
    : joint_frames_(make_joint_frames(model, bodies)), safeguards_(model) {}

void ContactDynamics::build_solver_bodies(const Model& m, const State& state) {
  const double h = m.step;
  const Particles& p = state.particles;
  const Bodies& bodies = state.bodies;
  const std::size_t np = p.size(), nb = m.bodies.size();
  SolverBodies& B = solver_bodies_;
  B.resize(np + nb);
  for_each_index(np, [&](std::size_t i) {
    B.x[i] = p.position[i];
    if (p.asleep(i)) {
      prescribed_body(B, i, p.velocity[i], p.angular_velocity[i]);
      return;
    }
    B.v[i] = p.velocity[i];
    B.w[i] = p.angular_velocity[i];
    B.inv_mass[i] = p.inv_mass[i];
    B.inv_inertia[i] = world_inverse_inertia(p.orientation[i], p.inv_inertia[i]);
    B.v_free[i] = p.velocity[i] + h * (m.gravity + p.inv_mass[i] * p.force[i]);
    B.w_free[i] = p.angular_velocity[i] + h * (B.inv_inertia[i] * p.torque[i]);
  });
  for (std::size_t k = 0; k < nb; ++k) {
    const RigidBody& rb = m.bodies[k];
    const std::size_t i = np + k;
    B.x[i] = bodies.pose[k].position;
    prescribed_body(B, i, bodies.velocity[k], bodies.angular_velocity[k]);
    if (rb.kind != BodyKind::Dynamic) continue;
    B.inv_mass[i] = 1.0 / rb.mass;
    B.inv_inertia[i] = world_inverse_inertia(bodies.pose[k].orientation, rb.inertia.cwiseInverse());
    B.v_free[i] += h * (m.gravity + bodies.force[k] / rb.mass);
    B.w_free[i] += h * (B.inv_inertia[i] * bodies.torque[k]);
  }
}

void ContactDynamics::assemble(const Model& m, State& state, const Contacts& contacts,
                               StepStats& stats) {
  const double h = m.step;
  build_solver_bodies(m, state);
  const bool dem = m.contact_model == ContactModel::DEM;
  if (dem) {
    stats.rayleigh_time = rayleigh_time(m, state.particles);
    stats.step_above_rayleigh_limit = h > kRayleighFraction * stats.rayleigh_time;
    dem_.apply(m, state.particles, contacts, h, state.springs, solver_bodies_);
  }
  rows_.clear();
  stats.joint_drift =
      joint_rows(m, joint_frames_, state.bodies, int(state.particles.size()), h, rows_);
  const Contacts& ccp_contacts = dem ? kNoContacts : contacts;
  problem_.assemble(ccp_contacts, m.materials, solver_bodies_, rows_, h, m.contact);
  gamma_.resize(problem_.row_count());
  if (m.solver.warm_start)
    problem_.warm_start(ccp_contacts.key, state.impulses, state.row_impulses, gamma_);
  else
    std::fill(gamma_.begin(), gamma_.end(), 0.0);
  measure_penetration(m, state.particles, contacts, stats);
}

void ContactDynamics::measure_penetration(const Model& m, const Particles& particles,
                                          const Contacts& contacts, StepStats& stats) const {
  double pen_max = stats.max_penetration, rel_max = stats.max_penetration_relative,
         wall_max = stats.max_wall_penetration_relative, yield_max = stats.max_yield;
  const auto nc = std::ptrdiff_t(contacts.size());
  const std::size_t np = particles.size();
#pragma omp parallel for schedule(static) if (nc > kParallelMin) \
    reduction(max : pen_max, rel_max, wall_max, yield_max)
  for (std::ptrdiff_t s = 0; s < nc; ++s) {
    const auto k = std::size_t(s);
    const double pen = -contacts.gap[k], rel = pen / contacts.radius[k];
    if (m.materials.surfaces(contacts.surfaces[k]).compliance > 0.0) {
      yield_max = std::max(yield_max, pen);
      continue;
    }
    pen_max = std::max(pen_max, pen);
    rel_max = std::max(rel_max, rel);
    const auto a = std::size_t(contacts.body_a[k]);
    if (a >= np && m.bodies[a - np].kind != BodyKind::Dynamic) wall_max = std::max(wall_max, rel);
  }
  stats.max_penetration = pen_max;
  stats.max_penetration_relative = rel_max;
  stats.max_wall_penetration_relative = wall_max;
  stats.max_yield = yield_max;
}

void ContactDynamics::solve(const Model& m, StepStats& stats) {
  stats.solver = ces::solve(problem_, m.solver, gamma_, workspace_);
}

void ContactDynamics::safeguard(const Model& m, const State& state,
                                std::span<const double> envelope, StepStats& stats) {
  // The velocities of the impulses, which the safeguards change with them.
  problem_.velocities(gamma_, solver_bodies_.v, solver_bodies_.w);
  if (m.contact_model == ContactModel::DEM) return;
  const Particles& p = state.particles;
  apply_safeguards(m, p, problem_, safeguards_, gamma_, solver_bodies_, stats);
  stats.unlisted_wall_stops =
      stop_at_unlisted_walls(m, p, state.bodies, envelope, solver_bodies_);
}

void ContactDynamics::integrate(const Model& model, State& state, const Contacts& contacts) {
  // Semi-implicit: positions from the new velocities (the solve and the
  // safeguards put them here).
  const double h = model.step;
  const std::vector<Vec3>& v = solver_bodies_.v;
  const std::vector<Vec3>& w = solver_bodies_.w;
  Particles& p = state.particles;
  Bodies& bodies = state.bodies;
  const std::size_t np = p.size();
  for_each_index(np, [&](std::size_t i) {
    p.velocity[i] = v[i];
    p.angular_velocity[i] = w[i];
    if (p.asleep(i)) return;  // its carrier moves it (Sleep::carry)
    p.position[i] += h * v[i];
    p.orientation[i] = advance(p.orientation[i], w[i], h);
  });
  for (std::size_t k = 0; k < model.bodies.size(); ++k) {
    if (model.bodies[k].kind != BodyKind::Dynamic) continue;
    bodies.velocity[k] = v[np + k];
    bodies.angular_velocity[k] = w[np + k];
    bodies.pose[k].position += h * v[np + k];
    bodies.pose[k].orientation = advance(bodies.pose[k].orientation, w[np + k], h);
  }
  if (model.contact_model == ContactModel::DEM) return;
  // The warm start: the contacts' impulses as world vectors, and the
  // bilateral rows' alone (a copy of the whole solution would be a serial
  // pass over the contacts' rows).
  problem_.world_impulses(gamma_, impulse_scratch_);
  state.row_impulses.assign(gamma_.end() - std::ptrdiff_t(rows_.size()), gamma_.end());
  state.impulses.assign(contacts.key, impulse_scratch_);
}

}  // namespace ces
