#include "dynamics/solvers.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "common/parallel.hpp"

namespace ces {
namespace {

void copy(ConstSpan from, Span to) { std::copy(from.begin(), from.end(), to.begin()); }

// a.b, summed in an order of its own, the same on every machine: Eigen's
// dot sums in packets as wide as the vector unit the file is built for.
// Eight running sums, the products of rows 8 j + l in lo[l] and of 8 j + 4
// + l in hi[l], then lo += hi, a last four rows into lo, lo's lanes as
// (0 + 2) + (1 + 3), and the rows past a multiple of four one by one.
// (Under four rows: one by one.) It is the order of Eigen 3.4's dot on
// 256-bit vectors.
double dot(ConstSpan a, ConstSpan b) {
  const std::size_t n = a.size(), n4 = n / 4 * 4, n8 = n / 8 * 8;
  auto product = [&](std::size_t i) { return a[i] * b[i]; };
  double sum = n > 0 ? product(0) : 0.0;
  if (n4 == 0) {
    for (std::size_t i = 1; i < n; ++i) sum += product(i);
    return sum;
  }
  std::array<double, 4> lo, hi;
  for (std::size_t l = 0; l < 4; ++l) lo[l] = product(l);
  if (n4 > 4) {
    for (std::size_t l = 0; l < 4; ++l) hi[l] = product(4 + l);
    for (std::size_t i = 8; i < n8; i += 8)
      for (std::size_t l = 0; l < 4; ++l) {
        lo[l] += product(i + l);
        hi[l] += product(i + 4 + l);
      }
    for (std::size_t l = 0; l < 4; ++l) lo[l] += hi[l];
    if (n4 > n8)
      for (std::size_t l = 0; l < 4; ++l) lo[l] += product(n8 + l);
  }
  sum = (lo[0] + lo[2]) + (lo[1] + lo[3]);
  for (std::size_t i = n4; i < n; ++i) sum += product(i);
  return sum;
}

// The stopping rule of every solver: the residual at or under the
// tolerance, and no contact left overlapping by more than the overlap aim
// (SolverSettings::overlap_aim) at the end of the step, nor, where it
// overlaps more already,
// by more than now (CcpProblem::overlaps_within). g is the gradient at the
// iterate.
bool accurate(const CcpProblem& p, const SolverSettings& s, double rms, ConstSpan g, bool world) {
  return rms <= s.tolerance && p.overlaps_within(g, world, s.overlap_aim());
}

// The best iterate's record. Until a finite residual is met the stats say
// NaN: a solve whose every residual was NaN or inf must not report 0.
struct Best {
  SolveStats stats{0, std::numeric_limits<double>::quiet_NaN(), false};
  double residual = std::numeric_limits<double>::infinity();
  bool improves(double rms) const { return rms < residual; }  // false for NaN
  void take(double rms) { residual = stats.residual = rms; }
};

// The Lipschitz constant's first estimate, in the metric: |W^1/2 N W^1/2 u|
// / |u| along u = (1, ..., 1) (W normalises N's diagonal blocks to at most
// 1). u and Nu are scratch.
double initial_lipschitz(const CcpProblem& p, Span u, Span Nu) {
  std::fill(u.begin(), u.end(), 1.0);
  p.scale_by_metric(u);
  p.multiply(u, Nu);
  p.scale_by_metric(Nu);
  return std::max(std::sqrt(dot(Nu, Nu) / double(u.size())), 1e-12);
}

// The five iterates and three gradients of solve_apgd, by role: x, the
// one before it (x_old), the best so far (kept where it lies instead of
// copied; it may be x or x_old), the trial x1 and the next trial, made
// ahead in x1's gradient pass on the guess that x1 is accepted. A trial
// goes where it overwrites none of the others (a backtracking step makes
// x1 again from x and x_old). Accepting x1 passes the roles round instead
// of copying.
class ApgdIterates {
 public:
  ApgdIterates(SolverWorkspace::Apgd& buffers, std::size_t m) {
    for (std::size_t i = 0; i < xs_.size(); ++i) xs_[i] = buffers.iterates[i].take(m);
    for (std::size_t i = 0; i < gs_.size(); ++i) gs_[i] = buffers.gradients[i].take(m);
  }
  Span x() const { return xs_[ix_]; }
  Span x_old() const { return xs_[iold_]; }
  Span best() const { return xs_[ibest_]; }
  Span trial() const { return xs_[i1_]; }
  Span next() const { return xs_[inext_]; }
  Span g() const { return gs_[gx_]; }
  Span g_old() const { return gs_[gold_]; }
  Span g_trial() const { return gs_[g1_]; }

  void trial_is_best() { ibest_ = i1_; }
  // Where the next trial goes: the slot no other role holds.
  void place_next() {
    inext_ = 0;
    while (inext_ == ix_ || inext_ == iold_ || inext_ == ibest_ || inext_ == i1_) ++inext_;
  }
  // x1 becomes x, x becomes x_old, and the next trial, already made, x1.
  void accept() {
    iold_ = std::exchange(ix_, std::exchange(i1_, inext_));
    gold_ = std::exchange(gx_, std::exchange(g1_, gold_));
  }

 private:
  std::array<Span, 5> xs_;
  std::array<Span, 3> gs_;
  std::size_t ix_ = 0, iold_ = 1, ibest_ = 2, i1_ = 3, inext_ = 4;
  std::size_t gx_ = 0, gold_ = 1, g1_ = 2;
};

// What carries from one APGD iteration to the next: the Lipschitz
// estimate, theta, the momentum (y = ca x - cb x_old; at the start and
// after a restart y = x) and the current trial's sums.
struct ApgdState {
  double L = 0.0;
  double theta = 1.0;
  CcpProblem::Momentum momentum;
  CcpProblem::TrialSums t;
};

// x1's gradient pass (making the next trial with it unless `last`),
// doubling L and making x1 again until the sufficient-decrease test holds
// or L passes L_cap. Returns the next iteration's state if x1 is accepted
// (L relaxed by 0.9). A backtracking step changes t.uphill and L, so the
// next iteration's theta and momentum are made again with them.
ApgdState gradient_pass(const CcpProblem& p, const ApgdIterates& v, ApgdState& st, double L_cap,
                        bool last) {
  ApgdState next;
  for (;;) {
    const double theta = st.theta;
    const double theta1 = 0.5 * (-theta * theta + theta * std::sqrt(theta * theta + 4.0));
    const double beta = theta * (1.0 - theta) / (theta * theta + theta1);
    const bool restart = st.t.uphill > 0.0;  // momentum points uphill
    next.theta = restart ? 1.0 : theta1;
    next.momentum = restart ? CcpProblem::Momentum{} : CcpProblem::Momentum{1.0 + beta, beta};
    next.L = st.L * 0.9;
    CcpProblem::NextTrial trial;
    if (!last) trial = {v.next(), v.g(), next.momentum, 1.0 / next.L};
    next.t = p.apgd_gradient(v.trial(), v.g_trial(), v.x(), v.x_old(), st.momentum, st.t, trial);
    if (st.t.dnd <= st.L * st.t.dd * (1.0 + 1e-10) || st.L > L_cap) return next;
    st.L *= 2.0;
    st.t = p.apgd_step(v.x(), v.x_old(), v.trial(), v.g(), v.g_old(), st.momentum, 1.0 / st.L);
  }
}

}  // namespace

// Accelerated projected gradient descent with adaptive step, backtracking and
// gradient restart (Mazhar, Heyn, Negrut, Tasora, ACM TOG 34(3), 2015, Alg. 2),
// with one product N x per iteration instead of the paper's two: the gradient
// is affine, so the gradient at the extrapolated point
//   y' = (1 + beta) x1 - beta x  is  (1 + beta) g(x1) - beta g(x),
// and f is quadratic, so the sufficient-decrease test
//   f(x1) <= f(y) + g(y).d + L/2 |d|^2,  d = x1 - y,
// is exactly d.(g(x1) - g(y)) <= L |d|^2, which needs no objective values.
// The projected step is taken in the metric of W = diag(w_k) (one weight
// per contact, CcpProblem::metric_weight, about the inverse of its block of
// N): x1 = Π(y - W g(y) / L), and the test measures |d|^2 in W^-1. A
// contact's weight scales its three rows alike and the cone is a cone, so
// the projection in that metric is still the plain one, contact by contact.
// Particles from 0.5 to 2 mm of copper and FR-4 have inverse masses 300
// times apart; with one step for all, set by the lightest, the heavy ones'
// impulses would move 300 times too slowly (docs/accuracy.md, section 2,
// has the iterations the reference scene needs).
// The sums of an iteration come from the kernel's pass over the rows,
// which makes x1's gradient and, on the guess that x1 is accepted, the next
// trial (a rejected x1 costs a trial pass more). The kernel runs on world
// rows (CcpProblem::to_world): x is changed to them here and back at the
// end.
SolveStats solve_apgd(const CcpProblem& p, const SolverSettings& s, Span out, SolverWorkspace& ws) {
  const std::size_t m = p.row_count();
  if (m == 0) return {0, 0.0, true};
  ApgdIterates v(ws.apgd, m);
  p.to_world(out, v.x());
  p.world_gradient(v.x(), v.g());
  copy(v.x(), v.best());  // the best until an iterate improves on it
  ApgdState st;
  st.L = initial_lipschitz(p, v.trial(), v.g_trial());
  const double L_cap = 1e3 * double(m);
  st.t = p.apgd_step(v.x(), v.x_old(), v.trial(), v.g(), v.g_old(), st.momentum, 1.0 / st.L);
  Best record;
  int it = 0;
  for (; it < s.max_iterations; ++it) {
    v.place_next();
    const ApgdState next = gradient_pass(p, v, st, L_cap, it + 1 == s.max_iterations);
    const double rms = std::sqrt(st.t.res_sum / double(m));
    if (accurate(p, s, rms, v.g_trial(), true)) {
      record.take(rms);
      record.stats.converged = true;
      record.stats.iterations = it + 1;
      p.to_local(v.trial(), out);
      return record.stats;
    }
    if (record.improves(rms)) {
      record.take(rms);
      v.trial_is_best();
    }
    v.accept();
    st = next;
  }
  record.stats.iterations = it;
  p.to_local(v.best(), out);
  return record.stats;
}

// Spectral projected gradient with Barzilai-Borwein steps and a non-monotone
// line search (Birgin, Martinez, Raydan, SIAM J. Optim. 10(4), 2000), the
// seed paper's method. f is quadratic, so the line search is exact arithmetic
// on gd and dNd: one product N d per iteration.
SolveStats solve_spg(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws) {
  const std::size_t m = p.row_count();
  if (m == 0) return {0, 0.0, true};
  constexpr int kMemory = 10;
  constexpr double kSufficient = 1e-4;
  const double alpha_min = 1e-10 / p.diagonal_max(), alpha_max = 1e10 / p.diagonal_max();
  SolverWorkspace::Spg& buffers = ws.spg;
  const Span r = buffers.bias.take(m), g = buffers.gradient.take(m), d = buffers.direction.take(m),
             nd = buffers.product.take(m), best = buffers.best.take(m);
  p.project(x);
  std::fill(d.begin(), d.end(), 0.0);
  p.gradient(d, r);
  p.gradient(x, g);
  // f(x) = 1/2 x^T N x + r^T x = 1/2 x^T (g + r) with g = N x + r.
  double f = 0.5 * (dot(x, g) + dot(x, r));
  std::array<double, kMemory> history;
  history.fill(f);
  double alpha = 1.0 / p.diagonal_max();
  Best record;
  int it = 0;
  for (; it <= s.max_iterations; ++it) {
    const double rms = p.residual(x, g);
    if (record.improves(rms)) {
      record.take(rms);
      copy(x, best);
    }
    if (accurate(p, s, rms, g, false)) {
      record.stats.converged = true;
      break;
    }
    if (it == s.max_iterations) break;
    p.projected_step(x, g, alpha, d);
    for (std::size_t i = 0; i < m; ++i) d[i] -= x[i];
    p.multiply(d, nd);
    const double gd = dot(g, d), dNd = dot(d, nd);
    const double f_ref = *std::max_element(history.begin(), history.end());
    double lambda = 1.0;
    double f_new = f + gd + 0.5 * dNd;
    while (f_new > f_ref + kSufficient * lambda * gd && lambda > 1e-12) {
      // Minimiser of the quadratic along d, safeguarded to [0.1, 0.5] lambda.
      const double trial = dNd > 0.0 ? -gd / dNd : 0.5 * lambda;
      lambda = std::clamp(trial, 0.1 * lambda, 0.5 * lambda);
      f_new = f + lambda * gd + 0.5 * lambda * lambda * dNd;
    }
    for (std::size_t i = 0; i < m; ++i) {
      x[i] += lambda * d[i];
      g[i] += lambda * nd[i];
    }
    f = f_new;
    history[std::size_t(it % kMemory)] = f;
    const double sy = lambda * lambda * dNd, ss = lambda * lambda * dot(d, d);
    alpha = sy > 0.0 ? std::clamp(ss / sy, alpha_min, alpha_max) : alpha_max;
  }
  record.stats.iterations = std::min(it, s.max_iterations);
  copy(best, x);
  return record.stats;
}

// Projected Gauss-Seidel (Anitescu, Tasora, Comput. Optim. Appl.
// 47(2), 2010): contact by contact, then bilateral row by row, each
// projected step applied at once to the running velocities v, w, which the
// next rows read.
namespace {

// One sweep over the contacts, contact k's rows by its step steps[k].
void pgs_contacts(const CcpProblem& p, ConstSpan steps, Span x, std::vector<Vec3>& v,
                  std::vector<Vec3>& w) {
  const SolverBodies& B = p.bodies();
  for (std::size_t k = 0; k < p.contact_count(); ++k) {
    const double step = steps[k];
    if (step <= 0.0) continue;
    const Vec3 ra = p.lever_a(k), rb = p.lever_b(k);
    const auto [n, t1, t2] = p.frame(k);
    const Vec3 rel = p.relative_velocity(k, v, w);
    const std::size_t i = 3 * k;
    double gn = x[i] - step * (n.dot(rel) + p.bias(k) + p.softness(k) * x[i]);
    double g1 = x[i + 1] - step * t1.dot(rel);
    double g2 = x[i + 2] - step * t2.dot(rel);
    project_cone(p.friction(k), gn, g1, g2);
    const Vec3 dP = n * (gn - x[i]) + t1 * (g1 - x[i + 1]) + t2 * (g2 - x[i + 2]);
    x[i] = gn;
    x[i + 1] = g1;
    x[i + 2] = g2;
    const auto a = std::size_t(p.body_a(k)), b = std::size_t(p.body_b(k));
    v[a] -= B.inv_mass[a] * dP;
    w[a] -= B.inv_inertia[a] * ra.cross(dP);
    v[b] += B.inv_mass[b] * dP;
    w[b] += B.inv_inertia[b] * rb.cross(dP);
  }
}

// One sweep over the bilateral rows, row j's by relaxation / N_jj.
void pgs_rows(const CcpProblem& p, double relaxation, Span x, std::vector<Vec3>& v,
              std::vector<Vec3>& w) {
  const std::size_t base = 3 * p.contact_count();
  for (std::size_t j = 0; j < p.rows().size(); ++j) {
    const double diagonal = p.row_diagonal(j);
    if (diagonal <= 0.0) continue;
    const BilateralRow& row = p.rows()[j];
    double& xi = x[base + j];
    const double next = std::clamp(
        xi - relaxation / diagonal * (row_velocity(v, w, row) + row.bias), row.lo, row.hi);
    apply_row(p.bodies(), row, next - xi, v, w);
    xi = next;
  }
}

}  // namespace

SolveStats solve_pgs(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws) {
  std::vector<Vec3>& v = ws.pgs.v;
  std::vector<Vec3>& w = ws.pgs.w;
  p.velocities(x, v, w);
  const std::size_t nc = p.contact_count();
  // One step per contact block: with the normal row's 1/diag alone, a
  // cluster's tangential rows (large lever arms) are over-stepped and diverge.
  const Span steps = ws.pgs.steps.take(nc), g = ws.pgs.gradient.take(x.size());
  for (std::size_t k = 0; k < nc; ++k) {
    const double bound = p.block_bound(k);
    steps[k] = bound > 0.0 ? s.pgs_relaxation / bound : 0.0;
  }
  SolveStats stats;
  for (int it = 0; it < s.max_iterations; ++it) {
    pgs_contacts(p, steps, x, v, w);
    pgs_rows(p, s.pgs_relaxation, x, v, w);
    stats.iterations = it + 1;
    p.gradient(x, g);
    stats.residual = p.residual(x, g);
    if (accurate(p, s, stats.residual, g, false)) {
      stats.converged = true;
      break;
    }
  }
  return stats;
}

SolveStats solve(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws) {
  switch (s.method) {
    case SolverMethod::APGD: return solve_apgd(p, s, x, ws);
    case SolverMethod::SPG: return solve_spg(p, s, x, ws);
    case SolverMethod::PGS: return solve_pgs(p, s, x, ws);
  }
  return {};
}

}  // namespace ces
