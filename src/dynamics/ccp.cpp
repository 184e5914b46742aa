#include "dynamics/ccp.hpp"

#include <algorithm>
#include <cmath>

#include "common/parallel.hpp"

namespace ces {
namespace {

double row_mass(const SolverBodies& B, int i, const Vec3& lin, const Vec3& ang) {
  if (i < 0) return 0.0;
  const auto u = std::size_t(i);
  return B.inv_mass[u] * lin.squaredNorm() + ang.dot(B.inv_inertia[u] * ang);
}

// A yielding contact's row (CcpProblem::softness): a spring k = 1 / C with a
// dashpot c in parallel, stepped by backward Euler. Its force at the end of
// the step, F = -k (gap + h v_n) - c v_n, is gamma / h; so
//   v_n + gap / (h + c / k) + gamma / (h (k h + c)) = 0  while it presses.
// The dashpot's damping ratio zeta is the pair's (spring_damping_ratio: it
// gives the pair's restitution), at the row's effective mass
// 1 / normal_mass. An open gap is closed as a rigid contact's (gap / h) and
// the spring takes what the step would leave overlapping.
struct SoftRow {
  double softness = 0.0, bias = 0.0;
};
SoftRow soft_row(double compliance, double zeta, double normal_mass, double gap, double h) {
  const double k = 1.0 / compliance;
  const double c = normal_mass > 0.0 ? 2.0 * zeta * std::sqrt(k / normal_mass) : 0.0;
  return {1.0 / (h * (k * h + c)), gap < 0.0 ? gap / (h + c / k) : gap / h};
}

// A rigid contact's bias: close a positive gap exactly this step, push an
// overlap out no faster than the recovery speed, and rebound from an
// impact by the restitution.
double rigid_bias(const Contacts& c, std::size_t k, double restitution, const SolverBodies& B,
                  double h, const ContactSettings& settings) {
  const Vec3& n = c.normal[k];
  double bias = std::max(c.gap[k] / h, -settings.recovery_speed);
  const double approach =
      n.dot(B.velocity_at(c.body_b[k], c.point[k]) - B.velocity_at(c.body_a[k], c.point[k]));
  const bool impact = approach < -settings.restitution_threshold && c.gap[k] + h * approach < 0.0;
  if (impact && restitution > 0.0) bias = std::min(bias, restitution * approach);
  return bias;
}

}  // namespace

double row_velocity(const std::vector<Vec3>& v, const std::vector<Vec3>& w,
                    const BilateralRow& row) {
  double s = 0.0;
  if (row.a >= 0) s += row.lin_a.dot(v[std::size_t(row.a)]) + row.ang_a.dot(w[std::size_t(row.a)]);
  if (row.b >= 0) s += row.lin_b.dot(v[std::size_t(row.b)]) + row.ang_b.dot(w[std::size_t(row.b)]);
  return s;
}

namespace {
// One side of apply_row: what the row's impulse does to body i, at the row's
// lin and ang of that side (add_row_impulses applies it to listed bodies).
void apply_side(const SolverBodies& B, std::size_t i, const Vec3& lin, const Vec3& ang,
                double impulse, std::vector<Vec3>& v, std::vector<Vec3>& w) {
  v[i] += B.inv_mass[i] * impulse * lin;
  w[i] += B.inv_inertia[i] * (impulse * ang);
}
}  // namespace

void apply_row(const SolverBodies& B, const BilateralRow& row, double impulse,
               std::vector<Vec3>& v, std::vector<Vec3>& w) {
  if (row.a >= 0) apply_side(B, std::size_t(row.a), row.lin_a, row.ang_a, impulse, v, w);
  if (row.b >= 0) apply_side(B, std::size_t(row.b), row.lin_b, row.ang_b, impulse, v, w);
}

void SolverBodies::resize(std::size_t n) {
  x.resize(n);
  v.resize(n);
  w.resize(n);
  v_free.resize(n);
  w_free.resize(n);
  inv_mass.resize(n);
  inv_inertia.resize(n);
}

void CcpProblem::assemble(const Contacts& c, const MaterialTable& materials,
                          const SolverBodies& B, const std::vector<BilateralRow>& rows, double h,
                          const ContactSettings& settings) {
  bodies_ = &B;
  contacts_ = &c;
  rows_ = rows;
  step_ = h;
  size_for(c.size(), B.inv_mass.size());
  pack_inverse_masses(B);
  double diag_max = 0.0;
  const std::size_t nc = c.size();
#pragma omp parallel for schedule(static) \
    reduction(max                         \
              : diag_max) if (std::ptrdiff_t(nc) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(nc); ++s)
    diag_max = std::max(diag_max, assemble_contact(std::size_t(s), c, materials, h, settings));
  mark_soft_blocks();
  diag_max_ = std::max(diag_max, assemble_rows());
  if (!(diag_max_ > 0.0)) diag_max_ = 1.0;
  row_metric_.resize(rows_.size());
  for (std::size_t j = 0; j < rows_.size(); ++j)
    row_metric_[j] = 1.0 / (row_diag_[j] > 0.0 ? row_diag_[j] : diag_max_);
  adj_.build(a_, b_, B.inv_mass.size(),
             [&](std::int32_t i) { return B.inv_mass[std::size_t(i)] > 0.0; });
}

// Every array at its size for nc contacts and `bodies` solver bodies. The
// kernel's arrays are padded to whole blocks of kLanes contacts with zeros;
// assemble_contact writes each contact's own numbers, so only the padding
// is zeroed here.
void CcpProblem::size_for(std::size_t nc, std::size_t bodies) {
  a_.resize(nc);
  b_.resize(nc);
  const std::size_t padded = chunk_count(nc, kLanes) * kLanes;
  frame_.resize(padded / kLanes * kFrameBlock);
  lever_.resize(6 * padded + 1);
  bias_.resize(padded);
  softness_.resize(padded);
  metric_.resize(padded / kLanes * kMetricBlock);
  for (std::size_t k = nc; k < padded; ++k) {
    const std::size_t lane = k % kLanes;
    for (std::size_t j = 0; j < 4; ++j) frame_[k / kLanes * kFrameBlock + j * kLanes + lane] = 0;
    for (std::size_t j = 0; j < 2; ++j) metric_[k / kLanes * kMetricBlock + j * kLanes + lane] = 0;
    bias_[k] = 0.0;
    softness_[k] = 0.0;
  }
  std::fill(lever_.begin() + std::ptrdiff_t(6 * nc), lever_.end(), 0.0f);
  tangent_.resize(2 * nc);
  // World rows for scatter_bodies, and a spare: it loads each contact's
  // impulse as a four-number vector.
  impulse_.resize(3 * nc + rows_.size() + 1);
  inverse_mass_.resize(kMassStride * bodies);
  // The gather loads a body's velocity as a four-number vector: a spare.
  dv_.resize(bodies + 1);
  dw_.resize(bodies + 1);
}

void CcpProblem::pack_inverse_masses(const SolverBodies& B) {
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(B.inv_mass.size()) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(B.inv_mass.size()); ++s) {
    const auto i = std::size_t(s);
    const Mat3& I = B.inv_inertia[i];
    StoredScalar* m = &inverse_mass_[kMassStride * i];
    // Last, a bound on I^-1's largest eigenvalue (Gershgorin), for the metric.
    const double upper[] = {I(0, 0), I(0, 1), I(0, 2), I(1, 1), I(1, 2), I(2, 2), B.inv_mass[i],
                            I.cwiseAbs().rowwise().sum().maxCoeff()};
    for (std::size_t c = 0; c < kMassStride; ++c) m[c] = StoredScalar(upper[c]);
  }
}

// Contact k's frame, friction, lever arms, bias, softness and metric;
// returns its normal row's diagonal of N.
double CcpProblem::assemble_contact(std::size_t k, const Contacts& c,
                                    const MaterialTable& materials, double h,
                                    const ContactSettings& settings) {
  const SolverBodies& B = *bodies_;
  a_[k] = c.body_a[k];
  b_[k] = c.body_b[k];
  const Vec3& n = c.normal[k];
  const SurfacePair& surfaces = materials.surfaces(c.surfaces[k]);
  const Vec3 ra = c.point[k] - B.x[std::size_t(a_[k])];
  const Vec3 rb = c.point[k] - B.x[std::size_t(b_[k])];
  StoredScalar* f = &frame_[k / kLanes * kFrameBlock + k % kLanes];
  for (int i = 0; i < 3; ++i) f[std::size_t(i) * kLanes] = StoredScalar(n[i]);
  f[3 * kLanes] = StoredScalar(surfaces.friction);
  make_tangents(k);
  for (int i = 0; i < 3; ++i) {
    lever_[6 * k + std::size_t(i)] = StoredScalar(ra[i]);
    lever_[6 * k + 3 + std::size_t(i)] = StoredScalar(rb[i]);
  }
  const Vec3 nw = normal(k);  // the rounded row the kernel applies
  const double normal_mass =
      row_mass(B, a_[k], nw, lever_a(k).cross(nw)) + row_mass(B, b_[k], nw, lever_b(k).cross(nw));
  const SoftRow row =
      surfaces.compliance > 0.0
          ? soft_row(surfaces.compliance, surfaces.damping_ratio, normal_mass, c.gap[k], h)
          : SoftRow{0.0, rigid_bias(c, k, surfaces.restitution, B, h, settings)};
  softness_[k] = row.softness;
  bias_[k] = row.bias;
  const double bound =
      block_scale(a_[k], lever_a(k)) + block_scale(b_[k], lever_b(k)) + softness_[k];
  float* mt = &metric_[k / kLanes * kMetricBlock + k % kLanes];
  mt[0] = bound > 0.0 ? float(1.0 / bound) : 0.0f;
  mt[kLanes] = float(bound);
  return normal_mass + softness_[k];
}

// The bilateral rows' diagonal of N; returns its largest entry (0: none).
double CcpProblem::assemble_rows() {
  const SolverBodies& B = *bodies_;
  row_diag_.resize(rows_.size());
  double diag_max = 0.0;
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const BilateralRow& r = rows_[j];
    row_diag_[j] = row_mass(B, r.a, r.lin_a, r.ang_a) + row_mass(B, r.b, r.lin_b, r.ang_b);
    diag_max = std::max(diag_max, row_diag_[j]);
  }
  return diag_max;
}

namespace {

// A maximum as reduce_chunks adds its parts.
struct Worst {
  double value = 0.0;
  Worst& operator+=(const Worst& o) {
    value = std::max(value, o.value);
    return *this;
  }
};

// f.template operator()<I>() for the kernel's instruction set I.
template <class F>
decltype(auto) on_kernel(F&& f) {
  switch (kernel_isa()) {
    case Isa::Avx512: return f.template operator()<Isa::Avx512>();
    case Isa::Avx2: return f.template operator()<Isa::Avx2>();
    default: return f.template operator()<Isa::Baseline>();
  }
}

}  // namespace

void CcpProblem::scatter_bodies(const double* P, ConstSpan x, bool add_free,
                                std::vector<Vec3>& dv, std::vector<Vec3>& dw) const {
  on_kernel([&]<Isa I>() { scatter_bodies_on<I>(P, x, add_free, dv, dw); });
}

CcpProblem::TrialSums CcpProblem::apgd_step(ConstSpan x, ConstSpan x_old, Span x1, ConstSpan gx,
                                            ConstSpan g_old, Momentum mo, double step) const {
  return on_kernel([&]<Isa I>() { return apgd_step_on<I>(x, x_old, x1, gx, g_old, mo, step); });
}

CcpProblem::TrialSums CcpProblem::apgd_gradient(ConstSpan x1, Span g1, ConstSpan x,
                                                ConstSpan x_old, Momentum mo, TrialSums& t,
                                                const NextTrial& next) const {
  return on_kernel(
      [&]<Isa I>() { return apgd_gradient_on<I>(x1, g1, x, x_old, mo, t, next); });
}

CcpProblem::TrialSums& CcpProblem::TrialSums::operator+=(const TrialSums& o) {
  dd += o.dd;
  dnd += o.dnd;
  uphill += o.uphill;
  res_sum += o.res_sum;
  return *this;
}

void CcpProblem::scatter(ConstSpan x, bool add_free, std::vector<Vec3>& dv,
                         std::vector<Vec3>& dw) const {
  to_world(x, Span(impulse_.data(), x.size()));
  scatter_bodies(impulse_.data(), x, add_free, dv, dw);
}

std::array<double, 3> CcpProblem::gather_contact(std::size_t k, const std::vector<Vec3>& v,
                                                 const std::vector<Vec3>& w, bool add_bias) const {
  const Vec3 rel = relative_velocity(k, v, w);
  const Frame F = frame(k);
  return {F.n.dot(rel) + (add_bias ? bias_[k] : 0.0), F.t1.dot(rel), F.t2.dot(rel)};
}

std::array<double, 3> CcpProblem::gradient_rows(std::size_t k, const std::vector<Vec3>& v,
                                                const std::vector<Vec3>& w, ConstSpan x) const {
  std::array<double, 3> g = gather_contact(k, v, w, true);
  if (softness_[k] > 0.0) g[0] += softness_[k] * x[3 * k];  // add_softness's term
  return g;
}

void CcpProblem::gather(const std::vector<Vec3>& v, const std::vector<Vec3>& w, bool add_bias,
                        Span y) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t s = 0; s < nc; ++s) {
    const auto k = std::size_t(s);
    const std::array<double, 3> rows = gather_contact(k, v, w, add_bias);
    std::copy(rows.begin(), rows.end(), &y[3 * k]);
  }
  gather_rows(v, w, add_bias, y);
}

CcpProblem::EnergySums& CcpProblem::EnergySums::operator+=(const EnergySums& o) {
  rx += o.rx;
  xnx += o.xnx;
  return *this;
}

CcpProblem::EnergySums CcpProblem::energy_sums(const std::vector<Vec3>& v_base,
                                               const std::vector<Vec3>& w_base,
                                               const std::vector<Vec3>& v,
                                               const std::vector<Vec3>& w, ConstSpan x) const {
  return reduce_chunks<EnergySums>(a_.size(), [&](std::size_t begin, std::size_t end,
                                                  EnergySums& part) {
    for (std::size_t k = begin; k < end; ++k) {
      const std::array<double, 3> r = gather_contact(k, v_base, w_base, true);
      const std::array<double, 3> g = gradient_rows(k, v, w, x);
      for (std::size_t c = 0; c < 3; ++c) {
        part.rx += r[c] * x[3 * k + c];
        part.xnx += x[3 * k + c] * (g[c] - r[c]);
      }
    }
  });
}

void CcpProblem::gather_rows(const std::vector<Vec3>& v, const std::vector<Vec3>& w,
                             bool add_bias, Span y) const {
  for (std::size_t j = 0; j < rows_.size(); ++j)
    y[3 * a_.size() + j] = row_velocity(v, w, rows_[j]) + (add_bias ? rows_[j].bias : 0.0);
}

void CcpProblem::add_row_impulses(ConstSpan x, std::vector<Vec3>& dv, std::vector<Vec3>& dw,
                                  const std::vector<std::uint32_t>* only) const {
  if (only == nullptr) {
    for (std::size_t j = 0; j < rows_.size(); ++j)
      apply_row(*bodies_, rows_[j], x[3 * a_.size() + j], dv, dw);
    return;
  }
  // The listed bodies' sides of the rows in the order apply_row adds them
  // (row by row, a's side before b's): the same bits for each.
  const auto listed = [&](std::int32_t body) {
    return body >= 0 && std::binary_search(only->begin(), only->end(), std::uint32_t(body));
  };
  for (std::size_t j = 0; j < rows_.size(); ++j) {
    const BilateralRow& r = rows_[j];
    const double impulse = x[3 * a_.size() + j];
    if (listed(r.a)) apply_side(*bodies_, std::size_t(r.a), r.lin_a, r.ang_a, impulse, dv, dw);
    if (listed(r.b)) apply_side(*bodies_, std::size_t(r.b), r.lin_b, r.ang_b, impulse, dv, dw);
  }
}

void CcpProblem::multiply(ConstSpan x, Span y) const {
  scatter(x, false, dv_, dw_);
  gather(dv_, dw_, false, y);
  add_softness(x, y);
}

void CcpProblem::velocities(ConstSpan x, std::vector<Vec3>& v, std::vector<Vec3>& w) const {
  scatter(x, true, v, w);
}

void CcpProblem::velocities_of(ConstSpan x, const std::vector<std::uint32_t>& bodies,
                               std::vector<Vec3>& v, std::vector<Vec3>& w) const {
  // The world impulses of the listed bodies' contacts alone, where
  // scatter_bodies reads them; serial, as a contact of two listed bodies
  // is in both lists.
  for (const std::uint32_t u : bodies)
    for (std::uint32_t e = adj_.offset[u]; e < adj_.offset[u + 1]; ++e) {
      const std::size_t k = adj_.entry[e] >> 1;
      const Vec3 P = world_impulse(k, x);
      std::copy_n(P.data(), 3, &impulse_[3 * k]);
    }
  on_kernel([&]<Isa I>() { scatter_bodies_on<I>(impulse_.data(), x, true, v, w, &bodies); });
}

void CcpProblem::row_velocities(ConstSpan x, std::vector<Vec3>& v, std::vector<Vec3>& w) const {
  const SolverBodies& B = *bodies_;
  // scatter_bodies adds v_free to a zero sum: v_free to the bit.
  v.assign(B.v_free.begin(), B.v_free.end());
  w.assign(B.w_free.begin(), B.w_free.end());
  for (std::size_t j = 0; j < rows_.size(); ++j) apply_row(B, rows_[j], x[3 * a_.size() + j], v, w);
}

void CcpProblem::gradient(ConstSpan x, Span g) const {
  scatter(x, true, dv_, dw_);
  gather(dv_, dw_, true, g);
  add_softness(x, g);
}

void CcpProblem::mark_soft_blocks() {
  const std::size_t nc = a_.size(), blocks = chunk_count(nc, kLanes);
  auto soft = [&](std::size_t k) { return softness_[k] > 0.0; };
  soft_block_.resize(blocks);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(nc) > kParallelMin)
  for (std::size_t b = 0; b < blocks; ++b) {
    bool any = false;
    for (std::size_t k = b * kLanes; k < std::min(nc, (b + 1) * kLanes); ++k) any = any || soft(k);
    soft_block_[b] = any;
  }
  select_in_order(nc, soft, soft_);
}

void CcpProblem::add_softness(ConstSpan x, Span g) const {
  for (const std::uint32_t k : soft_) g[3 * k] += softness_[k] * x[3 * k];
}

void CcpProblem::project(Span x) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k)
    project_cone(friction(std::size_t(k)), x[3 * std::size_t(k)], x[3 * std::size_t(k) + 1],
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
    project_cone(friction(std::size_t(k)), gn, g1, g2);
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
  double sum = 0.0;
  ResidualPart& operator+=(const ResidualPart& o) {
    sum += o.sum;
    return *this;
  }
  void add(double x, double projected, double inv_s) {
    const double r = (x - projected) * inv_s;
    sum += r * r;
  }
};
}  // namespace

template <class ContactG, class RowG>
double CcpProblem::residual_of(ConstSpan x, ContactG contact_g, RowG row_g) const {
  const double s = 1.0 / diag_max_;
  const ResidualPart total = reduce<ResidualPart>(
      [&](std::ptrdiff_t k, double mu, ResidualPart& part) {
        const auto i = 3 * std::size_t(k);
        const std::array<double, 3> g = contact_g(std::size_t(k));
        double pn = x[i] - s * g[0], p1 = x[i + 1] - s * g[1], p2 = x[i + 2] - s * g[2];
        project_cone(mu, pn, p1, p2);
        part.add(x[i], pn, diag_max_);
        part.add(x[i + 1], p1, diag_max_);
        part.add(x[i + 2], p2, diag_max_);
      },
      [&](std::ptrdiff_t i, double lo, double hi, ResidualPart& part) {
        const auto u = std::size_t(i);
        part.add(x[u], std::clamp(x[u] - s * row_g(u), lo, hi), diag_max_);
      });
  return x.empty() ? 0.0 : std::sqrt(total.sum / double(x.size()));
}

double CcpProblem::residual(ConstSpan x, ConstSpan g) const {
  return residual_of(
      x, [&](std::size_t k) { return std::array<double, 3>{g[3 * k], g[3 * k + 1], g[3 * k + 2]}; },
      [&](std::size_t i) { return g[i]; });
}

double CcpProblem::residual_at(const std::vector<Vec3>& v, const std::vector<Vec3>& w,
                               ConstSpan x) const {
  const std::size_t base = 3 * a_.size();
  return residual_of(
      x, [&](std::size_t k) { return gradient_rows(k, v, w, x); },
      [&](std::size_t i) { return row_velocity(v, w, rows_[i - base]) + rows_[i - base].bias; });
}

double CcpProblem::block_scale(int body, const Vec3& r) const {
  // m^-1 1 + [r]x I^-1 [r]x^T <= (m^-1 + lambda_max(I^-1) |r|^2) 1, as
  // [r]x's singular values are |r|, |r|, 0: exact for a sphere.
  if (body < 0) return 0.0;
  const StoredScalar* record = &inverse_mass_[kMassStride * std::size_t(body)];
  return double(record[6]) + double(record[7]) * r.squaredNorm();
}

double CcpProblem::metric_weight(std::size_t i) const {
  const std::size_t nc = a_.size();
  if (i >= 3 * nc) return row_metric_[i - 3 * nc];
  const std::size_t k = i / 3;
  return double(metric_[k / kLanes * kMetricBlock + k % kLanes]);
}

void CcpProblem::scale_by_metric(Span v) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k) {
    const double root = std::sqrt(metric_weight(3 * std::size_t(k)));
    for (std::size_t c = 0; c < 3; ++c) v[3 * std::size_t(k) + c] *= root;
  }
  for (std::size_t i = 3 * a_.size(); i < v.size(); ++i) v[i] *= std::sqrt(metric_weight(i));
}

void CcpProblem::world_impulses(ConstSpan x, std::vector<Vec3>& out) const {
  const auto nc = std::ptrdiff_t(a_.size());
  out.resize(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k) out[std::size_t(k)] = world_impulse(std::size_t(k), x);
}

void CcpProblem::to_world(ConstSpan x, Span P) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t s = 0; s < nc; ++s) {
    const auto k = std::size_t(s);
    const Vec3 w = world_impulse(k, x);
    std::copy_n(w.data(), 3, &P[3 * k]);
  }
  std::copy(x.begin() + 3 * nc, x.end(), P.begin() + 3 * nc);
}

void CcpProblem::to_local(ConstSpan P, Span x) const {
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t s = 0; s < nc; ++s) {
    const auto k = std::size_t(s);
    const Frame F = frame(k);
    const Vec3 w(P[3 * k], P[3 * k + 1], P[3 * k + 2]);
    x[3 * k] = F.n.dot(w);
    x[3 * k + 1] = F.t1.dot(w);
    x[3 * k + 2] = F.t2.dot(w);
  }
  std::copy(P.begin() + 3 * nc, P.end(), x.begin() + 3 * nc);
}

// The overlap after the step is -(gap + h (row - b)); it may reach
// max(tolerance r, -gap), so the row may end as low as -slack.
double CcpProblem::overlap_slack(std::size_t k, double tolerance) const {
  const double gap = contacts_->gap[k];
  return (std::max(tolerance * contacts_->radius[k], -gap) + gap) / step_ - bias_[k];
}

bool CcpProblem::overlaps_within(ConstSpan g, bool world, double tolerance) const {
  auto excess = [&](std::size_t begin, std::size_t end, Worst& part) {
    for (std::size_t k = begin; k < end; ++k) {
      if (softness_[k] > 0.0) continue;  // a yielding surface's overlap is its give
      const Vec3 gk(g[3 * k], g[3 * k + 1], g[3 * k + 2]);
      const double row = world ? normal(k).dot(gk) : gk[0];
      part.value = std::max(part.value, -row - overlap_slack(k, tolerance));
    }
  };
  return reduce_chunks<Worst>(a_.size(), excess).value <= 0.0;
}

void CcpProblem::world_gradient(ConstSpan P, Span g) const {
  scatter_bodies(P.data(), P, true, dv_, dw_);
  const auto nc = std::ptrdiff_t(a_.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t s = 0; s < nc; ++s) {
    const auto k = std::size_t(s);
    const Vec3 n = normal(k), impulse(P[3 * k], P[3 * k + 1], P[3 * k + 2]);
    const Vec3 rel =
        relative_velocity(k, dv_, dw_) + (bias_[k] + softness_[k] * n.dot(impulse)) * n;
    std::copy_n(rel.data(), 3, &g[3 * k]);
  }
  gather_rows(dv_, dw_, true, g);
}

void CcpProblem::make_tangents(std::size_t k) {
  // Duff et al., "Building an Orthonormal Basis, Revisited", JCGT 6(1),
  // 2017: branch-free, and no other vector than n goes in.
  const Vec3 n = normal(k);
  const double sign = n.z() < 0.0 ? -1.0 : 1.0, a = -1.0 / (sign + n.z()), b = n.x() * n.y() * a;
  tangent_[2 * k] = {1.0 + sign * n.x() * n.x() * a, sign * b, -sign * n.x()};
  tangent_[2 * k + 1] = {b, sign + n.y() * n.y() * a, -n.y()};
}

void CcpProblem::warm_start(const std::vector<ContactKey>& keys, const ContactMemory& previous,
                            ConstSpan prev_rows, Span x) const {
  // In fixed chunks, each with a cursor of its own, in parallel: what a
  // contact finds does not depend on them. First where the last step's
  // order would have each key (ContactMemory::find_at); the chunks with a
  // key found elsewhere or not at all again by the hash table, built on
  // the threads between the two passes only if one is needed.
  const std::size_t nc = keys.size();
  static thread_local std::vector<std::uint8_t> missed_buffer;
  std::vector<std::uint8_t>& missed = missed_buffer;  // (named outside the region)
  missed.assign(chunk_count(nc, kReduceChunk), 0);
  auto pass = [&](bool hashed) {
    auto chunk = [&](std::size_t ch, std::size_t begin, std::size_t end) {
      if (hashed && !missed[ch]) return;
      std::size_t cursor = begin;
      for (std::size_t k = begin; k < end; ++k) {
        const Vec3* P =
            hashed ? previous.find(keys[k], cursor) : previous.find_at(keys[k], cursor);
        if (!P && !hashed) {
          missed[ch] = 1;  // the chunk is looked up again, whole
          return;
        }
        const Frame F = frame(k);
        x[3 * k] = P ? F.n.dot(*P) : 0.0;
        x[3 * k + 1] = P ? F.t1.dot(*P) : 0.0;
        x[3 * k + 2] = P ? F.t2.dot(*P) : 0.0;
      }
    };
    for_each_range(nc, kReduceChunk, std::ptrdiff_t(nc) > kParallelMin, chunk);
  };
  pass(false);
  if (std::find(missed.begin(), missed.end(), 1) != missed.end()) {
    previous.index();
    pass(true);
  }
  const std::size_t base = 3 * nc;
  std::fill(x.begin() + std::ptrdiff_t(base), x.end(), 0.0);
  if (prev_rows.size() == rows_.size())
    std::copy(prev_rows.begin(), prev_rows.end(), x.begin() + std::ptrdiff_t(base));
  project(x);
}

double CcpProblem::block_bound(std::size_t k) const {
  // Gershgorin bound on the largest eigenvalue of the contact's 3x3 block of
  // N: per body, m^-1 D D^T + C I^-1 C^T with D the rows (n, t1, t2) and C
  // their lever-arm rows r x d.
  const Frame F = frame(k);
  const Vec3 dir[3] = {F.n, F.t1, F.t2};
  Mat3 D;
  for (int i = 0; i < 3; ++i) D.row(i) = dir[i].transpose();
  Mat3 block = Mat3::Zero();
  auto add = [&](int body, const Vec3& r) {
    const auto u = std::size_t(body);
    Mat3 C;
    for (int i = 0; i < 3; ++i) C.row(i) = r.cross(dir[i]).transpose();
    block += bodies_->inv_mass[u] * D * D.transpose() + C * bodies_->inv_inertia[u] * C.transpose();
  };
  add(a_[k], lever_a(k));
  add(b_[k], lever_b(k));
  block(0, 0) += softness_[k];
  return block.cwiseAbs().rowwise().sum().maxCoeff();
}

}  // namespace ces
