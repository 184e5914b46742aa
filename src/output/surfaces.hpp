// The machine's surfaces as polygons, for the trajectory files: a plane as
// a square, a box as six quadrilaterals, a cylinder with kCylinderFacets
// facets around (they lie within 0.06 % of its radius of the true
// surface), a mesh as its triangles. World frame; each polygon tagged with
// the part it belongs to; outward normals by the right-hand rule.
#pragma once
#include <cstdint>
#include <vector>

#include "common/math.hpp"
#include "geometry/shapes.hpp"

namespace ces::output {

inline constexpr int kCylinderFacets = 96;

struct SurfaceMesh {
  std::vector<Vec3> points;
  std::vector<std::int64_t> connectivity, offsets;  // VTK's layout of polygons
  std::vector<std::int32_t> part;                   // per polygon
};

// Planes are unbounded: each is drawn as the square of side 2 half_size
// centred on its point nearest `centre`.
struct PlaneExtent {
  Vec3 centre = Vec3::Zero();
  double half_size = 0.5;  // m
};

// Appends `shape` placed at `pose`, its polygons tagged `part`.
void add_surface(const geo::Shape& shape, const Pose& pose, int part, const PlaneExtent& plane,
                 SurfaceMesh& out);

// A cylinder of `radius` from z = -half_length to half_length about the
// axis through (x, y) along z (the field model's electrodes).
void add_z_cylinder(const Vec2& centre, double radius, double half_length, int part,
                    SurfaceMesh& out);

}  // namespace ces::output
