#include "dynamics/world.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>

#include "common/parallel.hpp"

namespace ces {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

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

// The wall guard acts on rows violated by more than this many solver
// tolerances (m/s), but never less than kGuardFloor (below it rounding, not
// the solve, decides a row's sign: at tolerance 0 the guard's sweeps chased
// rounding), in at most this many sweeps (a particle in a corner touches
// two or three walls); the sliding release on rows lifting by more.
constexpr double kGuardFactor = 10.0, kGuardFloor = 1e-12;
constexpr int kGuardSweeps = 4;
// Then up to this many more over the rows of each body still violated
// (CcpProblem::guard_walls; stats.walls_finished counts those bodies).
constexpr int kFinishSweeps = 20000;

// A clump in contact turns by at most this much per step (limit_spin): its
// spheres then leave the linearised rows by at most kDrift of the smallest
// radius, and it never turns by more than kMaxTurn. Spheres turn freely.
// (A quarter of a radius left flakes 1.08 radii in walls in the 10 ms stress
// scene once the guards no longer undid the cap, a tenth 0.79;
// docs/accuracy.md, section 4.)
constexpr double kDrift = 0.1;
constexpr double kMaxTurn = 0.25 * kPi;
double max_turn(const ParticleShape& s) {
  if (s.is_sphere()) return std::numeric_limits<double>::infinity();
  double lever = 0.0;
  for (const Vec3& c : s.centers) lever = std::max(lever, c.norm());
  const double r = *std::min_element(s.radii.begin(), s.radii.end());
  return std::min(kMaxTurn, std::sqrt(2.0 * kDrift * r / lever));
}

}  // namespace

StageTimes& StageTimes::operator+=(const StageTimes& o) {
  hooks += o.hooks;
  broadphase += o.broadphase;
  narrowphase += o.narrowphase;
  forces += o.forces;
  assemble += o.assemble;
  solve += o.solve;
  integrate += o.integrate;
  return *this;
}

double StageTimes::total() const {
  return hooks + broadphase + narrowphase + forces + assemble + solve + integrate;
}

World::World(std::shared_ptr<const Model> model) : model_(std::move(model)) {
  if (model_->threads > 0) omp_set_num_threads(model_->threads);
  const std::size_t nb = model_->bodies.size();
  bodies_.pose.resize(nb);
  bodies_.velocity.resize(nb);
  bodies_.angular_velocity.resize(nb);
  bodies_.force.assign(nb, Vec3::Zero());
  bodies_.torque.assign(nb, Vec3::Zero());
  for (std::size_t i = 0; i < nb; ++i) {
    const RigidBody& b = model_->bodies[i];
    bodies_.pose[i] = b.pose;
    bodies_.velocity[i] = b.kind == BodyKind::Dynamic ? b.velocity : Vec3::Zero();
    bodies_.angular_velocity[i] = b.kind == BodyKind::Dynamic ? b.angular_velocity : Vec3::Zero();
  }
  set_body_motion(0.0);
  joint_frames_ = make_joint_frames(*model_, bodies_);
  for (const ParticleShape& s : model_->shapes) {
    max_turn_.push_back(max_turn(s));
    has_clumps_ = has_clumps_ || !s.is_sphere();
  }
}

void World::prescribed_state(const RigidBody& b, double t, Pose& pose, Vec3& v, Vec3& w) {
  const PrescribedMotion& m = b.motion;
  const Vec3 axis = m.axis.normalized();
  const Quat turn(Eigen::AngleAxisd(m.angular_speed * t, axis));
  const Vec3 centre = m.center + m.linear_velocity * t;
  pose.position = centre + turn * (b.pose.position - m.center);
  pose.orientation = turn * b.pose.orientation;
  w = m.angular_speed * axis;
  v = m.linear_velocity + w.cross(pose.position - centre);
}

void World::set_body_motion(double t) {
  for (std::size_t i = 0; i < model_->bodies.size(); ++i) {
    const RigidBody& b = model_->bodies[i];
    if (b.kind == BodyKind::Kinematic)
      prescribed_state(b, t, bodies_.pose[i], bodies_.velocity[i], bodies_.angular_velocity[i]);
  }
}

std::uint64_t World::add_particle(int shape, double scale, int material, const Vec3& position,
                                  const Quat& orientation, const Vec3& velocity,
                                  const Vec3& angular_velocity) {
  const ParticleShape& s = model_->shapes[std::size_t(shape)];
  const double density = model_->materials.materials()[std::size_t(material)].density;
  const double mass = density * s.volume * scale * scale * scale;
  const Vec3 inertia = mass * scale * scale * s.unit_inertia;
  const std::uint64_t id = next_id_++;
  particles_.push(id, shape, scale, material, mass, inertia, position, orientation, velocity,
                  angular_velocity);
  return id;
}

void World::build_solver_bodies() {
  const Model& m = *model_;
  const double h = m.step;
  const std::size_t np = particles_.size(), nb = m.bodies.size();
  SolverBodies& B = solver_bodies_;
  B.resize(np + nb);
  const Particles& p = particles_;
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(np) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(np); ++s) {
    const auto i = std::size_t(s);
    B.x[i] = p.position[i];
    B.v[i] = p.velocity[i];
    B.w[i] = p.angular_velocity[i];
    B.inv_mass[i] = p.inv_mass[i];
    B.inv_inertia[i] = world_inverse_inertia(p.orientation[i], p.inv_inertia[i]);
    B.v_free[i] = p.velocity[i] + h * (m.gravity + p.inv_mass[i] * p.force[i]);
    B.w_free[i] = p.angular_velocity[i] + h * (B.inv_inertia[i] * p.torque[i]);
  }
  for (std::size_t k = 0; k < nb; ++k) {
    const RigidBody& rb = m.bodies[k];
    const std::size_t i = np + k;
    B.x[i] = bodies_.pose[k].position;
    B.v[i] = B.v_free[i] = bodies_.velocity[k];
    B.w[i] = B.w_free[i] = bodies_.angular_velocity[k];
    B.inv_mass[i] = 0.0;
    B.inv_inertia[i].setZero();
    if (rb.kind != BodyKind::Dynamic) continue;
    B.inv_mass[i] = 1.0 / rb.mass;
    B.inv_inertia[i] = world_inverse_inertia(bodies_.pose[k].orientation, rb.inertia.cwiseInverse());
    B.v_free[i] += h * (m.gravity + bodies_.force[k] / rb.mass);
    B.w_free[i] += h * (B.inv_inertia[i] * bodies_.torque[k]);
  }
}

const StepStats& World::step() {
  const Model& m = *model_;
  const double h = m.step;
  StepStats stats;
  stats.step = stats_.step + 1;

  auto t0 = Clock::now();
  for (Hook& hook : pre_) hook(*this);
  stats.seconds.hooks = seconds_since(t0);

  t0 = Clock::now();
  if (m.reorder_interval > 0 && stats_.step % std::uint64_t(m.reorder_interval) == 0)
    reorder_in_space();
  const double reorder_seconds = seconds_since(t0);
  collider_.collide(m, particles_, bodies_, contacts_);
  stats.seconds.broadphase = reorder_seconds + collider_.broadphase_seconds();
  stats.seconds.narrowphase = collider_.narrowphase_seconds();

  t0 = Clock::now();
  std::fill(particles_.force.begin(), particles_.force.end(), Vec3::Zero());
  std::fill(particles_.torque.begin(), particles_.torque.end(), Vec3::Zero());
  std::fill(bodies_.force.begin(), bodies_.force.end(), Vec3::Zero());
  std::fill(bodies_.torque.begin(), bodies_.torque.end(), Vec3::Zero());
  for (ForceStage& f : forces_) f(*this, contacts_);
  stats.seconds.forces = seconds_since(t0);

  t0 = Clock::now();
  build_solver_bodies();
  const bool dem = m.contact_model == ContactModel::DEM;
  if (dem) dem_contacts(stats);
  rows_.clear();
  stats.joint_drift = joint_rows(m, joint_frames_, bodies_, int(particles_.size()), h, rows_);
  // Under DEM the contact forces are already in v_free: the CCP keeps only
  // the joints' rows, so joints and motors work with either contact model.
  static const Contacts kNoContacts;
  const Contacts& ccp_contacts = dem ? kNoContacts : contacts_;
  problem_.assemble(ccp_contacts, solver_bodies_, rows_, h, m.contact);
  gamma_.resize(problem_.row_count());
  if (m.solver.warm_start)
    problem_.warm_start(ccp_contacts.key, prev_impulses_, prev_rows_, gamma_);
  else
    std::fill(gamma_.begin(), gamma_.end(), 0.0);
  double pen_max = stats.max_penetration, rel_max = stats.max_penetration_relative,
         wall_max = stats.max_wall_penetration_relative;
  const auto nc = std::ptrdiff_t(contacts_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin) \
    reduction(max : pen_max, rel_max, wall_max)
  for (std::ptrdiff_t s = 0; s < nc; ++s) {
    const auto k = std::size_t(s);
    const double pen = -contacts_.gap[k], rel = pen / contacts_.radius[k];
    pen_max = std::max(pen_max, pen);
    rel_max = std::max(rel_max, rel);
    const auto a = std::size_t(contacts_.body_a[k]);
    if (a >= particles_.size() && m.bodies[a - particles_.size()].kind != BodyKind::Dynamic)
      wall_max = std::max(wall_max, rel);
  }
  stats.max_penetration = pen_max;
  stats.max_penetration_relative = rel_max;
  stats.max_wall_penetration_relative = wall_max;
  stats.seconds.assemble = seconds_since(t0);

  t0 = Clock::now();
  stats.solver = solve(problem_, m.solver, gamma_, workspace_);
  stats.seconds.solve = seconds_since(t0);

  t0 = Clock::now();
  // The velocities of the impulses, made safe first (make_safe).
  problem_.velocities(gamma_, solver_bodies_.v, solver_bodies_.w);
  if (!dem) make_safe(stats);
  if (!dem) release_sliding(stats);
  if (!dem) limit_spin(stats);
  integrate(h);
  if (!dem) remember_impulses();
  time_ += h;
  set_body_motion(time_);
  stats.seconds.integrate = seconds_since(t0);

  stats.time = time_;
  stats.particles = particles_.size();
  stats.contacts = contacts_.size();
  stats_ = stats;
  t0 = Clock::now();
  for (Hook& hook : post_) hook(*this);
  stats_.seconds.hooks += seconds_since(t0);
  return stats_;
}

// A solve stopped at its iteration cap returns impulses that may be far from
// the solution, in two ways that matter (docs/accuracy.md, stress table);
// the second is checked on every step:
//
// 1. Energy. The CCP minimises f(x) = 1/2 x.Nx + r.x over the cones, and
//    f(x) = (kinetic energy after - kinetic energy of the free motion) + b.x
//    + the work of x on moving kinematic bodies (M-norm, b the rows' bias):
//    with f <= 0 the step cannot gain more kinetic energy than -b.x, what
//    the bias allows (the push-out of an overlap at the recovery speed, a
//    restitution rebound), plus what a moving wall does; the exact
//    solution has f <= f(0) = 0. A stopped iterate need not: on the mass
//    ratio 1:1000 scene the warm-started impulses, which the solver corrects
//    along the heavy sphere's direction 1000 times slower than along a light
//    grain's, threw the sphere back up at 0.41 m/s (4 x the recovery
//    speed), a gain of 104 % of the peak kinetic energy. So if f(x) > 0,
//    the contact impulses are replaced by the best point a x on the segment
//    from 0 to them, the joints' impulses held (an exact line search: f is
//    quadratic along it; a x stays in the cones), which has f <= 0.
// 2. Walls. The wall guard (CcpProblem::guard_walls) finishes the rows of
//    walls the iterate leaves violated, so no particle goes through one.
//
// The residual reported is then that of these impulses (the sliding
// release after it changes them again, on purpose: not measured).
void World::make_safe(StepStats& stats) {
  std::vector<Vec3>& v = solver_bodies_.v;
  std::vector<Vec3>& w = solver_bodies_.w;
  const std::size_t rows = gamma_.size(), contact_rows = 3 * problem_.contact_count();
  // The solver's buffers are free after the solve.
  const Span g = workspace_.take(7, rows);
  bool changed = false;
  if (!stats.solver.converged) {
    // The line search runs over the contacts' rows only: joints and motors
    // keep their impulses.
    const Span r = workspace_.take(6, rows);
    problem_.row_velocities(gamma_, base_v_, base_w_);
    problem_.gradient_at(base_v_, base_w_, r);  // at the joints' impulses alone
    problem_.gradient_at(v, w, g);              // N x + r, from the velocities of x
    // r.x and x.Nx in fixed chunks: the same bits for any thread count.
    struct Sums {
      double rx = 0.0, xnx = 0.0;
      Sums& operator+=(const Sums& o) {
        rx += o.rx;
        xnx += o.xnx;
        return *this;
      }
    };
    const Sums f = reduce_chunks<Sums>(problem_.contact_count(), [&](std::size_t begin,
                                                                     std::size_t end, Sums& part) {
      for (std::size_t i = 3 * begin; i < 3 * end; ++i) {
        part.rx += r[i] * gamma_[i];
        part.xnx += gamma_[i] * (g[i] - r[i]);
      }
    });
    const double rx = f.rx, xnx = f.xnx;
    if (0.5 * xnx + rx > 0.0) {
      const double scale = xnx > 0.0 ? std::clamp(-rx / xnx, 0.0, 1.0) : 0.0;
      const auto n = std::ptrdiff_t(contact_rows);
#pragma omp parallel for schedule(static) if (n > 3 * kParallelMin)
      for (std::ptrdiff_t i = 0; i < n; ++i) gamma_[std::size_t(i)] *= scale;
      stats.impulse_scale = scale;
      problem_.velocities(gamma_, v, w);
      changed = true;
    }
  }
  // Every step: a solve that converged by its RMS residual can still leave
  // one wall row violated.
  guard_walls(stats);
  if (stats.wall_corrections > 0) {
    problem_.velocities(gamma_, v, w);  // exactly those of the impulses
    changed = true;
  }
  if (changed) {
    problem_.gradient_at(v, w, g);
    stats.solver.residual = problem_.residual(gamma_, g);
  }
}

// Sliding contacts with walls get the Coulomb law's normal velocity, not the
// relaxed cone's mu |v_t| lift (CcpProblem::release_sliding_walls).
void World::release_sliding(StepStats& stats) {
  std::vector<Vec3>& v = solver_bodies_.v;
  std::vector<Vec3>& w = solver_bodies_.w;
  stats.sliding_releases =
      problem_.release_sliding_walls(gamma_, v, w, guard_tolerance());
  if (stats.sliding_releases > 0) problem_.velocities(gamma_, v, w);  // exactly those of x
}

// The contact rows are linear in the step's motion, but a clump's spheres
// move on arcs: turning by an angle a, a sphere at lever l leaves its row by
// l a^2 / 2, and at a large step flakes turning by radians went into the drum
// (docs/accuracy.md, section 4). So a clump with a contact (or a candidate
// within its envelope) this step turns at most by max_turn_ per step, as
// Box2D caps every body's turn at pi/4 per step. Spheres are exempt:
// turning moves no surface. The cap only takes kinetic energy away, but it
// moves the clump off what the solve planned for it by the spin taken
// away times the lever, so the rows of every contact of a capped clump are
// guarded again (CcpProblem::guard_bodies), with its partners whatever they
// are. Neither is an impulse of the solve: x no longer gives v, w exactly
// (nothing recomputes them after this) and the residual reported is that
// before the cap.
void World::limit_spin(StepStats& stats) {
  if (!has_clumps_) return;
  const std::size_t np = particles_.size();
  touching_.assign(np, 0);
  for (std::size_t k = 0; k < contacts_.size(); ++k)
    for (const std::int32_t i : {contacts_.body_a[k], contacts_.body_b[k]})
      if (std::size_t(i) < np) touching_[std::size_t(i)] = 1;
  std::vector<Vec3>& w = solver_bodies_.w;
  capped_.assign(solver_bodies_.inv_mass.size(), 0);
  for (std::size_t i = 0; i < np; ++i) {
    if (!touching_[i]) continue;
    const double limit = max_turn_[std::size_t(particles_.shape[i])] / model_->step;
    const double spin = w[i].norm();
    if (!(spin > limit)) continue;
    w[i] *= limit / spin;
    capped_[i] = 1;
    ++stats.spin_limited;
  }
  if (stats.spin_limited == 0) return;
  // Their partners move too: the walls' rows of everyone last.
  const double tolerance = guard_tolerance();
  // The guards after the cap move clumps in contact in translation only: a
  // normal impulse on a sphere at the rim of a flake would spin it past the
  // cap again (to 200-300 rad/s at 10 ms, cap 35: 3 radii into the drum).
  locked_.assign(solver_bodies_.inv_mass.size(), 0);
  for (std::size_t i = 0; i < np; ++i)
    locked_[i] = touching_[i] && std::isfinite(max_turn_[std::size_t(particles_.shape[i])]);
  stats.wall_corrections += problem_.guard_bodies(gamma_, solver_bodies_.v, w, capped_,
                                                   tolerance, kGuardSweeps, &locked_);
  guard_walls(stats, &locked_);
}

double World::guard_tolerance() const {
  return std::max(kGuardFactor * model_->solver.tolerance, kGuardFloor);
}

// The wall guard (CcpProblem::guard_walls), its counts into the stats.
void World::guard_walls(StepStats& stats, const std::vector<std::uint8_t>* locked) {
  const CcpProblem::WallGuard f = problem_.guard_walls(
      gamma_, solver_bodies_.v, solver_bodies_.w, guard_tolerance(),
      kGuardSweeps, kGuardSweeps + kFinishSweeps, locked);
  stats.wall_corrections += f.corrections;
  stats.walls_finished += f.bodies;
  stats.walls_unfinished += f.unconverged;
}

void World::dem_contacts(StepStats& stats) {
  const Model& m = *model_;
  constexpr double kRayleighFraction = 0.2;  // the usual DEM stability margin
  stats.rayleigh_time = rayleigh_time(m, particles_);
  stats.step_above_rayleigh_limit = m.step > kRayleighFraction * stats.rayleigh_time;
  dem_.apply(m, particles_, contacts_, m.step, solver_bodies_);
}

void World::integrate(double h) {
  // Semi-implicit: positions from the new velocities (step() put them here).
  const std::vector<Vec3>& v = solver_bodies_.v;
  const std::vector<Vec3>& w = solver_bodies_.w;
  const std::size_t np = particles_.size();
  Particles& p = particles_;
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(np) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(np); ++s) {
    const auto i = std::size_t(s);
    p.velocity[i] = v[i];
    p.angular_velocity[i] = w[i];
    p.position[i] += h * v[i];
    p.orientation[i] = advance(p.orientation[i], w[i], h);
  }
  for (std::size_t k = 0; k < model_->bodies.size(); ++k) {
    if (model_->bodies[k].kind != BodyKind::Dynamic) continue;
    bodies_.velocity[k] = v[np + k];
    bodies_.angular_velocity[k] = w[np + k];
    bodies_.pose[k].position += h * v[np + k];
    bodies_.pose[k].orientation = advance(bodies_.pose[k].orientation, w[np + k], h);
  }
}

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

void World::reorder_in_space() {
  const Particles& p = particles_;
  const std::size_t n = p.size();
  if (n < std::max<std::size_t>(2, model_->reorder_min_particles)) return;
  Vec3 lo = p.position[0];
  double reach = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    lo = lo.cwiseMin(p.position[i]);
    reach = std::max(reach, model_->shapes[std::size_t(p.shape[i])].bounding_radius * p.scale[i]);
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
  particles_.permute(order_, reorder_scratch_);
}

void World::remember_impulses() {
  problem_.world_impulses(gamma_, impulse_scratch_);
  // The rows alone: a copy of the whole solution was a serial pass over
  // the contacts' rows.
  prev_rows_.assign(gamma_.end() - std::ptrdiff_t(rows_.size()), gamma_.end());
  prev_impulses_.assign(contacts_.key, impulse_scratch_);
}

}  // namespace ces
