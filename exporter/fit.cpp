#include "fit.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
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

// Eigenvalues of the normals' scatter closer than this fraction of the
// largest count as one: a square plate leaves a plane of eigenvectors, a
// cube all of space, and facet normals pick the face directions there.
constexpr double kSameEigenvalue = 1e-3;
// A facet within 1 degree of a face direction lies on that face; float
// STL coordinates tilt a 1 mm facet 2 m from the origin by 1e-4 rad.
constexpr double kOnFaceCos = 0.99985;

// The normal of the largest facet `keep` accepts; `fallback` for none.
template <class Keep>
Vec3 largest_facet_normal(const Mesh& m, Keep keep, const Vec3& fallback) {
  double best = 0.0;
  Vec3 found = fallback;
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    if (const Vec3 n = m.normal(t); keep(n) && m.area(t) > best) {
      best = m.area(t);
      found = n;
    }
  return found;
}

// The principal axes of the facet normals: for a box, its face directions
// (the eigenvalues are twice the areas of the faces across them).
Mat3 principal_axes(const Mesh& m) {
  const auto all = [](const Vec3&) { return true; };
  const Eigen::SelfAdjointEigenSolver<Mat3> eigen(normal_scatter(m, all));
  const Vec3& l = eigen.eigenvalues();
  const Mat3& v = eigen.eigenvectors();
  const bool low_pair = l(1) - l(0) <= kSameEigenvalue * l(2);
  const bool high_pair = l(2) - l(1) <= kSameEigenvalue * l(2);
  if (!low_pair && !high_pair) return v;
  // The axis whose eigenvalue stands apart, or, when none does, the largest
  // facet's normal; then the largest facet across it (within 60 degrees of
  // perpendicular) gives the second.
  const Vec3 a = !low_pair    ? v.col(0)
                 : !high_pair ? v.col(2)
                              : largest_facet_normal(m, all, v.col(0));
  const auto across = [&](const Vec3& n) { return std::abs(n.dot(a)) <= 0.5; };
  const Vec3 n = largest_facet_normal(m, across, a.unitOrthogonal());
  Mat3 axes;
  axes.col(0) = a;
  axes.col(1) = (n - n.dot(a) * a).normalized();
  axes.col(2) = a.cross(axes.col(1));
  return axes;
}

// Each axis made the area-weighted mean of the normals on its two faces,
// then the nearest orthogonal frame (polar decomposition): a single facet's
// float noise averages out over all of them.
Mat3 refine_axes(const Mesh& m, const Mat3& axes) {
  Mat3 sum = Mat3::Zero();
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Vec3 n = m.normal(t);
    for (int k = 0; k < 3; ++k)
      if (const double c = n.dot(axes.col(k)); std::abs(c) > kOnFaceCos)
        sum.col(k) += m.area(t) * (c > 0.0 ? n : Vec3(-n));
  }
  if ((sum.colwise().norm().array() == 0.0).any()) return axes;
  const Eigen::JacobiSVD<Mat3> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

// Volume enclosed by outward-wound closed pieces, from `c` (near the mesh,
// so the terms do not cancel far from the origin).
double enclosed_volume(const Mesh& m, const Vec3& c) {
  double v = 0.0;
  for (const auto& t : m.triangles)
    v += (m.vertices[t[0]] - c).dot((m.vertices[t[1]] - c).cross(m.vertices[t[2]] - c));
  return v / 6.0;
}

// The facet area on each of the six faces (-x, +x, -y, ... of `frame`) and
// the area on none.
std::array<double, 7> face_areas(const Mesh& m, const Mat3& frame) {
  std::array<double, 7> a{};
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Vec3 n = frame.transpose() * m.normal(t);
    int face = 6;
    for (int k = 0; k < 3; ++k)
      if (std::abs(n[k]) > kOnFaceCos) face = 2 * k + (n[k] > 0.0 ? 1 : 0);
    a[std::size_t(face)] += m.area(t);
  }
  return a;
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

std::optional<BoxFit> fit_box(const Mesh& mesh) {
  if (!(total_area(mesh) > 0.0)) return std::nullopt;
  const Mat3 axes = refine_axes(mesh, principal_axes(mesh));
  BoxFit f;
  f.box.frame = frame_near_world({axes.col(0), axes.col(1), axes.col(2)});
  Bounds local;
  for (const Vec3& p : mesh.vertices) local.add(f.box.frame.transpose() * p);
  const Vec3 s = local.size();
  f.box.size = s;
  f.box.center = f.box.frame * local.center();
  const Vec3 faces(s.y() * s.z(), s.z() * s.x(), s.x() * s.y());
  if (!(faces.minCoeff() > 0.0)) {  // a flat sheet: no volume to measure against
    f.volume_error = f.face_error = f.other_area = 1.0;
    return f;
  }
  const double volume = s.prod();
  f.volume_error = std::abs(enclosed_volume(mesh, f.box.center) - volume) / volume;
  const auto on = face_areas(mesh, f.box.frame);
  for (int k = 0; k < 6; ++k)
    f.face_error =
        std::max(f.face_error, std::abs(on[std::size_t(k)] - faces[k / 2]) / faces[k / 2]);
  f.other_area = on[6] / (2.0 * faces.sum());
  return f;
}

}  // namespace ces::exporter
