// Projected-gradient solvers for the CCP (see ccp.hpp). Both take x as the
// warm start and return the best iterate found.
#include <algorithm>
#include <cmath>
#include <deque>

#include "dynamics/ccp.hpp"

namespace ces {
namespace {

// f(x) = 1/2 x^T N x + r^T x = 1/2 x^T (g + r) with g = N x + r; r = g(0).
double objective(const VectorXd& x, const VectorXd& g, const VectorXd& r) {
  return 0.5 * (x.dot(g) + x.dot(r));
}

struct Best {
  SolveStats stats;
  VectorXd x;
  double residual = std::numeric_limits<double>::infinity();
  void offer(const VectorXd& candidate, double rms, double max) {
    if (rms < residual) {
      residual = rms;
      x = candidate;
      stats.residual = rms;
      stats.residual_max = max;
    }
  }
};

}  // namespace

// Accelerated projected gradient descent with adaptive step, backtracking and
// gradient restart (Mazhar, Heyn, Negrut, Tasora, ACM TOG 34(3), 2015, Alg. 2).
SolveStats solve_apgd(const CcpProblem& p, const SolverSettings& s, VectorXd& x) {
  const auto m = std::ptrdiff_t(p.row_count());
  Best best;
  if (m == 0) return {0, 0.0, 0.0, true};
  VectorXd r, g, gx, y = x, x1, y1, d;
  p.gradient(VectorXd::Zero(m), r);
  // Initial Lipschitz estimate from a secant through a perturbed point.
  VectorXd probe = x;
  probe.array() += 1.0 / p.diagonal_max();
  VectorXd Nd;
  p.multiply(x - probe, Nd);
  double L = std::max(Nd.norm() / (x - probe).norm(), 1e-12 * p.diagonal_max());
  double theta = 1.0;
  int it = 0;
  for (; it < s.max_iterations; ++it) {
    p.gradient(y, g);
    const double fy = objective(y, g, r);
    for (;;) {
      x1 = y - g / L;
      p.project(x1);
      p.gradient(x1, gx);
      d = x1 - y;
      if (objective(x1, gx, r) <= fy + g.dot(d) + 0.5 * L * d.squaredNorm() + 1e-15 * std::abs(fy) ||
          L > 1e3 * p.diagonal_max() * double(m))
        break;
      L *= 2.0;
    }
    double rms, max;
    p.residual(x1, gx, rms, max);
    best.offer(x1, rms, max);
    if (rms <= s.tolerance) {
      best.stats.converged = true;
      ++it;
      break;
    }
    const double theta1 = 0.5 * (-theta * theta + theta * std::sqrt(theta * theta + 4.0));
    const double beta = theta * (1.0 - theta) / (theta * theta + theta1);
    y1 = (1.0 + beta) * x1 - beta * x;
    if (g.dot(x1 - x) > 0.0) {  // restart: momentum points uphill
      y1 = x1;
      theta = 1.0;
    } else {
      theta = theta1;
    }
    x.swap(x1);
    y.swap(y1);
    L *= 0.9;
  }
  best.stats.iterations = it;
  x = best.x;
  return best.stats;
}

// Spectral projected gradient with Barzilai-Borwein steps and a non-monotone
// line search (Birgin, Martinez, Raydan, SIAM J. Optim. 10(4), 2000), the
// seed paper's method. f is quadratic, so the line search is exact arithmetic
// on gd and dNd: one product N d per iteration.
SolveStats solve_spg(const CcpProblem& p, const SolverSettings& s, VectorXd& x) {
  const auto m = std::ptrdiff_t(p.row_count());
  if (m == 0) return {0, 0.0, 0.0, true};
  constexpr int kMemory = 10;
  constexpr double kSufficient = 1e-4;
  const double alpha_min = 1e-10 / p.diagonal_max(), alpha_max = 1e10 / p.diagonal_max();
  p.project(x);
  VectorXd r, g, d, Nd;
  p.gradient(VectorXd::Zero(m), r);
  p.gradient(x, g);
  double f = objective(x, g, r);
  std::deque<double> history{f};
  double alpha = 1.0 / p.diagonal_max();
  Best best;
  int it = 0;
  for (; it < s.max_iterations; ++it) {
    double rms, max;
    p.residual(x, g, rms, max);
    best.offer(x, rms, max);
    if (rms <= s.tolerance) {
      best.stats.converged = true;
      break;
    }
    d = x - alpha * g;
    p.project(d);
    d -= x;
    p.multiply(d, Nd);
    const double gd = g.dot(d), dNd = d.dot(Nd);
    const double f_ref = *std::max_element(history.begin(), history.end());
    double lambda = 1.0;
    double f_new = f + gd + 0.5 * dNd;
    while (f_new > f_ref + kSufficient * lambda * gd && lambda > 1e-12) {
      // Minimiser of the quadratic along d, safeguarded to [0.1, 0.5] lambda.
      const double trial = dNd > 0.0 ? -gd / dNd : 0.5 * lambda;
      lambda = std::clamp(trial, 0.1 * lambda, 0.5 * lambda);
      f_new = f + lambda * gd + 0.5 * lambda * lambda * dNd;
    }
    x += lambda * d;
    g += lambda * Nd;
    f = f_new;
    history.push_back(f);
    if (history.size() > kMemory) history.pop_front();
    const double sy = lambda * lambda * dNd, ss = lambda * lambda * d.squaredNorm();
    alpha = sy > 0.0 ? std::clamp(ss / sy, alpha_min, alpha_max) : alpha_max;
  }
  if (!best.stats.converged) {
    double rms, max;
    p.residual(x, g, rms, max);
    best.offer(x, rms, max);
  }
  best.stats.iterations = it;
  x = best.x;
  return best.stats;
}

SolveStats solve(const CcpProblem& p, const SolverSettings& s, VectorXd& x) {
  switch (s.method) {
    case SolverMethod::APGD: return solve_apgd(p, s, x);
    case SolverMethod::SPG: return solve_spg(p, s, x);
    case SolverMethod::PGS: return p.solve_pgs(x, s);
  }
  return {};
}

}  // namespace ces
