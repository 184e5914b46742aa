#include "dynamics/ccp.hpp"

#include <algorithm>
#include <cmath>

#include "common/parallel.hpp"

namespace ces {
namespace {

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

Vec3 wide(const Vec3f& f) { return f.cast<double>(); }

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
                          const std::vector<BilateralRow>& rows, double h,
                          const ContactSettings& settings) {
  bodies_ = &B;
  rows_ = rows;
  const std::size_t nc = c.size();
  a_ = c.body_a;
  b_ = c.body_b;
  mu_ = c.friction;
  for (auto* f : {&n_, &t1_, &t2_, &ra_, &rb_}) f->resize(nc);
  bias_.resize(nc);
  double diag_max = 0.0;
#pragma omp parallel for schedule(static) reduction(max : diag_max) if (std::ptrdiff_t(nc) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(nc); ++s) {
    const auto k = std::size_t(s);
    const Vec3& n = c.normal[k];
    Vec3 t1, t2;
    tangents(n, t1, t2);
    const Vec3 ra = c.point[k] - B.x[std::size_t(a_[k])];
    const Vec3 rb = c.point[k] - B.x[std::size_t(b_[k])];
    n_[k] = n.cast<float>();
    t1_[k] = t1.cast<float>();
    t2_[k] = t2.cast<float>();
    ra_[k] = ra.cast<float>();
    rb_[k] = rb.cast<float>();
    // Stabilization: close a positive gap exactly this step, push an overlap
    // out no faster than the recovery speed.
    double bias = std::max(c.gap[k] / h, -settings.recovery_speed);
    const double approach =
        n.dot(point_velocity(B.v, B.w, b_[k], rb) - point_velocity(B.v, B.w, a_[k], ra));
    const bool impact = approach < -settings.restitution_threshold && c.gap[k] + h * approach < 0.0;
    if (impact && c.restitution[k] > 0.0) bias = std::min(bias, c.restitution[k] * approach);
    bias_[k] = bias;
    const Vec3 nw = wide(n_[k]);  // the rounded row the kernel applies
    diag_max = std::max(diag_max, row_mass(B, a_[k], nw, wide(ra_[k]).cross(nw)) +
                                      row_mass(B, b_[k], nw, wide(rb_[k]).cross(nw)));
  }
  row_diag_.resize(rows_.size());
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const BilateralRow& r = rows_[j];
    row_diag_[j] = row_mass(B, r.a, r.lin_a, r.ang_a) + row_mass(B, r.b, r.lin_b, r.ang_b);
    diag_max = std::max(diag_max, row_diag_[j]);
  }
  diag_max_ = diag_max > 0.0 ? diag_max : 1.0;
  adj_.build(a_, b_, B.inv_mass.size(),
             [&](std::int32_t i) { return B.inv_mass[std::size_t(i)] > 0.0; });
}

void CcpProblem::scatter(ConstSpan x, bool add_free, std::vector<Vec3>& dv,
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
    impulse_[u] = wide(n_[u]) * x[3 * u] + wide(t1_[u]) * x[3 * u + 1] + wide(t2_[u]) * x[3 * u + 2];
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
        ang += wide(rb_[k]).cross(impulse_[k]);
      } else {
        lin -= impulse_[k];
        ang -= wide(ra_[k]).cross(impulse_[k]);
      }
    }
    dv[u] = B.inv_mass[u] * lin;
    dw[u] = B.inv_inertia[u] * ang;
    if (add_free) {
      dv[u] += B.v_free[u];
      dw[u] += B.w_free[u];
    }
  }
  for (std::size_t j = 0; j < rows_.size(); ++j) apply_row(B, rows_[j], x[3 * a_.size() + j], dv, dw);
}

void CcpProblem::gather(const std::vector<Vec3>& v, const std::vector<Vec3>& w, bool add_bias,
                        Span y) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k) {
    const auto u = std::size_t(k);
    const Vec3 rel = point_velocity(v, w, b_[u], wide(rb_[u])) - point_velocity(v, w, a_[u], wide(ra_[u]));
    y[3 * u] = wide(n_[u]).dot(rel) + (add_bias ? bias_[u] : 0.0);
    y[3 * u + 1] = wide(t1_[u]).dot(rel);
    y[3 * u + 2] = wide(t2_[u]).dot(rel);
  }
  for (std::size_t j = 0; j < rows_.size(); ++j)
    y[3 * a_.size() + j] = row_velocity(v, w, rows_[j]) + (add_bias ? rows_[j].bias : 0.0);
}

void CcpProblem::multiply(ConstSpan x, Span y) const {
  scatter(x, false, dv_, dw_);
  gather(dv_, dw_, false, y);
}

void CcpProblem::velocities(ConstSpan x, std::vector<Vec3>& v, std::vector<Vec3>& w) const {
  scatter(x, true, v, w);
}

void CcpProblem::gradient(ConstSpan x, Span g) const {
  scatter(x, true, dv_, dw_);
  gather(dv_, dw_, true, g);
}

void CcpProblem::project(Span x) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k)
    project_cone(mu_[std::size_t(k)], x[3 * std::size_t(k)], x[3 * std::size_t(k) + 1],
                 x[3 * std::size_t(k) + 2]);
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    double& v = x[3 * a_.size() + j];
    v = std::clamp(v, rows_[j].lo, rows_[j].hi);
  }
}

void CcpProblem::projected_step(ConstSpan y, ConstSpan g, double step, Span out) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k) {
    const auto i = 3 * std::size_t(k);
    double gn = y[i] - step * g[i], g1 = y[i + 1] - step * g[i + 1], g2 = y[i + 2] - step * g[i + 2];
    project_cone(mu_[std::size_t(k)], gn, g1, g2);
    out[i] = gn;
    out[i + 1] = g1;
    out[i + 2] = g2;
  }
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const std::size_t i = 3 * a_.size() + j;
    out[i] = std::clamp(y[i] - step * g[i], rows_[j].lo, rows_[j].hi);
  }
}

namespace {
struct ResidualPart {
  double sum = 0.0, max = 0.0;
  ResidualPart& operator+=(const ResidualPart& o) {
    sum += o.sum;
    max = std::max(max, o.max);
    return *this;
  }
  void add(double x, double projected, double inv_s) {
    const double r = (x - projected) * inv_s;
    sum += r * r;
    max = std::max(max, std::abs(r));
  }
};
}  // namespace

void CcpProblem::residual(ConstSpan x, ConstSpan g, double& rms, double& max) const {
  const double s = 1.0 / diag_max_;
  const ResidualPart total = reduce<ResidualPart>(
      [&](std::ptrdiff_t k, double mu, ResidualPart& part) {
        const auto i = 3 * std::size_t(k);
        double pn = x[i] - s * g[i], p1 = x[i + 1] - s * g[i + 1], p2 = x[i + 2] - s * g[i + 2];
        project_cone(mu, pn, p1, p2);
        part.add(x[i], pn, diag_max_);
        part.add(x[i + 1], p1, diag_max_);
        part.add(x[i + 2], p2, diag_max_);
      },
      [&](std::ptrdiff_t i, double lo, double hi, ResidualPart& part) {
        const auto u = std::size_t(i);
        part.add(x[u], std::clamp(x[u] - s * g[u], lo, hi), diag_max_);
      });
  max = total.max;
  rms = x.empty() ? 0.0 : std::sqrt(total.sum / double(x.size()));
}

void CcpProblem::world_impulses(ConstSpan x, std::vector<Vec3>& out) const {
  out.resize(a_.size());
  for (std::size_t k = 0; k < a_.size(); ++k)
    out[k] = wide(n_[k]) * x[3 * k] + wide(t1_[k]) * x[3 * k + 1] + wide(t2_[k]) * x[3 * k + 2];
}

void CcpProblem::warm_start(const std::vector<ContactKey>& keys,
                            const std::vector<ContactKey>& prev_keys,
                            const std::vector<Vec3>& prev_impulse, ConstSpan prev_x, Span x) const {
  std::fill(x.begin(), x.end(), 0.0);
  // Both lists come sorted when the contacts are (the usual case): then a
  // merge, else a binary search per contact.
  auto from = prev_keys.begin();
  for (std::size_t k = 0; k < keys.size(); ++k) {
    if (from == prev_keys.end() || keys[k] < *from) from = prev_keys.begin();
    const auto it = std::lower_bound(from, prev_keys.end(), keys[k]);
    from = it;
    if (it == prev_keys.end() || !(*it == keys[k])) continue;
    const Vec3& P = prev_impulse[std::size_t(it - prev_keys.begin())];
    x[3 * k] = wide(n_[k]).dot(P);
    x[3 * k + 1] = wide(t1_[k]).dot(P);
    x[3 * k + 2] = wide(t2_[k]).dot(P);
  }
  const std::size_t base = 3 * a_.size();
  const auto prev_base = std::ptrdiff_t(prev_x.size()) - std::ptrdiff_t(rows_.size());
  if (prev_base >= 0 && prev_base % 3 == 0)
    for (std::size_t r = 0; r < rows_.size(); ++r) x[base + r] = prev_x[std::size_t(prev_base) + r];
  project(x);
}

double CcpProblem::block_bound(std::size_t k) const {
  // Gershgorin bound on the largest eigenvalue of the contact's 3x3 block of
  // N: per body, m^-1 D D^T + C I^-1 C^T with D the rows (n, t1, t2) and C
  // their lever-arm rows r x d.
  const Vec3 dir[3] = {wide(n_[k]), wide(t1_[k]), wide(t2_[k])};
  Mat3 D;
  for (int i = 0; i < 3; ++i) D.row(i) = dir[i].transpose();
  Mat3 block = Mat3::Zero();
  auto add = [&](int body, const Vec3& r) {
    const auto u = std::size_t(body);
    Mat3 C;
    for (int i = 0; i < 3; ++i) C.row(i) = r.cross(dir[i]).transpose();
    block += bodies_->inv_mass[u] * D * D.transpose() + C * bodies_->inv_inertia[u] * C.transpose();
  };
  add(a_[k], wide(ra_[k]));
  add(b_[k], wide(rb_[k]));
  return block.cwiseAbs().rowwise().sum().maxCoeff();
}

SolveStats CcpProblem::solve_pgs(Span x, const SolverSettings& s, SolverWorkspace& ws) const {
  const SolverBodies& B = *bodies_;
  std::vector<Vec3>& v = ws.v;
  std::vector<Vec3>& w = ws.w;
  velocities(x, v, w);
  const std::size_t nc = a_.size();
  // One step per contact block: with the normal row's 1/diag alone, a
  // cluster's tangential rows (large lever arms) were over-stepped and diverged.
  const Span steps = ws.take(0, nc), g = ws.take(1, x.size());
  for (std::size_t k = 0; k < nc; ++k) {
    const double bound = block_bound(k);
    steps[k] = bound > 0.0 ? s.pgs_relaxation / bound : 0.0;
  }
  SolveStats stats;
  for (int it = 0; it < s.max_iterations; ++it) {
    for (std::size_t k = 0; k < nc; ++k) {
      const double step = steps[k];
      if (step <= 0.0) continue;
      const Vec3 ra = wide(ra_[k]), rb = wide(rb_[k]), n = wide(n_[k]), t1 = wide(t1_[k]), t2 = wide(t2_[k]);
      const Vec3 rel = point_velocity(v, w, b_[k], rb) - point_velocity(v, w, a_[k], ra);
      const std::size_t i = 3 * k;
      double gn = x[i] - step * (n.dot(rel) + bias_[k]);
      double g1 = x[i + 1] - step * t1.dot(rel);
      double g2 = x[i + 2] - step * t2.dot(rel);
      project_cone(mu_[k], gn, g1, g2);
      const Vec3 dP = n * (gn - x[i]) + t1 * (g1 - x[i + 1]) + t2 * (g2 - x[i + 2]);
      x[i] = gn;
      x[i + 1] = g1;
      x[i + 2] = g2;
      const auto a = std::size_t(a_[k]), b = std::size_t(b_[k]);
      v[a] -= B.inv_mass[a] * dP;
      w[a] -= B.inv_inertia[a] * ra.cross(dP);
      v[b] += B.inv_mass[b] * dP;
      w[b] += B.inv_inertia[b] * rb.cross(dP);
    }
    for (std::size_t j = 0; j < rows_.size(); ++j) {
      if (row_diag_[j] <= 0.0) continue;
      const BilateralRow& row = rows_[j];
      double& xi = x[3 * nc + j];
      const double next = std::clamp(
          xi - s.pgs_relaxation / row_diag_[j] * (row_velocity(v, w, row) + row.bias), row.lo, row.hi);
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

// The wall guard. A solve stopped at its iteration cap can leave a wall's
// row far from satisfied: the step 1/L is set by the stiffest row (the
// lightest grain, or a tangential row with its lever arm), so the normal row
// of a heavy grain on a wall converges L m times slower, and a 10 m/s grain
// kept 1/4 of the impulse that stops it and went through the plate. The
// guard finishes those rows only, locally: per violated row, the normal
// impulse that makes v_n + b = 0 for the particle alone (the wall does not
// move under it). It only adds normal impulse, so the impulse stays in its
// friction cone and what is reported is what was applied. It brings v_n up to
// the row's own target -b: for an open gap (b = gap/h) that only removes
// approaching velocity, so on a static wall it cannot add energy; the
// targets above zero are the solver's own, a restitution rebound e |v_n|
// and the push-out of an overlap at the recovery speed. Contacts between
// particles, and with dynamic bodies, are left to the solver.
std::size_t CcpProblem::guard_walls(Span x, std::vector<Vec3>& v, std::vector<Vec3>& w,
                                    double tolerance, int sweeps,
                                    const std::vector<std::uint8_t>* locked) const {
  const SolverBodies& B = *bodies_;
  return guard_rows(
      x, v, w, tolerance, sweeps,
      [&](std::size_t a, std::size_t b) { return B.inv_mass[a] == 0.0 && B.inv_mass[b] != 0.0; },
      locked);
}

std::size_t CcpProblem::guard_bodies(Span x, std::vector<Vec3>& v, std::vector<Vec3>& w,
                                     const std::vector<std::uint8_t>& flagged, double tolerance,
                                     int sweeps, const std::vector<std::uint8_t>* locked) const {
  return guard_rows(
      x, v, w, tolerance, sweeps,
      [&](std::size_t a, std::size_t b) { return flagged[a] || flagged[b]; }, locked);
}

template <class Selected>
std::size_t CcpProblem::guard_rows(Span x, std::vector<Vec3>& v, std::vector<Vec3>& w,
                                   double tolerance, int sweeps, Selected selected,
                                   const std::vector<std::uint8_t>* locked) const {
  const SolverBodies& B = *bodies_;
  // A locked body takes the correction in translation only (its turn, the
  // angular terms, left as they are).
  auto turns = [&](std::size_t i) { return locked == nullptr || !(*locked)[i]; };
  std::size_t corrections = 0;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    std::size_t made = 0;
    for (std::size_t k = 0; k < a_.size(); ++k) {
      const auto a = std::size_t(a_[k]), b = std::size_t(b_[k]);
      if (!selected(a, b)) continue;
      const Vec3 n = wide(n_[k]), ra = wide(ra_[k]), rb = wide(rb_[k]);
      const double vn = n.dot(point_velocity(v, w, b_[k], rb) - point_velocity(v, w, a_[k], ra));
      const double deficit = -bias_[k] - vn;
      if (!(deficit > tolerance)) continue;  // (also skips a NaN)
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

std::size_t CcpProblem::release_sliding_walls(Span x, std::vector<Vec3>& v, std::vector<Vec3>& w,
                                              double tolerance) const {
  const SolverBodies& B = *bodies_;
  std::size_t released = 0;
  for (std::size_t b = 0; b < B.inv_mass.size(); ++b) {
    const std::uint32_t first = adj_.offset[b], last = adj_.offset[b + 1];
    if (first == last) continue;
    // The body's contacts: all with walls (it is their B side), every one
    // pressing is sliding, and at least one lifts off by more than the
    // tolerance. Then dv, dw: what taking all its impulses away would do.
    bool eligible = true, lifting = false;
    Vec3 dv = Vec3::Zero(), dw = Vec3::Zero();
    for (std::uint32_t e = first; e < last && eligible; ++e) {
      const std::size_t k = adj_.entry[e] >> 1, i = 3 * k;
      const double gn = x[i], gt2 = x[i + 1] * x[i + 1] + x[i + 2] * x[i + 2], mu = mu_[k];
      eligible = (adj_.entry[e] & 1) && B.inv_mass[std::size_t(a_[k])] == 0.0 &&
                 (gn <= 0.0 || (mu > 0.0 && gt2 >= mu * mu * gn * gn * (1.0 - 1e-6)));
      if (!eligible || gn <= 0.0) continue;
      const Vec3 P = wide(n_[k]) * gn + wide(t1_[k]) * x[i + 1] + wide(t2_[k]) * x[i + 2];
      dv -= B.inv_mass[b] * P;
      dw -= B.inv_inertia[b] * wide(rb_[k]).cross(P);
      lifting = lifting || row_of(k, v, w) > tolerance;
    }
    if (!eligible || !lifting) continue;
    // The largest share t of them to take away with every row staying >= 0,
    // if taking them away lowers a lifting row at all (friction's torque
    // can make it rise instead).
    double t = 1.0;
    bool lowers = false;
    for (std::uint32_t e = first; e < last; ++e) {
      const std::size_t k = adj_.entry[e] >> 1;
      const double rate = wide(n_[k]).dot(dv + dw.cross(wide(rb_[k]))), row = row_of(k, v, w);
      if (rate < 0.0) t = std::min(t, std::max(0.0, row) / -rate);
      lowers = lowers || (rate < 0.0 && row > tolerance && x[3 * k] > 0.0);
    }
    if (!lowers || !(t > 0.0)) continue;
    for (std::uint32_t e = first; e < last; ++e)
      for (std::size_t r = 0; r < 3; ++r) x[3 * (adj_.entry[e] >> 1) + r] *= 1.0 - t;
    v[b] += t * dv;
    w[b] += t * dw;
    ++released;
  }
  return released;
}

CcpProblem::WallFinish CcpProblem::finish_walls(Span x, std::vector<Vec3>& v,
                                                std::vector<Vec3>& w, double tolerance,
                                                int max_sweeps,
                                                const std::vector<std::uint8_t>* locked) const {
  const SolverBodies& B = *bodies_;
  WallFinish out;
  auto wall_row = [&](std::uint32_t e) {
    const std::size_t k = e >> 1;
    return (e & 1) && B.inv_mass[std::size_t(a_[k])] == 0.0;
  };
  for (std::size_t b = 0; b < B.inv_mass.size(); ++b) {
    const std::uint32_t first = adj_.offset[b], last = adj_.offset[b + 1];
    bool violated = false;
    for (std::uint32_t e = first; e < last && !violated; ++e)
      violated = wall_row(adj_.entry[e]) && -row_of(adj_.entry[e] >> 1, v, w) > tolerance;
    if (!violated) continue;
    ++out.bodies;
    const bool turn = locked == nullptr || !(*locked)[b];
    bool done = false;
    for (int sweep = 0; sweep < max_sweeps && !done; ++sweep) {
      done = true;
      for (std::uint32_t e = first; e < last; ++e) {
        if (!wall_row(adj_.entry[e])) continue;
        const std::size_t k = adj_.entry[e] >> 1;
        const double deficit = -row_of(k, v, w);
        if (!(deficit > tolerance)) continue;  // (also skips a NaN)
        const Vec3 n = wide(n_[k]), cb = wide(rb_[k]).cross(n);
        const double k_eff = B.inv_mass[b] + (turn ? cb.dot(B.inv_inertia[b] * cb) : 0.0);
        if (!(k_eff > 0.0)) continue;
        const double d = deficit / k_eff;
        x[3 * k] += d;
        v[b] += B.inv_mass[b] * d * n;
        if (turn) w[b] += B.inv_inertia[b] * (d * cb);
        ++out.corrections;
        done = false;
      }
    }
    if (!done) ++out.unconverged;
  }
  return out;
}

double CcpProblem::row_of(std::size_t k, const std::vector<Vec3>& v, const std::vector<Vec3>& w) const {
  return wide(n_[k]).dot(point_velocity(v, w, b_[k], wide(rb_[k])) - point_velocity(v, w, a_[k], wide(ra_[k]))) +
         bias_[k];
}

}  // namespace ces
