// Machine surfaces and their closed-form distance queries.
//
// Every shape lives in its body's local frame. A query takes a point in that
// frame and reports the closest surface point, the outward unit normal (out
// of the solid, toward the query point) and the signed distance (negative
// when the point is inside the solid). A sphere of radius r centred at p then
// has gap = distance - r along that normal.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "common/math.hpp"

namespace ces::geo {

struct SurfaceHit {
  Vec3 point;          // closest point on the surface (local frame)
  Vec3 normal;         // unit, out of the solid toward the query point
  double distance;     // signed: < 0 inside the solid
  std::uint32_t feature;  // stable id of the face/edge/vertex (warm start key)
};

struct Aabb {
  Vec3 min, max;
  static Aabb empty();
  void grow(const Vec3& p);
  void grow(const Aabb& b);
  Aabb inflated(double margin) const;
  bool overlaps(const Aabb& o) const;
  // Corner k of 8: bit 0 picks max.x over min.x, bit 1 y, bit 2 z.
  Vec3 corner(int k) const {
    return {(k & 1) ? max.x() : min.x(), (k & 2) ? max.y() : min.y(), (k & 4) ? max.z() : min.z()};
  }
};

// Solid half-space {x : normal . x <= offset}; its surface is the plane.
struct Plane {
  Vec3 normal = Vec3::UnitY();  // unit
  double offset = 0.0;
};

// Solid box centred at the origin. Feature ids: per axis i a base-3 digit
// (0: strictly between the faces, 1: at +half, 2: at -half), id = dx + 3dy + 9dz,
// so the 6 faces, 12 edges and 8 corners get distinct ids in 1..26.
struct Box {
  Vec3 half_extents;
};

// Cylinder along local z, centred at the origin, |z| <= half_length.
// thickness == 0: a solid cylinder (lateral surface, caps and rims).
// thickness > 0: a hollow open-ended shell, radius - thickness <= rho <= radius
// (outer and inner surfaces, and the annular rims at both ends).
// thickness >= radius leaves no hollow and is treated as solid.
// Both are a rectangle in the (rho, z) half-plane revolved about z, so one
// 2-D rectangle distance gives faces, rims and edges exactly.
// Feature ids: CylinderFeature (sides and corners of that rectangle).
struct Cylinder {
  double radius = 0.0;
  double half_length = 0.0;
  double thickness = 0.0;
};

enum CylinderFeature : std::uint32_t {
  kCylOuter = 0,      // lateral surface rho = radius
  kCylInner = 1,      // inner lateral surface rho = radius - thickness (shell)
  kCylTop = 2,        // z = +half_length: cap (solid) or annular end face (shell)
  kCylBottom = 3,     // z = -half_length
  kCylOuterTop = 4,   // rims: corners of the (rho, z) rectangle
  kCylOuterBottom = 5,
  kCylInnerTop = 6,
  kCylInnerBottom = 7,
};

// Triangle mesh with a bounding-volume hierarchy. Treated as a two-sided
// surface of zero thickness (open hoppers and chutes are sheets): distances
// are unsigned. Adjacency comes from shared vertex indices, so meshes should
// be welded (load_mesh does it). Zero-area triangles are ignored by queries.
//
// Feature ids (the top two bits are a tag):
//   face   t            triangle index
//   edge   kMeshEdge|e  e = rank of the sorted vertex pair among all edges
//   vertex kMeshVertex|v
class TriMesh {
 public:
  static constexpr std::uint32_t kMeshEdge = 1u << 30;
  static constexpr std::uint32_t kMeshVertex = 2u << 30;
  static constexpr std::uint32_t kMaxIndex = (1u << 30) - 1;

  // Throws std::invalid_argument on out-of-range indices, non-finite
  // vertices or more than kMaxIndex vertices/triangles/edges.
  TriMesh(std::vector<Vec3> vertices, std::vector<std::array<std::uint32_t, 3>> triangles);

  const std::vector<Vec3>& vertices() const { return vertices_; }
  const std::vector<std::array<std::uint32_t, 3>>& triangles() const { return triangles_; }
  const Aabb& bounds() const { return root_bounds_; }

  // Appends a hit for every surface feature within max_distance of p, one
  // per contact region: a sphere over an edge or vertex shared by several
  // triangles yields a single hit, not one per triangle. Hits are ordered by
  // feature id so the output is deterministic.
  // Precisely: one hit per local minimum of the distance from p over the
  // surface. An edge or vertex hit is dropped when an incident triangle gets
  // closer to p (its own face hit is the contact), and hits whose points
  // coincide keep only the lowest id (faces first).
  void query(const Vec3& p, double max_distance, std::vector<SurfaceHit>& out) const;

 private:
  struct Node {
    Aabb box;
    std::uint32_t first;  // leaf: first index into order_; inner: left child
    std::uint32_t count;  // leaf: number of triangles; inner: 0
  };
  std::vector<Vec3> vertices_;
  std::vector<std::array<std::uint32_t, 3>> triangles_;
  std::vector<Vec3> normals_;  // unit face normals; zero marks a degenerate triangle
  // Edge k of triangle t joins corners k and k+1; tri_edges_[t][k] is its id.
  std::vector<std::array<std::uint32_t, 3>> tri_edges_;
  std::vector<std::array<std::uint32_t, 2>> edges_;  // sorted vertex pair per edge
  // Compressed adjacency: the triangles around edge e are
  // edge_tris_[edge_start_[e] .. edge_start_[e + 1]), likewise for vertices.
  std::vector<std::uint32_t> edge_start_, edge_tris_;
  std::vector<std::uint32_t> vertex_start_, vertex_tris_;
  std::vector<std::uint32_t> order_;
  std::vector<Node> nodes_;
  Aabb root_bounds_;
  double tolerance_ = 0.0;  // coincidence radius: 1e-12 of the mesh size or offset
  void build();
  void build_adjacency();
  void query_triangle(std::uint32_t t, const Vec3& p, double max_distance,
                      std::vector<SurfaceHit>& out) const;
  bool is_edge_minimum(std::uint32_t e, const Vec3& d) const;
  bool is_vertex_minimum(std::uint32_t v, const Vec3& d) const;
  Vec3 contact_normal(std::uint32_t t, const Vec3& p, const Vec3& q, double dist) const;
};

// Loads a mesh file (STL, OBJ, PLY, ... through assimp), scales it to metres,
// welds vertices. Throws std::runtime_error naming the file on failure.
std::shared_ptr<const TriMesh> load_mesh(const std::string& path, double scale);

using Shape = std::variant<Plane, Box, Cylinder, std::shared_ptr<const TriMesh>>;

// Closest surface point of a shape within max_distance of p (local frame).
// Appends 0..n hits to out (n > 1 only for meshes).
void query(const Shape& shape, const Vec3& p, double max_distance,
           std::vector<SurfaceHit>& out);

// Local-frame bounding box; planes are unbounded (returns an infinite box).
Aabb local_bounds(const Shape& shape);

}  // namespace ces::geo
