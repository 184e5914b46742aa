#include "dynamics/ccp.hpp"

#include <algorithm>
#include <cmath>

namespace ces {
namespace {

constexpr std::ptrdiff_t kParallelMin = 256;  // below this, threads cost more than they save

// A tangent basis that depends only on n, so frames are reproducible.
void tangents(const Vec3& n, Vec3& t1, Vec3& t2) {
  const Vec3 helper = std::abs(n.x()) < 0.57735 ? Vec3::UnitX()
                      : std::abs(n.y()) < 0.57735 ? Vec3::UnitY()
                                                  : Vec3::UnitZ();
  t1 = n.cross(helper).normalized();
  t2 = n.cross(t1);
}

double row_mass(const SolverBodies& B, int i, const Vec3& lin, const Vec3& ang) {
  if (i < 0) return 0.0;
  const auto u = std::size_t(i);
  return B.inv_mass[u] * lin.squaredNorm() + ang.dot(B.inv_inertia[u] * ang);
}

Vec3 point_velocity(const std::vector<Vec3>& v, const std::vector<Vec3>& w, int i, const Vec3& r) {
  const auto u = std::size_t(i);
  return v[u] + w[u].cross(r);
}

double row_velocity(const std::vector<Vec3>& v, const std::vector<Vec3>& w, const BilateralRow& row) {
  double s = 0.0;
  if (row.a >= 0) s += row.lin_a.dot(v[std::size_t(row.a)]) + row.ang_a.dot(w[std::size_t(row.a)]);
  if (row.b >= 0) s += row.lin_b.dot(v[std::size_t(row.b)]) + row.ang_b.dot(w[std::size_t(row.b)]);
  return s;
}

void apply_row(const SolverBodies& B, const BilateralRow& row, double impulse,
               std::vector<Vec3>& v, std::vector<Vec3>& w) {
  if (row.a >= 0) {
    const auto a = std::size_t(row.a);
    v[a] += B.inv_mass[a] * impulse * row.lin_a;
    w[a] += B.inv_inertia[a] * (impulse * row.ang_a);
  }
  if (row.b >= 0) {
    const auto b = std::size_t(row.b);
    v[b] += B.inv_mass[b] * impulse * row.lin_b;
    w[b] += B.inv_inertia[b] * (impulse * row.ang_b);
  }
}

}  // namespace

void SolverBodies::resize(std::size_t n) {
  x.resize(n);
  v.resize(n);
  w.resize(n);
  v_free.resize(n);
  w_free.resize(n);
  inv_mass.resize(n);
  inv_inertia.resize(n);
}

void CcpProblem::assemble(const Contacts& c, const SolverBodies& B,
                          std::vector<BilateralRow> rows, double h,
                          const ContactSettings& settings) {
  bodies_ = &B;
  rows_ = std::move(rows);
  const std::size_t nc = c.size();
  a_ = c.body_a;
  b_ = c.body_b;
  n_ = c.normal;
  mu_ = c.friction;
  t1_.resize(nc);
  t2_.resize(nc);
  ra_.resize(nc);
  rb_.resize(nc);
  bias_.resize(nc);
  diag_.resize(nc);
  diag_max_ = 0.0;
  for (std::size_t k = 0; k < nc; ++k) {
    const Vec3& n = n_[k];
    tangents(n, t1_[k], t2_[k]);
    ra_[k] = c.point[k] - B.x[std::size_t(a_[k])];
    rb_[k] = c.point[k] - B.x[std::size_t(b_[k])];
    // Stabilization: close a positive gap exactly this step, push an overlap
    // out no faster than the recovery speed.
    double bias = std::max(c.gap[k] / h, -settings.recovery_speed);
    const double approach = n.dot(point_velocity(B.v, B.w, b_[k], rb_[k]) -
                                  point_velocity(B.v, B.w, a_[k], ra_[k]));
    const bool impact = approach < -settings.restitution_threshold && c.gap[k] + h * approach < 0.0;
    if (impact && c.restitution[k] > 0.0) bias = std::min(bias, c.restitution[k] * approach);
    bias_[k] = bias;
    diag_[k] = row_mass(B, a_[k], n, ra_[k].cross(n)) + row_mass(B, b_[k], n, rb_[k].cross(n));
    diag_max_ = std::max(diag_max_, diag_[k]);
  }
  row_diag_.resize(rows_.size());
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const BilateralRow& r = rows_[j];
    row_diag_[j] = row_mass(B, r.a, r.lin_a, r.ang_a) + row_mass(B, r.b, r.lin_b, r.ang_b);
    diag_max_ = std::max(diag_max_, row_diag_[j]);
  }
  if (diag_max_ <= 0.0) diag_max_ = 1.0;
  adj_.build(a_, b_, B.inv_mass.size(),
             [&](std::int32_t i) { return B.inv_mass[std::size_t(i)] > 0.0; });
}

void CcpProblem::scatter(const VectorXd& x, bool add_free, std::vector<Vec3>& dv,
                         std::vector<Vec3>& dw) const {
  const SolverBodies& B = *bodies_;
  const auto nc = std::ptrdiff_t(a_.size());
  const auto nb = std::ptrdiff_t(B.inv_mass.size());
  impulse_.resize(a_.size());
  dv.resize(B.inv_mass.size());
  dw.resize(B.inv_mass.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k) {
    const auto u = std::size_t(k);
    impulse_[u] = n_[u] * x[3 * k] + t1_[u] * x[3 * k + 1] + t2_[u] * x[3 * k + 2];
  }
#pragma omp parallel for schedule(static) if (nb > kParallelMin)
  for (std::ptrdiff_t i = 0; i < nb; ++i) {
    const auto u = std::size_t(i);
    Vec3 lin = Vec3::Zero(), ang = Vec3::Zero();
    for (std::uint32_t e = adj_.offset[u]; e < adj_.offset[u + 1]; ++e) {
      const std::uint32_t entry = adj_.entry[e];
      const std::size_t k = entry >> 1;
      if (entry & 1) {
        lin += impulse_[k];
        ang += rb_[k].cross(impulse_[k]);
      } else {
        lin -= impulse_[k];
        ang -= ra_[k].cross(impulse_[k]);
      }
    }
    dv[u] = B.inv_mass[u] * lin;
    dw[u] = B.inv_inertia[u] * ang;
    if (add_free) {
      dv[u] += B.v_free[u];
      dw[u] += B.w_free[u];
    }
  }
  for (std::size_t j = 0; j < rows_.size(); ++j)
    apply_row(B, rows_[j], x[std::ptrdiff_t(3 * a_.size() + j)], dv, dw);
}

void CcpProblem::gather(const std::vector<Vec3>& v, const std::vector<Vec3>& w, bool add_bias,
                        VectorXd& y) const {
  const auto nc = std::ptrdiff_t(a_.size());
  y.resize(std::ptrdiff_t(row_count()));
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k) {
    const auto u = std::size_t(k);
    const Vec3 rel = point_velocity(v, w, b_[u], rb_[u]) - point_velocity(v, w, a_[u], ra_[u]);
    y[3 * k] = n_[u].dot(rel) + (add_bias ? bias_[u] : 0.0);
    y[3 * k + 1] = t1_[u].dot(rel);
    y[3 * k + 2] = t2_[u].dot(rel);
  }
  for (std::size_t j = 0; j < rows_.size(); ++j)
    y[std::ptrdiff_t(3 * a_.size() + j)] =
        row_velocity(v, w, rows_[j]) + (add_bias ? rows_[j].bias : 0.0);
}

void CcpProblem::multiply(const VectorXd& x, VectorXd& y) const {
  scatter(x, false, dv_, dw_);
  gather(dv_, dw_, false, y);
}

void CcpProblem::velocities(const VectorXd& x, std::vector<Vec3>& v, std::vector<Vec3>& w) const {
  scatter(x, true, v, w);
}

void CcpProblem::gradient(const VectorXd& x, VectorXd& g) const {
  scatter(x, true, dv_, dw_);
  gather(dv_, dw_, true, g);
}

void CcpProblem::project(VectorXd& x) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k)
    project_cone(mu_[std::size_t(k)], x[3 * k], x[3 * k + 1], x[3 * k + 2]);
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    double& v = x[3 * nc + std::ptrdiff_t(j)];
    v = std::clamp(v, rows_[j].lo, rows_[j].hi);
  }
}

void CcpProblem::residual(const VectorXd& x, const VectorXd& g, double& rms, double& max) const {
  // One fused pass, no temporaries (it runs every iteration). Partial sums
  // over fixed chunks, added in chunk order: the same bits for any thread count.
  constexpr std::ptrdiff_t kChunk = 2048;
  const double s = 1.0 / diag_max_;
  const auto nc = std::ptrdiff_t(a_.size());
  const std::ptrdiff_t chunks = (nc + kChunk - 1) / kChunk;
  partial_sum_.assign(std::size_t(chunks) + 1, 0.0);
  partial_max_.assign(std::size_t(chunks) + 1, 0.0);
  auto add = [s](double xi, double pi, double& sum, double& largest) {
    const double r = (xi - pi) / s;
    sum += r * r;
    largest = std::max(largest, std::abs(r));
  };
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t ch = 0; ch < chunks; ++ch) {
    double sum = 0.0, largest = 0.0;
    for (std::ptrdiff_t k = ch * kChunk; k < std::min(nc, (ch + 1) * kChunk); ++k) {
      double pn = x[3 * k] - s * g[3 * k], p1 = x[3 * k + 1] - s * g[3 * k + 1],
             p2 = x[3 * k + 2] - s * g[3 * k + 2];
      project_cone(mu_[std::size_t(k)], pn, p1, p2);
      add(x[3 * k], pn, sum, largest);
      add(x[3 * k + 1], p1, sum, largest);
      add(x[3 * k + 2], p2, sum, largest);
    }
    partial_sum_[std::size_t(ch)] = sum;
    partial_max_[std::size_t(ch)] = largest;
  }
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const double xi = x[3 * nc + std::ptrdiff_t(j)];
    add(xi, std::clamp(xi - s * g[3 * nc + std::ptrdiff_t(j)], rows_[j].lo, rows_[j].hi),
        partial_sum_.back(), partial_max_.back());
  }
  double sum = 0.0;
  max = 0.0;
  for (std::size_t c = 0; c < partial_sum_.size(); ++c) {
    sum += partial_sum_[c];
    max = std::max(max, partial_max_[c]);
  }
  const auto m = x.size();
  rms = m > 0 ? std::sqrt(sum / double(m)) : 0.0;
}

void CcpProblem::world_impulses(const VectorXd& x, std::vector<Vec3>& out) const {
  out.resize(a_.size());
  for (std::size_t k = 0; k < a_.size(); ++k) {
    const auto i = std::ptrdiff_t(3 * k);
    out[k] = n_[k] * x[i] + t1_[k] * x[i + 1] + t2_[k] * x[i + 2];
  }
}

void CcpProblem::warm_start(const std::vector<ContactKey>& keys,
                            const std::vector<ContactKey>& prev_keys,
                            const std::vector<Vec3>& prev_impulse, const VectorXd& prev_x,
                            VectorXd& x) const {
  x.setZero(std::ptrdiff_t(row_count()));
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const auto it = std::lower_bound(prev_keys.begin(), prev_keys.end(), keys[k]);
    if (it == prev_keys.end() || !(*it == keys[k])) continue;
    const Vec3& P = prev_impulse[std::size_t(it - prev_keys.begin())];
    const auto i = std::ptrdiff_t(3 * k);
    x[i] = n_[k].dot(P);
    x[i + 1] = t1_[k].dot(P);
    x[i + 2] = t2_[k].dot(P);
  }
  const auto base = std::ptrdiff_t(3 * a_.size());
  const auto prev_base = prev_x.size() - std::ptrdiff_t(rows_.size());
  if (prev_base >= 0 && prev_base % 3 == 0)
    for (std::size_t r = 0; r < rows_.size(); ++r)
      x[base + std::ptrdiff_t(r)] = prev_x[prev_base + std::ptrdiff_t(r)];
  project(x);
}

SolveStats CcpProblem::solve_pgs(VectorXd& x, const SolverSettings& s) const {
  const SolverBodies& B = *bodies_;
  std::vector<Vec3> v, w;
  velocities(x, v, w);
  const double omega = s.pgs_relaxation;
  const std::size_t nc = a_.size();
  VectorXd g;
  SolveStats stats;
  for (int it = 0; it < s.max_iterations; ++it) {
    for (std::size_t k = 0; k < nc; ++k) {
      if (diag_[k] <= 0.0) continue;
      const Vec3 rel = point_velocity(v, w, b_[k], rb_[k]) - point_velocity(v, w, a_[k], ra_[k]);
      const double step = omega / diag_[k];
      const auto i = std::ptrdiff_t(3 * k);
      double gn = x[i] - step * (n_[k].dot(rel) + bias_[k]);
      double g1 = x[i + 1] - step * t1_[k].dot(rel);
      double g2 = x[i + 2] - step * t2_[k].dot(rel);
      project_cone(mu_[k], gn, g1, g2);
      const Vec3 dP = n_[k] * (gn - x[i]) + t1_[k] * (g1 - x[i + 1]) + t2_[k] * (g2 - x[i + 2]);
      x[i] = gn;
      x[i + 1] = g1;
      x[i + 2] = g2;
      const auto a = std::size_t(a_[k]), b = std::size_t(b_[k]);
      v[a] -= B.inv_mass[a] * dP;
      w[a] -= B.inv_inertia[a] * ra_[k].cross(dP);
      v[b] += B.inv_mass[b] * dP;
      w[b] += B.inv_inertia[b] * rb_[k].cross(dP);
    }
    for (std::size_t j = 0; j < rows_.size(); ++j) {
      if (row_diag_[j] <= 0.0) continue;
      const BilateralRow& row = rows_[j];
      double& xi = x[std::ptrdiff_t(3 * nc + j)];
      const double next = std::clamp(
          xi - omega / row_diag_[j] * (row_velocity(v, w, row) + row.bias), row.lo, row.hi);
      apply_row(B, row, next - xi, v, w);
      xi = next;
    }
    stats.iterations = it + 1;
    gradient(x, g);
    residual(x, g, stats.residual, stats.residual_max);
    if (stats.residual <= s.tolerance) {
      stats.converged = true;
      break;
    }
  }
  return stats;
}

}  // namespace ces
