#include "output/surfaces.hpp"

#include <cmath>
#include <initializer_list>
#include <type_traits>

namespace ces::output {
namespace {

// Builds polygons from local points placed at a pose.
class Builder {
 public:
  Builder(const Pose& pose, int part, SurfaceMesh& out)
      : pose_(pose), part_(part), out_(out), base_(std::int64_t(out.points.size())) {}

  std::int64_t point(const Vec3& local) {
    out_.points.push_back(pose_.apply(local));
    return std::int64_t(out_.points.size()) - 1 - base_;
  }
  // Indices from this builder's first point, counter-clockwise seen from outside.
  void polygon(std::initializer_list<std::int64_t> corners) {
    for (const std::int64_t c : corners) out_.connectivity.push_back(base_ + c);
    out_.offsets.push_back(std::int64_t(out_.connectivity.size()));
    out_.part.push_back(part_);
  }

 private:
  const Pose& pose_;
  int part_;
  SurfaceMesh& out_;
  std::int64_t base_;
};

void add_plane(const geo::Plane& plane, const PlaneExtent& extent, Builder& b, const Pose& pose) {
  const Vec3 n = plane.normal.normalized();
  const Vec3 near = pose.inverse_apply(extent.centre);
  const Vec3 c = near - (n.dot(near) - plane.offset) * n;
  const Vec3 u = n.unitOrthogonal() * extent.half_size;
  const Vec3 v = n.cross(u);
  b.point(c - u - v);
  b.point(c + u - v);
  b.point(c + u + v);
  b.point(c - u + v);
  b.polygon({0, 1, 2, 3});
}

void add_box(const geo::Box& box, Builder& b) {
  const Vec3& h = box.half_extents;
  for (int k = 0; k < 8; ++k)  // corner k: bit 0 +x, bit 1 +y, bit 2 +z
    b.point(Vec3(k & 1 ? h.x() : -h.x(), k & 2 ? h.y() : -h.y(), k & 4 ? h.z() : -h.z()));
  b.polygon({0, 2, 3, 1});  // -z
  b.polygon({4, 5, 7, 6});  // +z
  b.polygon({0, 1, 5, 4});  // -y
  b.polygon({2, 6, 7, 3});  // +y
  b.polygon({0, 4, 6, 2});  // -x
  b.polygon({1, 3, 7, 5});  // +x
}

// Rings of kCylinderFacets points at z = -h and z = h, radius r; returns
// the index of the first (bottom ring first, then top).
std::int64_t rings(double r, double h, Builder& b) {
  std::int64_t first = -1;
  for (const double z : {-h, h})
    for (int i = 0; i < kCylinderFacets; ++i) {
      const double a = 2.0 * kPi * i / kCylinderFacets;
      const std::int64_t p = b.point(Vec3(r * std::cos(a), r * std::sin(a), z));
      if (first < 0) first = p;
    }
  return first;
}

// Quadrilaterals between rings `from` and `to`, facing away from the axis
// (from a bottom ring to its top ring) or toward +z (from an outer ring to
// an inner one at the same z); reversed unless `outward`.
void band(std::int64_t from, std::int64_t to, bool outward, Builder& b) {
  constexpr int n = kCylinderFacets;
  for (int i = 0; i < n; ++i) {
    const std::int64_t j = (i + 1) % n;
    if (outward)
      b.polygon({from + i, from + j, to + j, to + i});
    else
      b.polygon({from + i, to + i, to + j, from + j});
  }
}

void add_cylinder(const geo::Cylinder& c, Builder& b) {
  constexpr int n = kCylinderFacets;
  const std::int64_t outer = rings(c.radius, c.half_length, b);
  band(outer, outer + n, true, b);  // lateral surface
  if (c.thickness > 0.0 && c.thickness < c.radius) {
    const std::int64_t inner = rings(c.radius - c.thickness, c.half_length, b);
    band(inner, inner + n, false, b);
    band(outer, inner, false, b);         // bottom end face, facing -z
    band(outer + n, inner + n, true, b);  // top end face
    return;
  }
  const std::int64_t bottom = b.point(Vec3(0, 0, -c.half_length));
  const std::int64_t top = b.point(Vec3(0, 0, c.half_length));
  for (int i = 0; i < n; ++i) {
    const std::int64_t j = (i + 1) % n;
    b.polygon({bottom, outer + j, outer + i});
    b.polygon({top, outer + n + i, outer + n + j});
  }
}

void add_mesh(const geo::TriMesh& mesh, Builder& b) {
  for (const Vec3& v : mesh.vertices()) b.point(v);
  for (const auto& t : mesh.triangles()) b.polygon({t[0], t[1], t[2]});
}

}  // namespace

void add_surface(const geo::Shape& shape, const Pose& pose, int part, const PlaneExtent& plane,
                 SurfaceMesh& out) {
  Builder b(pose, part, out);
  std::visit(
      [&](const auto& s) {
        using S = std::decay_t<decltype(s)>;
        if constexpr (std::is_same_v<S, geo::Plane>) add_plane(s, plane, b, pose);
        else if constexpr (std::is_same_v<S, geo::Box>) add_box(s, b);
        else if constexpr (std::is_same_v<S, geo::Cylinder>) add_cylinder(s, b);
        else add_mesh(*s, b);
      },
      shape);
}

void add_z_cylinder(const Vec2& centre, double radius, double half_length, int part,
                    SurfaceMesh& out) {
  const Pose pose{Vec3(centre.x(), centre.y(), 0.0), Quat::Identity()};
  add_surface(geo::Cylinder{radius, half_length, 0.0}, pose, part, {}, out);
}

}  // namespace ces::output
