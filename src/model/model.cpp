#include "model/model.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <map>
#include <mutex>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "common/hull.hpp"

namespace ces {

MaterialTable::MaterialTable(std::vector<Material> materials, const std::vector<MaterialPair>& pairs)
    : materials_(std::move(materials)) {
  const std::size_t n = materials_.size();
  pairs_.resize(n * n);
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = 0; b < n; ++b) {
      SurfacePair& s = pairs_[a * n + b];
      s.friction = std::min(materials_[a].friction, materials_[b].friction);
      s.restitution = std::min(materials_[a].restitution, materials_[b].restitution);
      s.compliance = materials_[a].compliance + materials_[b].compliance;
    }
  for (const MaterialPair& p : pairs) {
    for (auto [x, y] : {std::pair{p.a, p.b}, std::pair{p.b, p.a}}) {
      if (p.friction) pairs_[index(x, y)].friction = *p.friction;
      if (p.restitution) pairs_[index(x, y)].restitution = *p.restitution;
    }
  }
  for (SurfacePair& s : pairs_) s.damping_ratio = spring_damping_ratio(s.restitution);
}

namespace {
// e(zeta) of the spring-dashpot whose contact ends at zero force, zeta < 1
// (Schwager, Poeschel, 2007, eqs. for the force criterion).
double force_criterion_restitution(double zeta) {
  const double root = std::sqrt(1.0 - zeta * zeta), denominator = 1.0 - 2.0 * zeta * zeta;
  // The phase omega_d t at which the force comes back to 0.
  const double angle = kPi - std::atan2(2.0 * zeta * root, denominator);
  return std::exp(-zeta / root * angle);
}
}  // namespace

double spring_damping_ratio(double e) {
  if (!(e < 1.0)) return 0.0;
  if (e <= std::exp(-2.0)) return 1.0;
  double lo = 0.0, hi = 1.0;  // e falls with zeta
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (force_criterion_restitution(mid) > e ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

namespace {

// Volume, first and second moments of a solid about the origin.
struct Moments {
  double volume = 0.0;
  Vec3 first = Vec3::Zero();
  Mat3 second = Mat3::Zero();  // integral of x x^T

  void add_box(const Vec3& centre, const Vec3& size) {
    const double v = size.prod();
    volume += v;
    first += v * centre;
    second += v * centre * centre.transpose();
    second.diagonal() += v * size.cwiseProduct(size) / 12.0;
  }
  void add_point(const Vec3& x, double weight) {
    volume += weight;
    first += weight * x;
    second += weight * x * x.transpose();
  }
  void add_sphere(const Vec3& c, double r) {
    const double v = 4.0 / 3.0 * kPi * r * r * r;
    volume += v;
    first += v * c;
    second += v * c * c.transpose();
    second.diagonal().array() += v * r * r / 5.0;
  }
};

bool any_overlap(const std::vector<Vec3>& c, const std::vector<double>& r) {
  for (std::size_t i = 0; i < c.size(); ++i)
    for (std::size_t j = i + 1; j < c.size(); ++j)
      if ((c[i] - c[j]).norm() < r[i] + r[j]) return true;
  return false;
}

// Integrates the union of spheres by adaptive octree: cells inside one sphere
// are added exactly, cells outside all are dropped, cells cut by the surface
// are split down to 1/64 of the smallest radius, where 2x2x2 Gauss points
// decide. The error is
// confined to a one-cell layer at the surface and falls as cell size^2
// (1e-5 relative at the default depth, tested against the closed-form union
// of two spheres). The finest cells number about the spheres' surface over
// a cell's face; past kMaxCells (spheres of very different sizes, a large
// one with a tiny one) the finest cells are coarser, so that no shape takes
// more than about a second. The built-in flake of 19 spheres needs 2.5e6.
class UnionIntegrator {
 public:
  static constexpr double kMaxCells = 1e7;

  UnionIntegrator(const std::vector<Vec3>& c, const std::vector<double>& r) : c_(c), r_(r) {}

  // Cells down to 1/64 of the smallest radius.
  Moments integrate() {
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (std::size_t i = 0; i < c_.size(); ++i) {
      lo = lo.cwiseMin(c_[i] - Vec3::Constant(r_[i]));
      hi = hi.cwiseMax(c_[i] + Vec3::Constant(r_[i]));
    }
    const double edge = (hi - lo).maxCoeff();
    const double finest = *std::min_element(r_.begin(), r_.end()) / 64.0;
    double surface = 0.0;
    for (const double r : r_) surface += 4.0 * kPi * r * r;
    int depth = std::min(12, int(std::ceil(std::log2(edge / finest))));
    while (depth > 0 && surface / std::pow(std::ldexp(edge, -depth), 2) > kMaxCells) --depth;
    near_.assign(std::size_t(depth) + 2, {});
    for (std::size_t i = 0; i < c_.size(); ++i) near_[std::size_t(depth) + 1].push_back(i);
    Moments m;
    visit(lo, edge, depth, m);
    return m;
  }

 private:
  // A cell's tests go over the spheres that reach its parent only, in
  // index order (near_[depth + 1]), not over all of a cluster's spheres in
  // every cell. A sphere dropped from the list is farther from the
  // parent than its radius by a margin far above rounding, so it cannot
  // touch or contain any point of a child: the same cells are added in the
  // same order, to the bit.
  void visit(const Vec3& lo, double edge, int depth, Moments& m) {
    const Vec3 hi = lo + Vec3::Constant(edge);
    std::vector<std::size_t>& near = near_[std::size_t(depth)];
    near.clear();
    bool touches = false;
    for (const std::size_t i : near_[std::size_t(depth) + 1]) {
      const Vec3 nearest = c_[i].cwiseMax(lo).cwiseMin(hi);
      const double d2 = (nearest - c_[i]).squaredNorm(), r2 = r_[i] * r_[i];
      if (d2 < r2 * (1.0 + 1e-9)) near.push_back(i);
      if (d2 >= r2) continue;
      touches = true;
      const Vec3 far = (c_[i] - lo).cwiseAbs().cwiseMax((c_[i] - hi).cwiseAbs());
      if (far.squaredNorm() <= r2) {  // whole cell inside sphere i
        m.add_box(lo + Vec3::Constant(0.5 * edge), Vec3::Constant(edge));
        return;
      }
    }
    if (!touches) return;
    if (depth == 0) {
      const double g = 0.5 / std::sqrt(3.0);  // Gauss-Legendre nodes at 1/2 ± g
      const double w = edge * edge * edge / 8.0;
      for (int k = 0; k < 8; ++k) {
        const Vec3 p = lo + edge * Vec3(0.5 + ((k & 1) ? g : -g), 0.5 + ((k & 2) ? g : -g),
                                        0.5 + ((k & 4) ? g : -g));
        if (inside_any(p, near)) m.add_point(p, w);
      }
      return;
    }
    const double half = 0.5 * edge;
    for (int k = 0; k < 8; ++k)
      visit(lo + half * Vec3(k & 1, (k >> 1) & 1, (k >> 2) & 1), half, depth - 1, m);
  }
  bool inside_any(const Vec3& p, const std::vector<std::size_t>& spheres) const {
    for (const std::size_t i : spheres)
      if ((p - c_[i]).squaredNorm() <= r_[i] * r_[i]) return true;
    return false;
  }
  const std::vector<Vec3>& c_;
  const std::vector<double>& r_;
  std::vector<std::vector<std::size_t>> near_;  // per depth: the spheres near the cell visited
};

// The union's moments, remembered per process by the spheres' bits: the
// integration is most of a scene's load, and a process that loads scenes
// again (a sweep through the Python module, a test's cases) integrates
// the same clusters again. A remembered result is the integration's own,
// to the bit.
Moments union_moments(const std::vector<Vec3>& centers, const std::vector<double>& radii) {
  constexpr std::size_t kRemembered = 64;  // clusters; a scene makes at most a few dozen
  std::vector<std::uint64_t> key;
  key.reserve(4 * centers.size());
  for (std::size_t i = 0; i < centers.size(); ++i) {
    for (int k = 0; k < 3; ++k) key.push_back(std::bit_cast<std::uint64_t>(centers[i][k]));
    key.push_back(std::bit_cast<std::uint64_t>(radii[i]));
  }
  static std::mutex mutex;
  static std::map<std::vector<std::uint64_t>, Moments> known;
  {
    const std::lock_guard lock(mutex);
    if (const auto it = known.find(key); it != known.end()) return it->second;
  }
  const Moments m = UnionIntegrator(centers, radii).integrate();  // outside the lock
  const std::lock_guard lock(mutex);
  if (known.size() >= kRemembered) known.clear();
  known.emplace(std::move(key), m);
  return m;
}

// Eigen returns eigenvectors with arbitrary signs; fix them so the principal
// frame is right-handed and reproducible.
Mat3 canonical_axes(Mat3 axes) {
  for (int k = 0; k < 2; ++k) {
    const Eigen::Index i = [&] {
      Eigen::Index idx;
      axes.col(k).cwiseAbs().maxCoeff(&idx);
      return idx;
    }();
    if (axes(i, k) < 0) axes.col(k) = -axes.col(k);
  }
  axes.col(2) = axes.col(0).cross(axes.col(1));
  return axes;
}

// A sphere's centre in a plane's coordinates.
struct Corner {
  double x, y;
  std::uint32_t sphere;
};

// The plane fitted to a shape's centres, into face's frame: through their
// mean, its normal the direction they spread least in, its x axis the one
// they spread most.
void fit_plane(const std::vector<Vec3>& centers, FlatFace& face) {
  Vec3 origin = Vec3::Zero();
  for (const Vec3& c : centers) origin += c;
  origin /= double(centers.size());
  Mat3 spread = Mat3::Zero();
  for (const Vec3& c : centers) spread += (c - origin) * (c - origin).transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(spread);
  face.origin = origin;
  face.normal = eig.eigenvectors().col(0);
  face.x_axis = eig.eigenvectors().col(2);
  face.y_axis = face.normal.cross(face.x_axis);
}

// The hull of points (a plane's centres), counter-clockwise, into
// face.hull and face.corners. Points on an edge are not its corners.
void add_hull(std::vector<Corner> points, double least_turn, FlatFace& face) {
  std::sort(points.begin(), points.end(), [](const Corner& a, const Corner& b) {
    return std::tie(a.x, a.y, a.sphere) < std::tie(b.x, b.y, b.sphere);
  });
  std::vector<Corner> chain(2 * points.size());
  const std::size_t top = monotone_chain(
      points.data(), points.size(), chain.data(), [&](const Corner& o, const Corner& a,
                                                      const Corner& b) {
        return turn(o, a, b) > least_turn;
      });
  // The chains' ends appear twice: each corner once, counter-clockwise.
  for (std::size_t i = 0; i < top; ++i) {
    const bool repeated = (i > 0 && chain[i].sphere == chain[i - 1].sphere) ||
                          (i + 1 == top && chain[i].sphere == chain[0].sphere);
    if (repeated) continue;
    face.hull.push_back({chain[i].x, chain[i].y});
    face.corners.push_back(chain[i].sphere);
  }
}

// The squared distance from the origin past which no point is over the
// face: the farthest corner, with a margin far above the billionth of an
// edge that covers admits past the rim, also at a corner a thousandth of a
// degree sharp: the early out changes no answer.
double beyond(const FlatFace& face) {
  double corner = 0.0, edge = 0.0;
  for (std::size_t i = 0; i < face.hull.size(); ++i) {
    const auto& a = face.hull[i];
    const auto& b = face.hull[next_corner(i, face.hull.size())];
    corner = std::max(corner, std::hypot(a[0], a[1]));
    edge = std::max(edge, std::hypot(b[0] - a[0], b[1] - a[1]));
  }
  const double reach = corner + 1e-3 * (corner + edge);
  return reach * reach;
}

// The plate of spheres of one radius centred in one plane (a centre off
// it by more than rounding, or two radii, and the shape is not flat). The
// plane is fitted to the centres, not taken from the principal axes: those
// of overlapping spheres come from a numerical integration.
FlatFace flat_face(const ParticleShape& s) {
  FlatFace face;
  if (s.centers.size() < 3) return face;
  for (double r : s.radii)
    if (std::abs(r - s.radii[0]) > 1e-12 * s.radii[0]) return face;
  fit_plane(s.centers, face);
  const double thin = 1e-9 * s.bounding_radius;
  std::vector<Corner> points;
  for (std::size_t k = 0; k < s.centers.size(); ++k) {
    const Vec3 d = s.centers[k] - face.origin;
    if (std::abs(d.dot(face.normal)) > thin) return FlatFace{};
    points.push_back({d.dot(face.x_axis), d.dot(face.y_axis), std::uint32_t(k)});
  }
  add_hull(std::move(points), thin * s.bounding_radius, face);
  if (face.hull.size() < 3) return FlatFace{};  // centres in a line: a rod, not a plate
  face.at_corner.assign(s.centers.size(), 0);
  for (std::uint32_t k : face.corners) face.at_corner[k] = 1;
  face.beyond = beyond(face);
  return face;
}

}  // namespace

bool FlatFace::covers(double x, double y) const {
  if (x * x + y * y > beyond) return false;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const auto& a = hull[i];
    const auto& b = hull[next_corner(i, hull.size())];
    const double ex = b[0] - a[0], ey = b[1] - a[1];
    // The cross product is the edge's length times the distance from it.
    if (ex * (y - a[1]) - ey * (x - a[0]) < -1e-9 * (ex * ex + ey * ey)) return false;
  }
  return true;
}

ParticleShape make_particle_shape(const std::vector<Vec3>& centers, const std::vector<double>& radii,
                                  Pose* frame) {
  if (centers.empty() || centers.size() != radii.size())
    throw std::invalid_argument("particle shape needs one radius per sphere centre");
  for (double r : radii)
    if (!(r > 0.0)) throw std::invalid_argument("particle sphere radius must be > 0");
  Moments m;
  if (!any_overlap(centers, radii)) {
    for (std::size_t i = 0; i < centers.size(); ++i) m.add_sphere(centers[i], radii[i]);
  } else {
    m = union_moments(centers, radii);
  }
  const Vec3 com = m.first / m.volume;
  const Mat3 second = m.second / m.volume - com * com.transpose();  // about the COM, per unit mass
  const Mat3 inertia = Mat3::Identity() * second.trace() - second;
  Mat3 axes = Mat3::Identity();
  Vec3 principal = inertia.diagonal();
  if (centers.size() > 1) {
    Eigen::SelfAdjointEigenSolver<Mat3> eig(inertia);
    axes = canonical_axes(eig.eigenvectors());
    principal = eig.eigenvalues();
  }
  ParticleShape s;
  s.volume = m.volume;
  s.unit_inertia = principal;
  for (std::size_t i = 0; i < centers.size(); ++i) {
    s.centers.push_back(axes.transpose() * (centers[i] - com));
    s.radii.push_back(radii[i]);
    s.bounding_radius = std::max(s.bounding_radius, s.centers.back().norm() + radii[i]);
  }
  s.face = flat_face(s);
  if (frame) *frame = Pose{com, Quat(axes)};
  return s;
}

geo::Aabb world_bounds(const RigidBody& b) {
  const geo::Aabb local = geo::local_bounds(b.shape);
  geo::Aabb box = geo::Aabb::empty();
  for (int k = 0; k < 8; ++k) box.grow(b.pose.apply(local.corner(k)));
  return box;
}

double particle_mass(const Model& model, int shape, double scale, int material) {
  const ParticleShape& s = model.shapes.at(std::size_t(shape));
  const double density = model.materials.materials().at(std::size_t(material)).density;
  return density * s.volume * scale * scale * scale;
}

}  // namespace ces
