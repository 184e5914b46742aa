#include "fit.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <vector>

namespace ces::exporter {
namespace {

// A facet belongs to the side when its normal is within ~11 degrees of
// perpendicular to the axis, to an end cap within ~11 degrees of parallel.
constexpr double kSideCos = 0.2;
constexpr double kCapCos = 0.98;
constexpr double kMinSideFraction = 0.2;

// Area-weighted scatter of the normals of the facets `keep` accepts.
template <class Keep>
Mat3 normal_scatter(const Mesh& m, Keep keep) {
  Mat3 s = Mat3::Zero();
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Vec3 n = m.normal(t);
    if (keep(n)) s += m.area(t) * n * n.transpose();
  }
  return s;
}

// Eigenvectors in order of increasing eigenvalue (columns).
Mat3 eigenvectors(const Mat3& s) { return Eigen::SelfAdjointEigenSolver<Mat3>(s).eigenvectors(); }

double total_area(const Mesh& m) {
  double a = 0.0;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) a += m.area(t);
  return a;
}

double area_where(const Mesh& m, const Vec3& axis, double lo, double hi) {
  double a = 0.0;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const double c = std::abs(m.normal(t).dot(axis));
    if (c >= lo && c < hi) a += m.area(t);
  }
  return a;
}

struct Circle {
  Vec2 center = Vec2::Zero();
  double radius = 0.0;
};

// Kasa's algebraic fit (linear least squares on centred points), then
// Gauss-Newton on the geometric distances, which the algebraic fit biases.
Circle fit_circle(const std::vector<Vec2>& points) {
  Vec2 mean = Vec2::Zero();
  for (const Vec2& p : points) mean += p;
  mean /= double(points.size());
  Eigen::MatrixXd a(points.size(), 3);
  Eigen::VectorXd b(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec2 q = points[i] - mean;
    a.row(Eigen::Index(i)) << q.x(), q.y(), 1.0;
    b(Eigen::Index(i)) = -q.squaredNorm();
  }
  const Eigen::Vector3d d = a.colPivHouseholderQr().solve(b);
  Circle c{mean - 0.5 * d.head<2>(),
           std::sqrt(std::max(0.25 * d.head<2>().squaredNorm() - d(2), 0.0))};
  for (int iter = 0; iter < 20; ++iter) {
    Eigen::MatrixXd j(points.size(), 3);
    Eigen::VectorXd r(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Vec2 q = points[i] - c.center;
      const double len = std::max(q.norm(), 1e-300);
      j.row(Eigen::Index(i)) << -q.x() / len, -q.y() / len, -1.0;
      r(Eigen::Index(i)) = len - c.radius;
    }
    const Eigen::Vector3d step = j.colPivHouseholderQr().solve(-r);
    c.center += step.head<2>();
    c.radius += step(2);
    if (step.norm() <= 1e-15 * c.radius) break;
  }
  return c;
}

// Side facets with respect to `axis`, refined twice: the smallest direction
// of the side normals' scatter is the axis the side facets are parallel to.
std::optional<Vec3> refine_axis(const Mesh& m, Vec3 axis, double area) {
  for (int iter = 0; iter < 3; ++iter) {
    const auto is_side = [&](const Vec3& n) { return std::abs(n.dot(axis)) < kSideCos; };
    if (area_where(m, axis, 0.0, kSideCos) < kMinSideFraction * area) return std::nullopt;
    axis = eigenvectors(normal_scatter(m, is_side)).col(0);
  }
  return canonical_axis(axis);
}

struct SideSamples {
  std::vector<Vec3> vertices;   // each side vertex once
  std::vector<Vec3> centroids;  // of the side facets
};

SideSamples side_samples(const Mesh& m, const Vec3& axis) {
  SideSamples s;
  std::vector<bool> seen(m.vertices.size(), false);
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    if (std::abs(m.normal(t).dot(axis)) >= kSideCos) continue;
    Vec3 sum = Vec3::Zero();
    for (std::uint32_t v : m.triangles[t]) {
      sum += m.vertices[v];
      if (!seen[v]) s.vertices.push_back(m.vertices[v]);
      seen[v] = true;
    }
    s.centroids.push_back(sum / 3.0);
  }
  return s;
}

std::optional<CylinderFit> fit_about(const Mesh& m, const Vec3& guess, double area) {
  const auto axis = refine_axis(m, guess, area);
  if (!axis) return std::nullopt;
  const SideSamples s = side_samples(m, *axis);
  if (s.vertices.size() < 3) return std::nullopt;
  const Vec3 u = axis->unitOrthogonal();
  const Vec3 v = axis->cross(u);
  std::vector<Vec2> plane;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Vec3& p : s.vertices) {
    plane.emplace_back(p.dot(u), p.dot(v));
    lo = std::min(lo, p.dot(*axis));
    hi = std::max(hi, p.dot(*axis));
  }
  const Circle c = fit_circle(plane);
  double sum2 = 0.0;
  for (const auto* set : {&s.vertices, &s.centroids})
    for (const Vec3& p : *set) {
      const double d = (Vec2(p.dot(u), p.dot(v)) - c.center).norm() - c.radius;
      sum2 += d * d;
    }
  CylinderFit f;
  f.cylinder.axis = *axis;
  f.cylinder.center = c.center.x() * u + c.center.y() * v + 0.5 * (lo + hi) * *axis;
  f.cylinder.radius = c.radius;
  f.cylinder.length = hi - lo;
  f.rms = std::sqrt(sum2 / double(s.vertices.size() + s.centroids.size()));
  f.other_fraction = area_where(m, *axis, kSideCos, kCapCos) / area;
  return f;
}

// The three normal directions of a box, or nullopt.
std::optional<std::vector<Vec3>> box_directions(const Mesh& m) {
  constexpr double kParallel = 1.0 - 1e-9;
  std::vector<Vec3> dirs;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Vec3 n = m.normal(t);
    const bool known = std::any_of(dirs.begin(), dirs.end(),
                                   [&](const Vec3& d) { return std::abs(n.dot(d)) > kParallel; });
    if (known) continue;
    if (dirs.size() == 3) return std::nullopt;
    dirs.push_back(n);
  }
  if (dirs.size() != 3) return std::nullopt;
  for (int i = 0; i < 3; ++i)
    if (std::abs(dirs[i].dot(dirs[(i + 1) % 3])) > 1e-9) return std::nullopt;
  return dirs;
}

// Columns nearest to x, y and z, each pointing its way; the third is the
// cross product so the frame is a rotation.
Mat3 frame_near_world(std::vector<Vec3> dirs) {
  Mat3 f;
  for (int k = 0; k < 2; ++k) {
    const auto best = std::max_element(dirs.begin(), dirs.end(), [&](const Vec3& a, const Vec3& b) {
      return std::abs(a[k]) < std::abs(b[k]);
    });
    f.col(k) = (*best)[k] < 0.0 ? Vec3(-*best) : *best;
    dirs.erase(best);
  }
  f.col(2) = f.col(0).cross(f.col(1));
  return f;
}

}  // namespace

Vec3 canonical_axis(const Vec3& axis) {
  Eigen::Index k = 0;
  axis.cwiseAbs().maxCoeff(&k);
  const Vec3 a = axis.normalized();
  return a[k] < 0.0 ? Vec3(-a) : a;
}

std::optional<CylinderFit> fit_cylinder(const Mesh& mesh) {
  const double area = total_area(mesh);
  if (!(area > 0.0)) return std::nullopt;
  const Mat3 guesses = eigenvectors(normal_scatter(mesh, [](const Vec3&) { return true; }));
  std::optional<CylinderFit> best;
  for (int k = 0; k < 3; ++k) {
    const auto f = fit_about(mesh, guesses.col(k), area);
    if (f && (!best || f->rms / f->cylinder.radius < best->rms / best->cylinder.radius)) best = f;
  }
  return best;
}

std::optional<Box> match_box(const Mesh& mesh, double tolerance) {
  const auto dirs = box_directions(mesh);
  if (!dirs) return std::nullopt;
  Box box;
  box.frame = frame_near_world(*dirs);
  Bounds local;
  for (const Vec3& p : mesh.vertices) local.add(box.frame.transpose() * p);
  for (const Vec3& p : mesh.vertices) {
    const Vec3 q = box.frame.transpose() * p;
    const bool on_face = ((q - local.min).cwiseAbs().array() <= tolerance).any() ||
                         ((q - local.max).cwiseAbs().array() <= tolerance).any();
    if (!on_face) return std::nullopt;
  }
  box.size = local.size();
  box.center = box.frame * local.center();
  // Facets on the faces but not covering them (an open box, a plate with a
  // slot) show as missing area.
  const Vec3& s = box.size;
  const double faces = 2.0 * (s.x() * s.y() + s.y() * s.z() + s.z() * s.x());
  if (std::abs(total_area(mesh) - faces) > 1e-6 * faces) return std::nullopt;
  return box;
}

}  // namespace ces::exporter
