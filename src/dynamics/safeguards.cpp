#include "dynamics/safeguards.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/parallel.hpp"

namespace ces {
namespace {

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
double turn_limit(const ParticleShape& s) {
  if (s.is_sphere()) return std::numeric_limits<double>::infinity();
  double lever = 0.0;
  for (const Vec3& c : s.centers) lever = std::max(lever, c.norm());
  const double r = *std::min_element(s.radii.begin(), s.radii.end());
  return std::min(kMaxTurn, std::sqrt(2.0 * kDrift * r / lever));
}


// What the safeguards of one step work on.
struct Guard {
  const Model& model;
  const Particles& particles;
  const Contacts& contacts;
  const CcpProblem& problem;
  SafeguardScratch& scratch;
  Span gamma;
  SolverBodies& bodies;
  double tolerance;  // m/s: rows violated by less are left alone
};

void guard_walls(Guard& c, StepStats& stats, const std::vector<std::uint8_t>* locked = nullptr);

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
void make_safe(Guard& c, StepStats& stats) {
  std::vector<Vec3>& v = c.bodies.v;
  std::vector<Vec3>& w = c.bodies.w;
  const CcpProblem& problem = c.problem;
  const Span gamma = c.gamma;
  const std::size_t rows = gamma.size(), contact_rows = 3 * problem.contact_count();
  const Span g = c.scratch.take_gradient(rows);
  bool changed = false;
  if (!stats.solver.converged) {
    // The line search runs over the contacts' rows only: joints and motors
    // keep their impulses.
    const Span r = c.scratch.take_bias(rows);
    problem.row_velocities(gamma, c.scratch.base_v, c.scratch.base_w);
    problem.gradient_at(c.scratch.base_v, c.scratch.base_w, r);  // at the joints' impulses alone
    problem.gradient_at(v, w, g);              // N x + r, from the velocities of x
    // r.x and x.Nx in fixed chunks: the same bits for any thread count.
    struct Sums {
      double rx = 0.0, xnx = 0.0;
      Sums& operator+=(const Sums& o) {
        rx += o.rx;
        xnx += o.xnx;
        return *this;
      }
    };
    const Sums f = reduce_chunks<Sums>(problem.contact_count(), [&](std::size_t begin,
                                                                     std::size_t end, Sums& part) {
      for (std::size_t i = 3 * begin; i < 3 * end; ++i) {
        part.rx += r[i] * gamma[i];
        part.xnx += gamma[i] * (g[i] - r[i]);
      }
    });
    const double rx = f.rx, xnx = f.xnx;
    if (0.5 * xnx + rx > 0.0) {
      const double scale = xnx > 0.0 ? std::clamp(-rx / xnx, 0.0, 1.0) : 0.0;
      const auto n = std::ptrdiff_t(contact_rows);
#pragma omp parallel for schedule(static) if (n > 3 * kParallelMin)
      for (std::ptrdiff_t i = 0; i < n; ++i) gamma[std::size_t(i)] *= scale;
      stats.impulse_scale = scale;
      problem.velocities(gamma, v, w);
      changed = true;
    }
  }
  // Every step: a solve that converged by its RMS residual can still leave
  // one wall row violated.
  guard_walls(c, stats);
  if (stats.wall_corrections > 0) {
    problem.velocities(gamma, v, w);  // exactly those of the impulses
    changed = true;
  }
  if (changed) {
    problem.gradient_at(v, w, g);
    stats.solver.residual = problem.residual(gamma, g);
  }
}

// Sliding contacts with walls get the Coulomb law's normal velocity, not the
// relaxed cone's mu |v_t| lift (CcpProblem::release_sliding_walls).
void release_sliding(Guard& c, StepStats& stats) {
  std::vector<Vec3>& v = c.bodies.v;
  std::vector<Vec3>& w = c.bodies.w;
  stats.sliding_releases = c.problem.release_sliding_walls(c.gamma, v, w, c.tolerance);
  if (stats.sliding_releases > 0) c.problem.velocities(c.gamma, v, w);  // exactly those of x
}

// The contact rows are linear in the step's motion, but a clump's spheres
// move on arcs: turning by an angle a, a sphere at lever l leaves its row by
// l a^2 / 2, and at a large step flakes turning by radians went into the drum
// (docs/accuracy.md, section 4). So a clump with a contact (or a candidate
// within its envelope) this step turns at most by turn_limit() per step, as
// Box2D caps every body's turn at pi/4 per step. Spheres are exempt:
// turning moves no surface. The cap only takes kinetic energy away, but it
// moves the clump off what the solve planned for it by the spin taken
// away times the lever, so the rows of every contact of a capped clump are
// guarded again (CcpProblem::guard_bodies), with its partners whatever they
// are. Neither is an impulse of the solve: x no longer gives v, w exactly
// (nothing recomputes them after this) and the residual reported is that
// before the cap.
void limit_spin(Guard& c, StepStats& stats) {
  SafeguardScratch& s = c.scratch;
  if (!s.has_clumps) return;
  const Particles& p = c.particles;
  const Contacts& contacts = c.contacts;
  const std::size_t np = p.size();
  s.touching.assign(np, 0);
  for (std::size_t k = 0; k < contacts.size(); ++k)
    for (const std::int32_t i : {contacts.body_a[k], contacts.body_b[k]})
      if (std::size_t(i) < np) s.touching[std::size_t(i)] = 1;
  std::vector<Vec3>& w = c.bodies.w;
  s.capped.assign(c.bodies.inv_mass.size(), 0);
  for (std::size_t i = 0; i < np; ++i) {
    if (!s.touching[i]) continue;
    const double limit = s.max_turn[std::size_t(p.shape[i])] / c.model.step;
    const double spin = w[i].norm();
    if (!(spin > limit)) continue;
    w[i] *= limit / spin;
    s.capped[i] = 1;
    ++stats.spin_limited;
  }
  if (stats.spin_limited == 0) return;
  // Their partners move too: the walls' rows of everyone last.
  // The guards after the cap move clumps in contact in translation only: a
  // normal impulse on a sphere at the rim of a flake would spin it past the
  // cap again (to 200-300 rad/s at 10 ms, cap 35: 3 radii into the drum).
  s.locked.assign(c.bodies.inv_mass.size(), 0);
  for (std::size_t i = 0; i < np; ++i)
    s.locked[i] = s.touching[i] && std::isfinite(s.max_turn[std::size_t(p.shape[i])]);
  stats.wall_corrections += c.problem.guard_bodies(c.gamma, c.bodies.v, w, s.capped, c.tolerance,
                                                   kGuardSweeps, &s.locked);
  guard_walls(c, stats, &s.locked);
}

// The wall guard (CcpProblem::guard_walls), its counts into the stats.
void guard_walls(Guard& c, StepStats& stats, const std::vector<std::uint8_t>* locked) {
  const CcpProblem::WallGuard f =
      c.problem.guard_walls(c.gamma, c.bodies.v, c.bodies.w, c.tolerance, kGuardSweeps,
                            kGuardSweeps + kFinishSweeps, locked);
  stats.wall_corrections += f.corrections;
  stats.walls_finished += f.bodies;
  stats.walls_unfinished += f.unconverged;
}

}  // namespace

SafeguardScratch::SafeguardScratch(const Model& model) {
  for (const ParticleShape& s : model.shapes) {
    max_turn.push_back(turn_limit(s));
    has_clumps = has_clumps || !s.is_sphere();
  }
}

void apply_safeguards(const Model& model, const Particles& particles, const Contacts& contacts,
                      const CcpProblem& problem, SafeguardScratch& scratch, Span gamma,
                      SolverBodies& bodies, StepStats& stats) {
  const double tolerance = std::max(kGuardFactor * model.solver.tolerance, kGuardFloor);
  Guard c{model, particles, contacts, problem, scratch, gamma, bodies, tolerance};
  make_safe(c, stats);
  release_sliding(c, stats);
  limit_spin(c, stats);
}

}  // namespace ces
