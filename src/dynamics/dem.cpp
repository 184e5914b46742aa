#include "dynamics/dem.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "common/parallel.hpp"

namespace ces {
namespace {

const double kTsuji = 2.0 * std::sqrt(5.0 / 6.0);

// Dimensionless Hertz contact with Tsuji damping, x(0) = 0, x'(0) = 1 (RK4):
// returns the rebound speed, i.e. the restitution.
double rebound_speed(double beta) {
  const double gamma = std::sqrt(5.0) * beta;
  auto accel = [gamma](double x, double v) {
    if (x <= 0.0) return 0.0;
    return -std::max(0.0, x * std::sqrt(x) + gamma * std::sqrt(std::sqrt(x)) * v);
  };
  constexpr double dt = 2e-4;  // contact lasts ~3.2 units: e to ~1e-6
  double x = 0.0, v = 1.0;
  for (int i = 0; i < 1000000; ++i) {
    const double k1x = v, k1v = accel(x, v);
    const double k2x = v + 0.5 * dt * k1v, k2v = accel(x + 0.5 * dt * k1x, k2x);
    const double k3x = v + 0.5 * dt * k2v, k3v = accel(x + 0.5 * dt * k2x, k3x);
    const double k4x = v + dt * k3v, k4v = accel(x + dt * k3x, k4x);
    x += dt / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x);
    v += dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
    // Separated: back at zero overlap, or the (clamped) force has vanished
    // while unloading, after which nothing slows the rebound.
    if (v < 0.0 && (x <= 0.0 || accel(x, v) == 0.0)) return -v;
  }
  return 0.0;
}

double sphere_radius(const Model& m, const Particles& p, int body, std::uint32_t feature) {
  if (std::size_t(body) >= p.size()) return std::numeric_limits<double>::infinity();
  const auto i = std::size_t(body);
  return m.shapes[std::size_t(p.shape[i])].radii[feature] * p.scale[i];
}

int material_of(const Model& m, const Particles& p, int body) {
  const auto i = std::size_t(body);
  return i < p.size() ? p.material[i] : m.bodies[i - p.size()].material;
}

}  // namespace

double hertz_restitution(double beta) { return rebound_speed(beta); }

double hertz_damping_for_restitution(double e) {
  if (!(e > 0.0)) throw std::invalid_argument("DEM: restitution must be > 0");
  if (e >= 1.0) return 0.0;
  double lo = 0.0, hi = 1.0;
  while (rebound_speed(hi) > e) hi *= 2.0;
  for (int i = 0; i < 50; ++i) {  // bisection: the map is monotone
    const double mid = 0.5 * (lo + hi);
    (rebound_speed(mid) > e ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

double rayleigh_time(const Model& m, const Particles& p) {
  double t = std::numeric_limits<double>::infinity();
  const auto n = std::ptrdiff_t(p.size());
#pragma omp parallel for schedule(static) reduction(min : t) if (n > kParallelMin)
  for (std::ptrdiff_t s = 0; s < n; ++s) {
    const auto i = std::size_t(s);
    const ParticleShape& shape = m.shapes[std::size_t(p.shape[i])];
    const double r = shape.smallest_radius() * p.scale[i];
    const ElasticProperties& el = m.dem.elastic(p.material[i]);
    const double rho = m.materials.materials()[std::size_t(p.material[i])].density;
    const double g = el.youngs_modulus / (2.0 * (1.0 + el.poisson_ratio));
    t = std::min(t, M_PI * r * std::sqrt(rho / g) / (0.1631 * el.poisson_ratio + 0.8766));
  }
  return t;
}

void DemContacts::apply(const Model& model, const Particles& p, const Contacts& c, double h,
                        ContactMemory& springs, SolverBodies& B) {
  springs_ = &springs;
  cache_damping(model, c);
  const auto nc = std::ptrdiff_t(c.size());
  force_.resize(c.size());
  xi_.resize(c.size());
#pragma omp parallel for schedule(static) if (nc > kParallelMin)
  for (std::ptrdiff_t k = 0; k < nc; ++k) contact_force(model, p, c, std::size_t(k), h, B);

  adj_.build(c.body_a, c.body_b, B.inv_mass.size(),
             [&](std::int32_t i) { return B.inv_mass[std::size_t(i)] > 0.0; });
  const auto nb = std::ptrdiff_t(B.inv_mass.size());
#pragma omp parallel for schedule(static) if (nb > kParallelMin)
  for (std::ptrdiff_t i = 0; i < nb; ++i) {
    const auto u = std::size_t(i);
    Vec3 f = Vec3::Zero(), torque = Vec3::Zero();
    for (std::uint32_t e = adj_.offset[u]; e < adj_.offset[u + 1]; ++e) {
      const std::size_t k = adj_.entry[e] >> 1;
      const bool is_b = adj_.entry[e] & 1;
      const Vec3 fk = is_b ? force_[k] : Vec3(-force_[k]);
      f += fk;
      torque += (c.point[k] - B.x[u]).cross(fk);
    }
    B.v_free[u] += h * B.inv_mass[u] * f;
    B.w_free[u] += h * (B.inv_inertia[u] * torque);
  }
  // Contacts not touching have xi 0: found next step, the same as not
  // found. xi_ comes back with the last buffer; the next apply() refills it.
  springs.assign(c.key, xi_);
}

DemContacts::PairConstants DemContacts::pair_constants(const Model& m, const Particles& p,
                                                       const Contacts& c, std::size_t k,
                                                       const SolverBodies& B) const {
  const int a = c.body_a[k], b = c.body_b[k];
  const ElasticProperties& ea = m.dem.elastic(material_of(m, p, a));
  const ElasticProperties& eb = m.dem.elastic(material_of(m, p, b));
  auto compliance = [](const ElasticProperties& e) {
    return (1.0 - e.poisson_ratio * e.poisson_ratio) / e.youngs_modulus;
  };
  auto shear_compliance = [](const ElasticProperties& e) {
    return 2.0 * (2.0 - e.poisson_ratio) * (1.0 + e.poisson_ratio) / e.youngs_modulus;
  };
  PairConstants pc;
  pc.e_star = 1.0 / (compliance(ea) + compliance(eb));
  pc.g_star = 1.0 / (shear_compliance(ea) + shear_compliance(eb));
  const double ra = sphere_radius(m, p, a, c.key[k].feature_a);
  const double rb = sphere_radius(m, p, b, c.key[k].feature_b);
  pc.r_star = std::isinf(ra) ? rb : std::isinf(rb) ? ra : ra * rb / (ra + rb);
  pc.m_star = 1.0 / (B.inv_mass[std::size_t(a)] + B.inv_mass[std::size_t(b)]);
  const double e = m.materials.surfaces(c.surfaces[k]).restitution;
  pc.beta = damping(std::max(e, m.dem.min_restitution));
  return pc;
}

void DemContacts::contact_force(const Model& m, const Particles& p, const Contacts& c,
                                std::size_t k, double h, const SolverBodies& B) {
  force_[k].setZero();
  xi_[k].setZero();
  if (c.gap[k] >= 0.0) return;  // inside the envelope but not touching
  const PairConstants pc = pair_constants(m, p, c, k, B);
  const Vec3& n = c.normal[k];
  const int a = c.body_a[k], b = c.body_b[k];
  const Vec3 rel = B.velocity_at(b, c.point[k]) - B.velocity_at(a, c.point[k]);
  const double vn = n.dot(rel);
  const Vec3 vt = rel - vn * n;
  const double root = std::sqrt(pc.r_star * -c.gap[k]);
  const double sn = 2.0 * pc.e_star * root, st = 8.0 * pc.g_star * root;
  const double fn =
      std::max(0.0, 2.0 / 3.0 * sn * -c.gap[k] - kTsuji * pc.beta * std::sqrt(sn * pc.m_star) * vn);

  // The history rotates with the contact: keep its length in the new tangent plane.
  Vec3 xi = Vec3::Zero();
  std::size_t guess = k;  // where the last step's order would have it
  if (const Vec3* old = springs_->find(c.key[k], guess)) {
    const Vec3 in_plane = *old - n.dot(*old) * n;
    if (in_plane.squaredNorm() > 0.0) xi = in_plane * (old->norm() / in_plane.norm());
  }
  xi += h * vt;
  const double ct = kTsuji * pc.beta * std::sqrt(st * pc.m_star);
  Vec3 ft = -st * xi - ct * vt;
  const double limit = m.materials.surfaces(c.surfaces[k]).friction * fn;
  if (ft.norm() > limit) {  // sliding: the spring holds only what friction allows
    ft *= limit / ft.norm();
    xi = -(ft + ct * vt) / st;
  }
  force_[k] = fn * n + ft;
  xi_[k] = xi;
}

void DemContacts::cache_damping(const Model& m, const Contacts& c) {
  for (std::size_t k = 0; k < c.size(); ++k) {
    const double e =
        std::max(m.materials.surfaces(c.surfaces[k]).restitution, m.dem.min_restitution);
    const auto it = std::lower_bound(damping_.begin(), damping_.end(), std::make_pair(e, 0.0));
    if (it == damping_.end() || it->first != e)
      damping_.insert(it, {e, hertz_damping_for_restitution(e)});
  }
}

double DemContacts::damping(double e) const {
  return std::lower_bound(damping_.begin(), damping_.end(), std::make_pair(e, 0.0))->second;
}

}  // namespace ces
