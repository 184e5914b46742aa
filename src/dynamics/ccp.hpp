// The cone complementarity problem of one time step (Anitescu, Tasora,
// Comput. Optim. Appl. 47(2), 2010):
//   find gamma in K with  N gamma + r in K°,  gamma ⟂ N gamma + r,
// N = D^T M^-1 D, r = D^T v_free + b. It is the optimality condition of
//   min f(gamma) = 1/2 gamma^T N gamma + r^T gamma  over K,
// K the product of friction cones (3 rows per contact) and of intervals
// (bilateral rows: unbounded, or bounded for motors).
//
// N is never formed: N x is "scatter impulses into body velocities, gather
// constraint velocities". Scatter runs per body over a body->contact adjacency
// list and gather per contact, so every sum has a fixed order and the result
// is bitwise the same for any number of threads. Reductions over rows go
// through fixed chunks added in chunk order, for the same reason.
//
// APGD, the default, runs on a kernel of its own (apgd_step, apgd_gradient;
// kernel.inl, built for each instruction set: isa.hpp): one pass over the contacts per iteration instead of five
// (two after a rejected trial), four contacts to a SIMD vector, on world
// rows (a contact's impulse as a world vector), so it needs only the normal
// of a contact's frame. This file and ccp.cpp hold the problem and its
// operator; solvers.hpp the solvers and safeguards.hpp what the step does
// after a solve, both over the read-only view of the contacts below.
//
// The normals, friction coefficients and lever arms, and the bodies'
// inverse masses and inertias, are stored in float: the kernel streams them
// every iteration and is bound by memory. They are relative quantities (unit
// vectors, lever arms of a few mm, at most the drum radius), so float's
// 6e-8 relative error moves a contact point by nanometres; scatter and
// gather read the same rounded numbers, so N stays exactly symmetric. The
// build option CES_DOUBLE_STORAGE stores them all in double, to measure
// what float costs (docs/accuracy.md, section 2).
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <new>
#include <span>
#include <vector>

#include "collision/contacts.hpp"
#include "common/math.hpp"
#include "common/parallel.hpp"
#include "dynamics/adjacency.hpp"
#include "dynamics/isa.hpp"
#include "model/model.hpp"
#include "model/stats.hpp"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ces {

#ifdef CES_DOUBLE_STORAGE
using StoredScalar = double;
#else
using StoredScalar = float;
#endif

// Storage on cache-line boundaries: a 64-byte block of the kernel is then
// one line.
template <class T>
struct CacheAligned {
  using value_type = T;
  CacheAligned() = default;
  template <class U>
  CacheAligned(const CacheAligned<U>&) {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(64)));
  }
  void deallocate(T* p, std::size_t) { ::operator delete(p, std::align_val_t(64)); }
  bool operator==(const CacheAligned&) const { return true; }
};
template <class T>
using AlignedVector = std::vector<T, CacheAligned<T>>;

using Span = std::span<double>;
using ConstSpan = std::span<const double>;

// Bodies as the solver sees them: particles, then machine bodies.
struct SolverBodies {
  std::vector<Vec3> x;               // centre of mass (lever arms)
  std::vector<Vec3> v, w;            // velocities at the start of the step
  std::vector<Vec3> v_free, w_free;  // after external forces, before contacts
  std::vector<double> inv_mass;      // 0 for static and kinematic bodies
  std::vector<Mat3> inv_inertia;     // world frame
  void resize(std::size_t n);
  // Body i's velocity at the world point x, at the start of the step.
  Vec3 velocity_at(int i, const Vec3& x) const {
    const auto u = std::size_t(i);
    return v[u] + w[u].cross(x - this->x[u]);
  }
};

// One bilateral row: J v + bias = 0 with impulse in [lo, hi].
struct BilateralRow {
  int a = -1, b = -1;  // solver body indices, -1: the ground
  Vec3 lin_a = Vec3::Zero(), ang_a = Vec3::Zero(), lin_b = Vec3::Zero(), ang_b = Vec3::Zero();
  double bias = 0.0;
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
};
// The row's J v at velocities v, w (without its bias).
double row_velocity(const std::vector<Vec3>& v, const std::vector<Vec3>& w,
                    const BilateralRow& row);
// v, w += M^-1 J^T impulse: what the row's impulse does to its bodies.
void apply_row(const SolverBodies& B, const BilateralRow& row, double impulse,
               std::vector<Vec3>& v, std::vector<Vec3>& w);

class CcpProblem {
 public:
  // Builds the problem for this step. `rows` are the joints' and motors' rows.
  void assemble(const Contacts& contacts, const MaterialTable& materials,
                const SolverBodies& bodies, const std::vector<BilateralRow>& rows, double h,
                const ContactSettings& settings);

  std::size_t contact_count() const { return a_.size(); }
  std::size_t row_count() const { return 3 * a_.size() + rows_.size(); }

  // g = N x + r = J (v_free + M^-1 J^T x) + b.
  void gradient(ConstSpan x, Span g) const;
  // y = N x.
  void multiply(ConstSpan x, Span y) const;
  void project(Span x) const;
  // out = Π(y - step g), row by row: one pass, no temporaries.
  void projected_step(ConstSpan y, ConstSpan g, double step, Span out) const;
  // Projected-gradient residual (x - Π(x - s g)) / s, s = 1 / max diag N:
  // its RMS over the rows.
  double residual(ConstSpan x, ConstSpan g) const;
  // Whether the impulses whose gradient is g leave every contact, at the
  // end of the step, overlapping by at most `tolerance` times its smaller
  // radius, or, where it overlaps by more already, by no more than now:
  // from g's normal row v_n + b the overlap after the step is
  // -(gap + h v_n). g in world rows (the APGD kernel's) or in the
  // contacts' frames.
  bool overlaps_within(ConstSpan g, bool world, double tolerance) const;
  // How far below zero contact k's normal row v_n + b may end and still
  // leave the contact within overlaps_within's `tolerance`.
  double overlap_slack(std::size_t k, double tolerance) const;
  // Upper bound on the largest eigenvalue of N (Gershgorin-like, cheap).
  double diagonal_max() const { return diag_max_; }

  // The energy check's sums over the contacts' rows: r.x and x.(N + E)x,
  // where r = J v_base + b (v_base, w_base: the velocities of impulses
  // with no contact part, the joints' alone) and (N + E) x + r the
  // gradient at x (v, w: velocities(x)). One pass that stores neither
  // vector, in fixed chunks: the same bits for any thread count.
  struct EnergySums {
    double rx = 0.0, xnx = 0.0;
    EnergySums& operator+=(const EnergySums& o);
  };
  EnergySums energy_sums(const std::vector<Vec3>& v_base, const std::vector<Vec3>& w_base,
                         const std::vector<Vec3>& v, const std::vector<Vec3>& w,
                         ConstSpan x) const;
  // residual(x, g) for g the gradient at x, where v, w are velocities(x),
  // without the scatter again and with no gradient stored.
  double residual_at(const std::vector<Vec3>& v, const std::vector<Vec3>& w, ConstSpan x) const;
  // Final velocities v_free + M^-1 J^T x.
  void velocities(ConstSpan x, std::vector<Vec3>& v, std::vector<Vec3>& w) const;
  // velocities() for the listed bodies alone (each of finite mass, listed
  // once, in ascending order), the others' v, w left as they are: the same bits as
  // velocities(x) gives those bodies, each body's sum being its own. For
  // a change of x in the listed bodies' contacts only, where v, w were
  // velocities() of x before it.
  void velocities_of(ConstSpan x, const std::vector<std::uint32_t>& bodies, std::vector<Vec3>& v,
                     std::vector<Vec3>& w) const;
  // The same for x's bilateral rows alone (its contact rows taken as 0),
  // with no pass over the contacts: the same bits as velocities() of that x.
  void row_velocities(ConstSpan x, std::vector<Vec3>& v, std::vector<Vec3>& w) const;

  // Contact impulses as world vectors (normal + friction), for warm starts:
  // a world vector survives the rotation of the tangent frame between steps.
  void world_impulses(ConstSpan x, std::vector<Vec3>& out) const;
  // Initial guess: each contact's previous world impulse (found by key in
  // `previous`) re-expressed in its new frame; bilateral rows keep their
  // previous values, prev_rows, if there are as many (else 0).
  void warm_start(const std::vector<ContactKey>& keys, const ContactMemory& previous,
                  ConstSpan prev_rows, Span x) const;

  // APGD runs on world rows (kernel.inl): a contact's three rows are its
  // impulse as a world vector, n x_n + t1 x_t1 + t2 x_t2, and its gradient
  // J v + b n; bilateral rows as they are. The frame is orthonormal, so
  // norms, dot products and the residual are the same. to_world and
  // to_local change x between the two.
  void to_world(ConstSpan x, Span P) const;
  void to_local(ConstSpan P, Span x) const;
  // g = N P + r in world rows. P has a spare past its rows (RowBuffer).
  void world_gradient(ConstSpan P, Span g) const;
  // APGD's metric (solve_apgd): row i's step weight, the same for a
  // contact's three rows: 1 / (an upper bound on the largest eigenvalue of
  // the contact's 3x3 block of N), 1 / N_ii for a bilateral row.
  double metric_weight(std::size_t i) const;
  // v's rows times the square roots of their metric weights.
  void scale_by_metric(Span v) const;

  // APGD's iteration (kernel.inl) in one streaming pass over the contacts
  // (and one over the bodies), four contacts to a SIMD vector, on world
  // rows: apgd_gradient makes the next trial as it goes, and apgd_step
  // makes a trial alone at the start and after a rejected one. x, x1 have
  // a spare past their rows (RowBuffer).
  // The extrapolated point y = ca x - cb x_old and its gradient gy = ca gx -
  // cb g_old are made where they are used and never stored (cb = 0: y = x,
  // gy = gx, and x_old, g_old are not read): storing them costs more memory
  // traffic than reading x_old again in the second pass.
  struct Momentum {
    double ca = 1.0, cb = 0.0;
  };
  // The sums an APGD iteration decides on, added in fixed chunks as
  // reduce() adds them: dd = |d|^2 in the metric's W^-1 and dnd =
  // d.(g1 - gy) with d = x1 - y, uphill = gy.(x1 - x), and the residual's.
  struct TrialSums {
    double dd = 0, dnd = 0, uphill = 0, res_sum = 0;
    TrialSums& operator+=(const TrialSums& o);
  };
  // The first: x1 = Π(y - step W gy), and the sums but d.g1 and the
  // residual's. x1 must not be x or x_old (a backtracking step makes y
  // again).
  TrialSums apgd_step(ConstSpan x, ConstSpan x_old, Span x1, ConstSpan gx, ConstSpan g_old,
                      Momentum momentum, double step) const;
  // The next iteration's trial, made in apgd_gradient's pass on the guess
  // that its x1 is accepted: x2 = Π(y' - step W gy') with y' = ca x1 - cb x
  // and gy' = ca g1 - cb gx (gx unread when cb = 0). x2 empty: none.
  struct NextTrial {
    Span x2;
    ConstSpan gx;
    Momentum momentum;
    double step = 0.0;
  };
  // The second: g1 = N x1 + r at apgd_step's x1; adds d.g1 and the residual
  // to t. With `next`, makes the next trial in the same pass and returns its
  // sums: the same bits as apgd_step(x1, x, next.x2, g1, next.gx, ...)
  // after it, for one pass over the contacts instead of two.
  TrialSums apgd_gradient(ConstSpan x1, Span g1, ConstSpan x, ConstSpan x_old, Momentum momentum,
                          TrialSums& t, const NextTrial& next) const;

  // Contact k as the solvers and safeguards outside the kernel read it:
  // its solver bodies, frame, friction coefficient, lever arms (from each
  // body's centre of mass to the contact point) and bias b.
  const SolverBodies& bodies() const { return *bodies_; }
  int body_a(std::size_t k) const { return a_[k]; }
  int body_b(std::size_t k) const { return b_[k]; }
  Vec3 normal(std::size_t k) const {
    const StoredScalar* f = frame_at(k);
    return {double(f[0]), double(f[kLanes]), double(f[2 * kLanes])};
  }
  double friction(std::size_t k) const { return double(frame_at(k)[3 * kLanes]); }
  // The contact's frame: the stored normal and tangents made from it.
  struct Frame {
    Vec3 n, t1, t2;
  };
  Frame frame(std::size_t k) const { return {normal(k), tangent_[2 * k], tangent_[2 * k + 1]}; }
  Vec3 lever_a(std::size_t k) const { return lever(k, 0); }
  Vec3 lever_b(std::size_t k) const { return lever(k, 1); }
  double bias(std::size_t k) const { return bias_[k]; }
  // A contact with a yielding surface (Material::compliance C, m/N) is a
  // damped spring, not a wall: its normal row is v_n + b + eps x_n >= 0,
  // the backward-Euler step of a spring of stiffness 1 / C with its
  // dashpot (soft_row in ccp.cpp; Lacoursiere's regularised constraints,
  // as Chrono's compliance and Box2D's soft step take them); undamped,
  // eps = C / h^2. At rest under a force F it gives F C, and it pushes out
  // an overlap by its force, with no recovery cap. N becomes N + E, E = eps
  // on the normal rows: still symmetric and positive.
  double softness(std::size_t k) const { return softness_[k]; }
  bool yields(std::size_t k) const { return softness_[k] > 0.0; }
  // Contact k's rows of x (its frame's) as a world vector. Inline: the
  // safeguards take it contact by contact (the build does not contract
  // floating point, so inlined it rounds as out of line).
  Vec3 world_impulse(std::size_t k, ConstSpan x) const {
    const Frame F = frame(k);
    return F.n * x[3 * k] + F.t1 * x[3 * k + 1] + F.t2 * x[3 * k + 2];
  }
  // The velocity of b's point of the contact relative to a's, at v, w.
  Vec3 relative_velocity(std::size_t k, const std::vector<Vec3>& v,
                         const std::vector<Vec3>& w) const {
    const auto a = std::size_t(a_[k]), b = std::size_t(b_[k]);
    return (v[b] + w[b].cross(lever_b(k))) - (v[a] + w[a].cross(lever_a(k)));
  }
  // Contact k's normal row v_n + b at velocities v, w.
  double row_of(std::size_t k, const std::vector<Vec3>& v, const std::vector<Vec3>& w) const {
    return normal(k).dot(relative_velocity(k, v, w)) + bias_[k];
  }
  // A Gershgorin bound on the largest eigenvalue of contact k's 3x3 block
  // of N, in its frame.
  double block_bound(std::size_t k) const;
  // Each body of finite mass's contacts, in contact order.
  const ContactAdjacency& adjacency() const { return adj_; }
  // The bilateral rows (x's rows from 3 contact_count() on), and N's
  // diagonal on them.
  const std::vector<BilateralRow>& rows() const { return rows_; }
  double row_diagonal(std::size_t j) const { return row_diag_[j]; }

  // Sums acc(k, mu_k, part) over contacts k (rows 3k..3k+2) and
  // row(i, lo, hi, part) over bilateral rows i, in fixed chunks of contacts
  // added in chunk order: the same bits for any thread count.
  // Part needs += and a default constructor that gives the neutral element.
  template <class Part, class ContactFn, class RowFn>
  Part reduce(ContactFn acc, RowFn row) const;

 private:
  // dv = M^-1 J^T x (+ v_free); y = J v (+ b). scatter_bodies takes the
  // contacts' world impulses from P (three numbers each, and a spare past
  // them) and the bilateral rows from x.
  void scatter(ConstSpan x, bool add_free, std::vector<Vec3>& dv, std::vector<Vec3>& dw) const;
  void scatter_bodies(const double* P, ConstSpan x, bool add_free, std::vector<Vec3>& dv,
                      std::vector<Vec3>& dw) const;
  // The kernel's three functions as kernel.inl builds them for one
  // instruction set (explicit instantiations in kernel_*.cpp); the ones
  // above call those of kernel_isa().
  template <Isa I>
  TrialSums apgd_step_on(ConstSpan x, ConstSpan x_old, Span x1, ConstSpan gx, ConstSpan g_old,
                         Momentum momentum, double step) const;
  template <Isa I>
  TrialSums apgd_gradient_on(ConstSpan x1, Span g1, ConstSpan x, ConstSpan x_old,
                             Momentum momentum, TrialSums& t, const NextTrial& next) const;
  template <Isa I>
  void scatter_bodies_on(const double* P, ConstSpan x, bool add_free, std::vector<Vec3>& dv,
                         std::vector<Vec3>& dw,
                         const std::vector<std::uint32_t>* only = nullptr) const;
  // dv, dw += M^-1 J^T x over x's bilateral rows; with `only` (ascending),
  // for the listed bodies alone.
  void add_row_impulses(ConstSpan x, std::vector<Vec3>& dv, std::vector<Vec3>& dw,
                        const std::vector<std::uint32_t>* only = nullptr) const;
  void gather(const std::vector<Vec3>& v, const std::vector<Vec3>& w, bool add_bias, Span y) const;
  // Contact k's rows of J v (+ b with add_bias), as gather writes them.
  std::array<double, 3> gather_contact(std::size_t k, const std::vector<Vec3>& v,
                                       const std::vector<Vec3>& w, bool add_bias) const;
  // Contact k's rows of the gradient at x from v, w = velocities(x): J v +
  // b and, on a yielding contact, E x, as gather then add_softness make them.
  std::array<double, 3> gradient_rows(std::size_t k, const std::vector<Vec3>& v,
                                      const std::vector<Vec3>& w, ConstSpan x) const;
  // The residual of x, its gradient's contact rows by contact_g(k) and
  // its bilateral rows' by row_g(i).
  template <class ContactG, class RowG>
  double residual_of(ConstSpan x, ContactG contact_g, RowG row_g) const;
  void gather_rows(const std::vector<Vec3>& v, const std::vector<Vec3>& w, bool add_bias,
                   Span y) const;
  // A bound on the largest eigenvalue of one body's part of a contact's
  // block of N, at lever arm r (world rows).
  double block_scale(int body, const Vec3& r) const;
  // assemble's stages.
  void size_for(std::size_t nc, std::size_t bodies);
  void pack_inverse_masses(const SolverBodies& B);
  double assemble_contact(std::size_t k, const Contacts& c, const MaterialTable& materials,
                          double h, const ContactSettings& settings);
  double assemble_rows();

  const SolverBodies* bodies_ = nullptr;
  // The contacts assembled, read by overlaps_within (their gaps and radii);
  // like the bodies, they outlive the step's solve.
  const Contacts* contacts_ = nullptr;
  // Contacts, structure of arrays.
  std::vector<std::int32_t> a_, b_;
  // Normal and friction in blocks of kLanes contacts: component c (0-2 the
  // normal, 3 the friction coefficient) of contact k at
  // frame_[k / kLanes * kFrameBlock + c * kLanes + k % kLanes], so the
  // kernel loads one component of four contacts at once, and a block of
  // float is one 64-byte cache line. The kernel needs no tangents (world
  // rows); the scalar code's are stored apart (tangent_).
  static constexpr std::size_t kLanes = 4, kFrameBlock = 4 * kLanes;
  AlignedVector<StoredScalar> frame_;
  // Lever arms contact by contact, a's then b's: lever_[6 k + 3 side + c].
  // The bodies' pass reads one contact's arm of one side, as one vector;
  // the gather reads a block's, and transposes them. One spare at the end:
  // a vector load of the last arm reads a fourth number it does not use.
  std::vector<StoredScalar> lever_;
  const StoredScalar* frame_at(std::size_t k) const {
    return &frame_[k / kLanes * kFrameBlock + k % kLanes];
  }
  // The tangents of contact k's frame, made from its stored normal once per
  // step: the scalar passes (warm start, the changes of rows, the scatter
  // and gather outside the kernel, PGS, the safeguards) take a frame about
  // ten times a step, and making one costs a division.
  void make_tangents(std::size_t k);
  std::vector<Vec3> tangent_;
  Vec3 lever(std::size_t k, std::size_t side) const {
    const StoredScalar* r = &lever_[6 * k + 3 * side];
    return {double(r[0]), double(r[1]), double(r[2])};
  }
  std::vector<double> bias_;
  // eps per contact (0: rigid), padded like bias_; the blocks of four
  // with a yielding contact, which the kernel alone gives the E x term,
  // and the yielding contacts, for the passes outside it.
  std::vector<double> softness_;
  std::vector<std::uint8_t> soft_block_;
  std::vector<std::uint32_t> soft_;
  void mark_soft_blocks();
  // g += E x for x in the contacts' frames: a yielding contact's normal row
  // carries its softness times its impulse.
  void add_softness(ConstSpan x, Span g) const;
  double step_ = 0.0;  // h, for overlaps_within
  // APGD's metric, per block of four contacts: their step weights w, then
  // the bounds 1 / w (apgd_step scales the step by w and |d|^2 by 1 / w:
  // both loaded, no division).
  static constexpr std::size_t kMetricBlock = 2 * kLanes;
  AlignedVector<float> metric_;
  std::vector<double> row_metric_;
  // Bodies as the bodies' pass reads them, one 32-byte record each: the
  // inverse inertia's upper triangle (00 01 02 11 12 22), the inverse mass,
  // a bound on the inverse inertia's largest eigenvalue (the metric's); in
  // float, a third of the 80 bytes of SolverBodies' double Mat3 and mass,
  // which would be the pass's largest stream. scatter_bodies, and so N,
  // uses them alone, so N stays symmetric and positive; the wall guard and
  // PGS's own sweeps apply SolverBodies' doubles, which differ from them by
  // float's rounding.
  static constexpr std::size_t kMassStride = 8;
  AlignedVector<StoredScalar> inverse_mass_;
  std::vector<BilateralRow> rows_;
  std::vector<double> row_diag_;
  ContactAdjacency adj_;  // bodies with finite mass
  double diag_max_ = 1.0;
  mutable std::vector<Vec3> dv_, dw_;
  mutable std::vector<double> impulse_;
};

// Projection of (gn, gt1, gt2) onto the cone |gt| <= mu gn. Inline: it runs
// twice per contact per iteration.
inline void project_cone(double mu, double& gn, double& gt1, double& gt2) {
  if (mu <= 0.0) {  // frictionless: a half-line
    gn = std::max(gn, 0.0);
    gt1 = gt2 = 0.0;
    return;
  }
  // The common cases, sticking (inside the cone) and separating (inside the
  // polar cone), are decided on squares: no square root, no division.
  const double s2 = gt1 * gt1 + gt2 * gt2, mu2 = mu * mu;
  if (gn >= 0.0 && s2 <= mu2 * gn * gn) return;
  if (gn <= 0.0 && mu2 * s2 <= gn * gn) {
    gn = gt1 = gt2 = 0.0;
    return;
  }
  // Sliding: onto the cone's surface. s > 0 here (s = 0 fell in a case above).
  // Plain sqrt, not std::hypot: impulses cannot overflow. One division.
  const double s = std::sqrt(s2);
  const double along = mu * s + gn, q = 1.0 / ((mu2 + 1.0) * s);
  gn = along * s * q;
  const double scale = mu * along * q;
  gt1 *= scale;
  gt2 *= scale;
}

template <class Part, class ContactFn, class RowFn>
Part CcpProblem::reduce(ContactFn acc, RowFn row) const {
  auto contacts = [&](std::size_t begin, std::size_t end, Part& part) {
    for (std::size_t k = begin; k < end; ++k) acc(std::ptrdiff_t(k), friction(k), part);
  };
  Part total = reduce_chunks<Part>(a_.size(), contacts);
  const auto nc = std::ptrdiff_t(a_.size());
  for (std::size_t j = 0; j < rows_.size(); ++j)
    row(3 * nc + std::ptrdiff_t(j), rows_[j].lo, rows_[j].hi, total);
  return total;
}

}  // namespace ces
