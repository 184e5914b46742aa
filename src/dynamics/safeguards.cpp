#include "dynamics/safeguards.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/parallel.hpp"

namespace ces {
namespace {

// The guards act on rows violated by more than this many solver
// tolerances (m/s), but never less than kGuardFloor (below it rounding, not
// the solve, decides a row's sign: at tolerance 0 the guard's sweeps would
// chase rounding), nor by less than leaves the contact within the overlap
// the solve aims at (Allowance), in at most this many sweeps (a
// particle in a corner touches two or three walls); the sliding release on
// rows lifting by more than the tolerances.
constexpr double kGuardFactor = 10.0, kGuardFloor = 1e-12;
constexpr int kGuardSweeps = 4;
// Then up to this many more over the rows of each body still violated
// (guard_wall_rows; stats.walls_finished counts those bodies).
constexpr int kFinishSweeps = 20000;

// A clump in contact turns by at most this much per step (limit_spin): its
// spheres then leave the linearised rows by at most kDrift of the smallest
// radius, and it never turns by more than kMaxTurn. Spheres turn freely.
// (What the cap leaves in walls at a large step: docs/accuracy.md,
// section 4.)
constexpr double kDrift = 0.1;
constexpr double kMaxTurn = 0.25 * kPi;
double turn_limit(const ParticleShape& s) {
  if (s.is_sphere()) return std::numeric_limits<double>::infinity();
  double lever = 0.0;
  for (const Vec3& c : s.centers) lever = std::max(lever, c.norm());
  const double r = s.smallest_radius();
  return std::min(kMaxTurn, std::sqrt(2.0 * kDrift * r / lever));
}

// The wall guard. A solve stopped at its iteration cap can leave a wall's
// row far from satisfied: the step 1/L is set by the stiffest row (the
// lightest grain, or a tangential row with its lever arm), so the normal row
// of a heavy grain on a wall converges L m times slower, and a 10 m/s grain
// can keep a quarter of the impulse that stops it and go through the plate.
// The guard finishes those rows only, locally: for each contact of a
// particle with a body of infinite mass (a wall, the drum, a mesh) whose
// row v_n + b >= 0 the impulses x leave violated by more than `allowed`
// allows, the normal impulse that makes v_n + b = 0 for the particle alone
// (the wall does not move under it), added into x and into the velocities
// v, w (which must be those of x). It only adds normal impulse, so the
// impulse stays in its friction cone and what is reported is what was
// applied. It brings v_n up to the row's own target -b: for an open gap
// (b = gap/h) that only removes approaching velocity, so on a static wall
// it cannot add energy; the targets above zero are the solver's own, a
// restitution rebound e |v_n| and the push-out of an overlap at the
// recovery speed. Contacts between particles, and with dynamic bodies, are
// left to the solver. A body flagged in `locked` (per solver body) takes
// its corrections in translation only: its spin is left as it is
// (limit_spin).
//
// A wall has infinite mass, so the guard's rows of one particle are a
// problem of their own: Gauss-Seidel sweeps over them run body by body, in
// parallel, until none of the body's rows is violated, at most
// `max_sweeps` times. Gauss-Seidel on two rows whose normals are nearly
// opposite (a grain in the nip of two surfaces, a narrow wedge) gains only
// a fraction sin^2 of the angle between them per sweep, so a few sweeps
// can leave a grain in the brush nip several radii inside the drum.
// What a guard lets a row keep of its violation: what the solve's own stop
// rule allows (CcpProblem::overlaps_within), or the velocity tolerance
// where that is more. A guard held to less would finish a wall row the
// solve left within the scene's accuracy, and the push it gives the grain
// goes into the grains beside it, whose rows the wall guard does not see
// (a flake on the drum under another).
struct Allowance {
  double velocity = 0.0;  // m/s
  double overlap = 0.0;   // of the smaller radius, as SolverSettings::overlap_aim
  double of(const CcpProblem& p, std::size_t k) const {
    return std::max(velocity, p.overlap_slack(k, overlap));
  }
};

struct WallGuard {
  std::size_t corrections = 0;  // rows corrected
  std::size_t bodies = 0;       // bodies still violated after `first_sweeps`
  std::size_t unconverged = 0;  // of them, left violated after max_sweeps
  WallGuard& operator+=(const WallGuard& o) {
    corrections += o.corrections;
    bodies += o.bodies;
    unconverged += o.unconverged;
    return *this;
  }
};

// Entry e of a body's adjacency is a contact of it with a wall: the body is
// its B side, and its A side has infinite mass and does not yield (a
// yielding surface is a spring the solve balances, not a row to finish).
bool wall_entry(const CcpProblem& p, std::uint32_t e) {
  const std::size_t k = e >> 1;
  return (e & 1) && p.bodies().inv_mass[std::size_t(p.body_a(k))] == 0.0 && !p.yields(k);
}

// The wall guard's sweeps over body b's rows with walls; its counts into out.
void guard_body_walls(const CcpProblem& p, std::size_t b, Span x, std::vector<Vec3>& v,
                      std::vector<Vec3>& w, const Allowance& allowed, int first_sweeps,
                      int max_sweeps, bool turn, WallGuard& out) {
  const SolverBodies& B = p.bodies();
  const ContactAdjacency& adj = p.adjacency();
  const std::uint32_t first = adj.offset[b], last = adj.offset[b + 1];
  bool done = false, beyond = false;  // corrected after the first sweeps
  for (int sweep = 0; sweep < max_sweeps && !done; ++sweep) {
    done = true;
    for (std::uint32_t e = first; e < last; ++e) {
      if (!wall_entry(p, adj.entry[e])) continue;
      const std::size_t k = adj.entry[e] >> 1;
      const double deficit = -p.row_of(k, v, w);
      if (!(deficit > allowed.of(p, k))) continue;  // (also skips a NaN)
      const Vec3 n = p.normal(k), cb = p.lever_b(k).cross(n);
      const double k_eff = B.inv_mass[b] + (turn ? cb.dot(B.inv_inertia[b] * cb) : 0.0);
      if (!(k_eff > 0.0)) continue;
      const double d = deficit / k_eff;
      x[3 * k] += d;
      v[b] += B.inv_mass[b] * d * n;
      if (turn) w[b] += B.inv_inertia[b] * (d * cb);
      ++out.corrections;
      done = false;
      beyond = beyond || sweep >= first_sweeps;
    }
  }
  out.bodies += beyond;
  out.unconverged += !done;
}

// `moved` (per solver body, if given): set for each body it corrects.
WallGuard guard_wall_rows(const CcpProblem& p, Span x, std::vector<Vec3>& v, std::vector<Vec3>& w,
                          const Allowance& allowed, int first_sweeps, int max_sweeps,
                          const std::vector<std::uint8_t>* locked,
                          std::vector<std::uint8_t>* moved) {
  const ContactAdjacency& adj = p.adjacency();
  // Bodies are independent here (a wall row moves one body only), so they
  // run in parallel with the same bits for any thread count.
  auto guard = [&](std::size_t b, WallGuard& out) {
    bool violated = false;
    for (std::uint32_t e = adj.offset[b]; e < adj.offset[b + 1] && !violated; ++e) {
      const std::size_t k = adj.entry[e] >> 1;
      violated = wall_entry(p, adj.entry[e]) && -p.row_of(k, v, w) > allowed.of(p, k);
    }
    if (!violated) return;
    const std::size_t before = out.corrections;
    guard_body_walls(p, b, x, v, w, allowed, first_sweeps, max_sweeps,
                     locked == nullptr || !(*locked)[b], out);
    if (moved != nullptr && out.corrections > before) (*moved)[b] = 1;
  };
  return reduce_chunks<WallGuard>(p.bodies().inv_mass.size(),
                                  [&](std::size_t begin, std::size_t end, WallGuard& out) {
                                    for (std::size_t b = begin; b < end; ++b) guard(b, out);
                                  });
}

// The same for every contact of a flagged body, whatever its partner (the
// impulse shared by both bodies), in at most `sweeps` Gauss-Seidel sweeps
// over those contacts in order: after the spin limit changed their spins.
// The contacts are picked out first, in parallel (`rows`: scratch), and
// only they are swept. v, w need not be those of x. Returns the rows
// corrected.
std::size_t guard_body_rows(const CcpProblem& p, Span x, std::vector<Vec3>& v, std::vector<Vec3>& w,
                            const std::vector<std::uint8_t>& flagged, const Allowance& allowed,
                            int sweeps,
                            const std::vector<std::uint8_t>* locked,
                            std::vector<std::uint32_t>& rows) {
  const SolverBodies& B = p.bodies();
  // A locked body takes the correction in translation only (its turn, the
  // angular terms, left as they are).
  auto turns = [&](std::size_t i) { return locked == nullptr || !(*locked)[i]; };
  auto of_flagged = [&](std::size_t k) {
    return flagged[std::size_t(p.body_a(k))] || flagged[std::size_t(p.body_b(k))];
  };
  select_in_order(p.contact_count(), of_flagged, rows);
  std::size_t corrections = 0;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    std::size_t made = 0;
    for (const std::uint32_t k : rows) {
      if (p.yields(k)) continue;
      const auto a = std::size_t(p.body_a(k)), b = std::size_t(p.body_b(k));
      const Vec3 n = p.normal(k), ra = p.lever_a(k), rb = p.lever_b(k);
      const double deficit = -p.bias(k) - n.dot(p.relative_velocity(k, v, w));
      if (!(deficit > allowed.of(p, k))) continue;  // (also skips a NaN)
      const Vec3 ca = ra.cross(n), cb = rb.cross(n);
      const bool turn_a = turns(a), turn_b = turns(b);
      const double k_eff = B.inv_mass[a] + (turn_a ? ca.dot(B.inv_inertia[a] * ca) : 0.0) +
                           B.inv_mass[b] + (turn_b ? cb.dot(B.inv_inertia[b] * cb) : 0.0);
      if (!(k_eff > 0.0)) continue;
      const double d = deficit / k_eff;
      x[3 * k] += d;
      v[a] -= B.inv_mass[a] * d * n;
      if (turn_a) w[a] -= B.inv_inertia[a] * (d * ca);
      v[b] += B.inv_mass[b] * d * n;
      if (turn_b) w[b] += B.inv_inertia[b] * (d * cb);
      ++made;
    }
    corrections += made;
    if (made == 0) break;
  }
  return corrections;
}

// The sliding lift of the relaxed cone complementarity, taken back on
// walls. The CCP gives a sliding contact the normal velocity mu |v_t|
// (Anitescu-Tasora), so a grain landing on a surface it slips against is
// thrown off it (at 0.19 m/s for 0.75 m/s of slip and mu 0.5) where the
// Coulomb law keeps it on: restitution 0 means no rebound. For each body
// whose contacts are all with bodies of infinite mass (a grain on the
// drum, not one in a pile: there the lift is shared with the neighbours),
// whose pressing contacts all slide and one of whose rows exceeds its
// target by more than `tolerance`: its contact impulses are scaled down
// together (each stays on its cone, friction mu times its normal impulse)
// by the largest share that leaves every one of its rows at or above its
// target. A flat contact comes to rest on its target, as under Coulomb.
// Into x and into v, w (which must be those of x); true if body b is
// released.
bool release_body(const CcpProblem& p, std::size_t b, Span x, std::vector<Vec3>& v,
                  std::vector<Vec3>& w, double tolerance) {
  const SolverBodies& B = p.bodies();
  const ContactAdjacency& adj = p.adjacency();
  const std::uint32_t first = adj.offset[b], last = adj.offset[b + 1];
  if (first == last) return false;
  // The body's contacts: all with walls (it is their B side), every one
  // pressing is sliding, and at least one lifts off by more than the
  // tolerance. Then dv, dw: what taking all its impulses away would do.
  bool eligible = true, lifting = false;
  Vec3 dv = Vec3::Zero(), dw = Vec3::Zero();
  for (std::uint32_t e = first; e < last && eligible; ++e) {
    const std::size_t k = adj.entry[e] >> 1, i = 3 * k;
    const double gn = x[i], gt2 = x[i + 1] * x[i + 1] + x[i + 2] * x[i + 2], mu = p.friction(k);
    eligible = wall_entry(p, adj.entry[e]) &&
               (gn <= 0.0 || (mu > 0.0 && gt2 >= mu * mu * gn * gn * (1.0 - 1e-6)));
    if (!eligible || gn <= 0.0) continue;
    const Vec3 P = p.world_impulse(k, x);
    dv -= B.inv_mass[b] * P;
    dw -= B.inv_inertia[b] * p.lever_b(k).cross(P);
    lifting = lifting || p.row_of(k, v, w) > tolerance;
  }
  if (!eligible || !lifting) return false;
  // The largest share t of them to take away with every row staying >= 0,
  // if taking them away lowers a lifting row at all (friction's torque
  // can make it rise instead).
  double t = 1.0;
  bool lowers = false;
  for (std::uint32_t e = first; e < last; ++e) {
    const std::size_t k = adj.entry[e] >> 1;
    const double rate = p.normal(k).dot(dv + dw.cross(p.lever_b(k))), row = p.row_of(k, v, w);
    if (rate < 0.0) t = std::min(t, std::max(0.0, row) / -rate);
    lowers = lowers || (rate < 0.0 && row > tolerance && x[3 * k] > 0.0);
  }
  if (!lowers || !(t > 0.0)) return false;
  for (std::uint32_t e = first; e < last; ++e)
    for (std::size_t r = 0; r < 3; ++r) x[3 * (adj.entry[e] >> 1) + r] *= 1.0 - t;
  v[b] += t * dv;
  w[b] += t * dw;
  return true;
}

// release_body for every body. Bodies are independent here: a released
// body's contacts are all with walls, so no other body reads the rows it
// changes, and the walls' v, w do not change. In parallel, with the same
// bits for any thread count. Returns the bodies released, and flags them
// in `moved` (per solver body).
std::size_t release_sliding_walls(const CcpProblem& p, Span x, std::vector<Vec3>& v,
                                  std::vector<Vec3>& w, double tolerance,
                                  std::vector<std::uint8_t>& moved) {
  return reduce_chunks<std::size_t>(p.bodies().inv_mass.size(),
                                    [&](std::size_t begin, std::size_t end, std::size_t& released) {
                                      for (std::size_t b = begin; b < end; ++b) {
                                        const bool done = release_body(p, b, x, v, w, tolerance);
                                        moved[b] = done;
                                        released += done;
                                      }
                                    });
}

// What the safeguards of one step work on.
struct Guard {
  const Model& model;
  const Particles& particles;
  const CcpProblem& problem;
  SafeguardScratch& scratch;
  Span gamma;
  SolverBodies& bodies;
  Allowance allowed;  // rows violated by less are left alone
};

void guard_walls(Guard& c, StepStats& stats, const std::vector<std::uint8_t>* locked = nullptr,
                 std::vector<std::uint8_t>* moved = nullptr);

// v, w made those of x again after a guard changed the impulses of the
// bodies flagged in scratch.moved, and their v, w: velocities() of those
// bodies alone (velocities_of), as the others' contacts kept their
// impulses. The same bits as velocities() of every body, for a pass over
// the moved bodies' contacts instead of all.
void refresh_moved(Guard& c) {
  SafeguardScratch& s = c.scratch;
  select_in_order(
      s.moved.size(), [&](std::size_t b) { return s.moved[b] != 0; }, s.moved_bodies);
  c.problem.velocities_of(c.gamma, s.moved_bodies, c.bodies.v, c.bodies.w);
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
//    solution has f <= f(0) = 0. A stopped iterate need not: a heavy
//    sphere on light grains (mass ratio 1:1000) keeps warm-started
//    impulses that the solver corrects along its direction 1000 times
//    slower than along a light grain's, and they can throw it back up at
//    several times the recovery speed. So if f(x) > 0,
//    the contact impulses are replaced by the best point a x on the segment
//    from 0 to them, the joints' impulses held (an exact line search: f is
//    quadratic along it; a x stays in the cones), which has f <= 0.
// 2. Walls. The wall guard (guard_wall_rows) finishes the rows of
//    walls the iterate leaves violated, so no particle goes through one.
//
// The residual reported is then that of these impulses (the sliding
// release after it changes them again, on purpose: not measured).
void make_safe(Guard& c, StepStats& stats) {
  std::vector<Vec3>& v = c.bodies.v;
  std::vector<Vec3>& w = c.bodies.w;
  const CcpProblem& problem = c.problem;
  const Span gamma = c.gamma;
  const std::size_t contact_rows = 3 * problem.contact_count();
  bool changed = false;
  if (!stats.solver.converged) {
    // The line search runs over the contacts' rows only: joints and motors
    // keep their impulses (r is at the joints' impulses alone).
    problem.row_velocities(gamma, c.scratch.base_v, c.scratch.base_w);
    const CcpProblem::EnergySums f =
        problem.energy_sums(c.scratch.base_v, c.scratch.base_w, v, w, gamma);
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
  // one wall row violated. v, w are velocities() of gamma here.
  c.scratch.moved.assign(v.size(), 0);
  guard_walls(c, stats, nullptr, &c.scratch.moved);
  if (stats.wall_corrections > 0) {
    refresh_moved(c);  // exactly those of the impulses
    changed = true;
  }
  if (changed) stats.solver.residual = problem.residual_at(v, w, gamma);
}

// Sliding contacts with walls get the Coulomb law's normal velocity, not the
// relaxed cone's mu |v_t| lift (release_sliding_walls).
void release_sliding(Guard& c, StepStats& stats) {
  std::vector<Vec3>& v = c.bodies.v;
  std::vector<Vec3>& w = c.bodies.w;
  c.scratch.moved.resize(v.size());
  stats.sliding_releases =
      release_sliding_walls(c.problem, c.gamma, v, w, c.allowed.velocity, c.scratch.moved);
  if (stats.sliding_releases > 0) refresh_moved(c);  // exactly those of x
}

// The contact rows are linear in the step's motion, but a clump's spheres
// move on arcs: turning by an angle a, a sphere at lever l leaves its row by
// l a^2 / 2, and at a large step a flake turning by radians goes into the
// drum. So a clump with a contact (or a candidate within its envelope) this
// step turns at most by turn_limit() per step, as Box2D caps every body's
// turn at pi/4 per step. Spheres are exempt: turning moves no surface. The
// cap only takes kinetic energy away, but it moves the clump off what the
// solve planned for it by the spin taken away times the lever, so the rows
// of every contact of a capped clump are guarded again (guard_body_rows),
// with its partners whatever they are. Neither is an impulse of the solve:
// x no longer gives v, w exactly (nothing recomputes them after this) and
// the residual reported is that before the cap.
void limit_spin(Guard& c, StepStats& stats) {
  SafeguardScratch& s = c.scratch;
  if (!s.has_clumps) return;
  const Particles& p = c.particles;
  const ContactAdjacency& adj = c.problem.adjacency();  // every particle's contacts
  std::vector<Vec3>& w = c.bodies.w;
  s.capped.assign(c.bodies.inv_mass.size(), 0);
  // The guards after the cap move clumps in contact in translation only: a
  // normal impulse on a sphere at the rim of a flake would spin it past the
  // cap again, several times over at a large step, and into the drum.
  s.locked.assign(c.bodies.inv_mass.size(), 0);
  std::size_t capped = 0;
  const auto np = std::ptrdiff_t(p.size());
#pragma omp parallel for schedule(static) reduction(+ : capped) if (np > kParallelMin)
  for (std::ptrdiff_t si = 0; si < np; ++si) {
    const auto i = std::size_t(si);
    if (adj.offset[i] == adj.offset[i + 1]) continue;  // no contact
    const double max_turn = s.max_turn[std::size_t(p.shape[i])];
    s.locked[i] = std::isfinite(max_turn);
    const double limit = max_turn / c.model.step, spin = w[i].norm();
    if (!(spin > limit)) continue;
    w[i] *= limit / spin;
    s.capped[i] = 1;
    ++capped;
  }
  stats.spin_limited += capped;
  if (capped == 0) return;
  // Their partners move too: the walls' rows of everyone last.
  stats.wall_corrections += guard_body_rows(c.problem, c.gamma, c.bodies.v, w, s.capped,
                                            c.allowed, kGuardSweeps, &s.locked, s.guarded);
  guard_walls(c, stats, &s.locked);
}

// The wall guard (guard_wall_rows), its counts into the stats.
void guard_walls(Guard& c, StepStats& stats, const std::vector<std::uint8_t>* locked,
                 std::vector<std::uint8_t>* moved) {
  const WallGuard f = guard_wall_rows(c.problem, c.gamma, c.bodies.v, c.bodies.w, c.allowed,
                                      kGuardSweeps, kGuardSweeps + kFinishSweeps, locked, moved);
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

void apply_safeguards(const Model& model, const Particles& particles, const CcpProblem& problem,
                      SafeguardScratch& scratch, Span gamma, SolverBodies& bodies,
                      StepStats& stats) {
  const Allowance allowed{std::max(kGuardFactor * model.solver.tolerance, kGuardFloor),
                          model.solver.overlap_aim()};
  Guard c{model, particles, problem, scratch, gamma, bodies, allowed};
  make_safe(c, stats);
  release_sliding(c, stats);
  limit_spin(c, stats);
}

}  // namespace ces
