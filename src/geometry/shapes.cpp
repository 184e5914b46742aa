// Closed-form distance queries for the analytic shapes, the Aabb helpers and
// the Shape dispatch. Meshes live in mesh.cpp.
#include "geometry/shapes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ces::geo {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void query_plane(const Plane& plane, const Vec3& p, double max_distance,
                 std::vector<SurfaceHit>& out) {
  const double d = plane.normal.dot(p) - plane.offset;
  if (d > max_distance) return;
  out.push_back({p - d * plane.normal, plane.normal, d, 0});
}

// Box feature ids: one base-3 digit per axis (see shapes.hpp).
constexpr std::array<std::uint32_t, 3> kPow3 = {1, 3, 9};

std::uint32_t box_digit(int axis, bool positive) { return (positive ? 1u : 2u) * kPow3[axis]; }

// Inside (or on) the box the closest surface point lies on the nearest face;
// ties go to the lowest axis and the + face so the choice is deterministic.
void query_box_inside(const Vec3& h, const Vec3& p, double max_distance,
                      std::vector<SurfaceHit>& out) {
  int axis = 0;
  double depth = h.x() - std::abs(p.x());
  for (int i = 1; i < 3; ++i) {
    const double d = h[i] - std::abs(p[i]);
    if (d < depth) {
      axis = i;
      depth = d;
    }
  }
  if (-depth > max_distance) return;
  const bool positive = p[axis] >= 0.0;
  Vec3 point = p;
  point[axis] = positive ? h[axis] : -h[axis];
  Vec3 normal = Vec3::Zero();
  normal[axis] = positive ? 1.0 : -1.0;
  out.push_back({point, normal, -depth, box_digit(axis, positive)});
}

void query_box(const Box& box, const Vec3& p, double max_distance, std::vector<SurfaceHit>& out) {
  const Vec3& h = box.half_extents;
  Vec3 point = p;
  Vec3 offset = Vec3::Zero();  // p - point, computed per axis without cancellation
  std::uint32_t feature = 0;
  int outside = 0;
  for (int i = 0; i < 3; ++i) {
    if (p[i] > h[i] || p[i] < -h[i]) {
      const bool positive = p[i] > 0.0;
      point[i] = positive ? h[i] : -h[i];
      offset[i] = positive ? p[i] - h[i] : p[i] + h[i];
      feature += box_digit(i, positive);
      ++outside;
    }
  }
  if (outside == 0) {
    query_box_inside(h, p, max_distance, out);
    return;
  }
  // Face regions: the distance is the single axis offset, exactly.
  const double distance = outside == 1 ? offset.cwiseAbs().maxCoeff() : offset.norm();
  if (distance > max_distance) return;
  out.push_back({point, offset / distance, distance, feature});
}

// Hit on one side of the (rho, z) rectangle, mapped back to 3-D. Caps keep
// the query's x and y exactly instead of rebuilding them from rho.
SurfaceHit cylinder_side(std::uint32_t side, double distance, const Vec3& p, const Vec3& radial,
                         double outer, double inner, double half_length) {
  switch (side) {
    case kCylOuter:
      return {Vec3(outer * radial.x(), outer * radial.y(), p.z()), radial, distance, side};
    case kCylInner:
      return {Vec3(inner * radial.x(), inner * radial.y(), p.z()), -radial, distance, side};
    case kCylTop:
      return {Vec3(p.x(), p.y(), half_length), Vec3::UnitZ(), distance, side};
    default:
      return {Vec3(p.x(), p.y(), -half_length), -Vec3::UnitZ(), distance, side};
  }
}

void query_cylinder(const Cylinder& c, const Vec3& p, double max_distance,
                    std::vector<SurfaceHit>& out) {
  // rho to about an ulp (std::hypot's care for overflow is not needed at a
  // machine's scale, and is slow in this, the drum's hot query); every
  // distance below is one subtraction of nearby numbers, exact by Sterbenz
  // near the surface.
  const double rho = std::sqrt(p.x() * p.x() + p.y() * p.y());
  // On the axis every radial direction is equally close: pick +x.
  const Vec3 radial = rho > 0.0 ? Vec3(p.x() / rho, p.y() / rho, 0.0) : Vec3::UnitX();
  const bool hollow = c.thickness > 0.0 && c.thickness < c.radius;
  const double inner = hollow ? c.radius - c.thickness : 0.0;
  const double h = c.half_length;

  // Signed distance to each side's line, positive outside; indexed by
  // CylinderFeature. A solid cylinder has no inner side.
  const std::array<double, 4> side = {rho - c.radius, hollow ? inner - rho : -kInf, p.z() - h,
                                      -h - p.z()};
  const bool radial_out = side[kCylOuter] > 0.0 || side[kCylInner] > 0.0;
  const bool axial_out = side[kCylTop] > 0.0 || side[kCylBottom] > 0.0;

  if (radial_out && axial_out) {  // closest to a rim (rectangle corner)
    const bool is_outer = side[kCylOuter] > 0.0;
    const bool is_top = side[kCylTop] > 0.0;
    const double dr = is_outer ? side[kCylOuter] : -side[kCylInner];
    const double dz = is_top ? side[kCylTop] : -side[kCylBottom];
    const double distance = std::hypot(dr, dz);
    if (distance > max_distance) return;
    const double r = is_outer ? c.radius : inner;
    const std::uint32_t feature = (is_outer ? kCylOuterTop : kCylInnerTop) + (is_top ? 0u : 1u);
    out.push_back({Vec3(r * radial.x(), r * radial.y(), is_top ? h : -h),
                   (dr / distance) * radial + (dz / distance) * Vec3::UnitZ(), distance, feature});
    return;
  }
  // Outside one side only, or inside: the largest signed side distance is
  // the rectangle's signed distance (first side wins ties).
  const auto best = std::max_element(side.begin(), side.end());
  if (*best > max_distance) return;
  const auto feature = static_cast<std::uint32_t>(best - side.begin());
  out.push_back(cylinder_side(feature, *best, p, radial, c.radius, inner, h));
}

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;  // not implied for aggregates before clang 17

}  // namespace

Aabb Aabb::empty() { return {Vec3::Constant(kInf), Vec3::Constant(-kInf)}; }

void Aabb::grow(const Vec3& p) {
  min = min.cwiseMin(p);
  max = max.cwiseMax(p);
}

void Aabb::grow(const Aabb& b) {
  min = min.cwiseMin(b.min);
  max = max.cwiseMax(b.max);
}

Aabb Aabb::inflated(double margin) const {
  return {(min.array() - margin).matrix(), (max.array() + margin).matrix()};
}

bool Aabb::overlaps(const Aabb& o) const {
  return (min.array() <= o.max.array()).all() && (o.min.array() <= max.array()).all();
}

void query(const Shape& shape, const Vec3& p, double max_distance, std::vector<SurfaceHit>& out) {
  std::visit(Overloaded{
                 [&](const Plane& s) { query_plane(s, p, max_distance, out); },
                 [&](const Box& s) { query_box(s, p, max_distance, out); },
                 [&](const Cylinder& s) { query_cylinder(s, p, max_distance, out); },
                 [&](const std::shared_ptr<const TriMesh>& s) {
                   if (s) s->query(p, max_distance, out);
                 },
             },
             shape);
}

Aabb local_bounds(const Shape& shape) {
  return std::visit(
      Overloaded{
          [](const Plane&) {
            return Aabb{Vec3::Constant(-kInf), Vec3::Constant(kInf)};
          },
          [](const Box& s) {
            return Aabb{-s.half_extents, s.half_extents};
          },
          [](const Cylinder& s) {
            const Vec3 h(s.radius, s.radius, s.half_length);
            return Aabb{-h, h};
          },
          [](const std::shared_ptr<const TriMesh>& s) { return s ? s->bounds() : Aabb::empty(); },
      },
      shape);
}

}  // namespace ces::geo
