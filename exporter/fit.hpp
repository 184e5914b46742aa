// Primitives recovered from triangles: a least-squares cylinder (drums,
// brushes and electrodes from STL/OBJ) and an exact box (plate splitters),
// so the simulator can use its closed-form contacts instead of facets.
#pragma once
#include <optional>

#include "mesh.hpp"

namespace ces::exporter {

struct Cylinder {
  Vec3 axis = Vec3::UnitZ();   // unit; its largest component is positive
  Vec3 center = Vec3::Zero();  // on the axis, halfway along the length
  double radius = 0.0;
  double length = 0.0;
};

struct CylinderFit {
  Cylinder cylinder;
  // Root mean square of the distance from the fitted surface over the side's
  // vertices and facet centroids: facets too coarse for a round drum show
  // here through their centroids, not only poor fits.
  double rms = 0.0;
  double other_fraction = 0.0;  // of the area: neither side nor end caps
};

// The best cylinder through the mesh's side facets, whichever way its axis
// lies; nullopt when no direction leaves a side to fit (fewer than 3 side
// vertices, or less than 20 % of the area).
std::optional<CylinderFit> fit_cylinder(const Mesh& mesh);

// Puts an axis in the form Cylinder::axis uses (largest component positive).
Vec3 canonical_axis(const Vec3& axis);

struct Box {
  Vec3 center = Vec3::Zero();
  Mat3 frame = Mat3::Identity();  // columns: the box's edge directions
  Vec3 size = Vec3::Zero();       // edge lengths along the columns of frame
};

// The box the mesh is, when it is one: every facet normal along one of three
// orthogonal directions and every vertex on a corner, within `tolerance`
// (m). The frame's columns are those nearest to x, y and z, pointing their way.
std::optional<Box> match_box(const Mesh& mesh, double tolerance);

}  // namespace ces::exporter
