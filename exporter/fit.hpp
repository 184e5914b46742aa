// Primitives recovered from triangles: a least-squares cylinder (drums,
// brushes and electrodes from STL/OBJ) and an oriented box (plate splitters),
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

// A mesh's oriented bounding box and how far the mesh is from it, each as a
// fraction: all three are 0 for a box.
struct BoxFit {
  Box box;
  // |mesh volume - box volume| / box volume
  double volume_error = 0.0;
  // The largest over the six faces of |facet area on it - its area| / its area.
  double face_error = 0.0;
  // The facet area facing none of the six ways / the box's area.
  double other_area = 0.0;
  bool within(double tolerance) const {
    return volume_error <= tolerance && face_error <= tolerance && other_area <= tolerance;
  }
};

// A part counts as its box when volume and every face's area agree within
// this fraction: float STL coordinates are off by 6e-8 of the coordinate,
// 1.2e-4 of a 1 mm plate's thickness 2 m from the origin, while a hole or a
// slot of more than 0.1 % of a face is a real feature.
inline constexpr double kBoxTolerance = 1e-3;

// The box around the mesh along its principal axes (those of the facet
// normals' area-weighted scatter, whose eigenvectors are a box's face
// directions), at any orientation, measured against the mesh; nullopt for
// a mesh without area. The frame's columns are those nearest to x, y and
// z, pointing their way.
std::optional<BoxFit> fit_box(const Mesh& mesh);

}  // namespace ces::exporter
