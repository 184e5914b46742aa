// Triangle soups from CAD made into meshes the simulator can trust: welded
// vertices, no degenerate triangles, one winding per connected piece
// (outward on closed pieces), and a report of what was found.
#pragma once
#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/math.hpp"

namespace ces::exporter {

struct Bounds {
  Vec3 min = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 max = Vec3::Constant(-std::numeric_limits<double>::infinity());

  void add(const Vec3& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  void add(const Bounds& b) {
    min = min.cwiseMin(b.min);
    max = max.cwiseMax(b.max);
  }
  bool empty() const { return !(min.array() <= max.array()).all(); }
  Vec3 size() const { return max - min; }
  Vec3 center() const { return 0.5 * (min + max); }
};

struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;

  Bounds bounds() const;
  Vec3 normal(std::size_t t) const;  // unit, from the winding
  double area(std::size_t t) const;
  // Appends `other`, moved by `scale` (units to metres).
  void append(const Mesh& other, double scale = 1.0);
};

// What cleaning found; the counts describe the mesh as written.
struct MeshQuality {
  std::size_t input_triangles = 0;
  std::size_t triangles = 0;
  std::size_t vertices = 0;
  std::size_t merged_vertices = 0;        // welded into another vertex
  std::size_t degenerate_triangles = 0;   // removed: zero area or repeated corners
  std::size_t open_edges = 0;             // used by one triangle
  std::size_t non_manifold_edges = 0;     // used by three or more
  std::size_t flipped_triangles = 0;      // rewound to agree with their neighbours
  std::size_t orientation_conflicts = 0;  // edges no winding can make consistent
  std::size_t pieces = 0;                 // edge-connected components
  std::size_t closed_pieces = 0;          // without open or non-manifold edges
  Bounds bounds;

  nlohmann::ordered_json to_json() const;
};

// A vector as the JSON array [x, y, z] of the export report.
nlohmann::ordered_json vec_json(const Vec3& v);

// Welds vertices closer than `tolerance` (m), drops degenerate triangles,
// winds every piece consistently across its shared edges, and turns closed
// pieces outward (positive signed volume).
MeshQuality clean(Mesh& mesh, double tolerance);

// The default weld tolerance for a mesh: 1e-6 of its bounding-box diagonal,
// far below any CAD tolerance and far above rounding of coordinates.
double weld_tolerance(const Mesh& mesh);

// Binary STL (float coordinates, normals from the winding). Throws
// std::filesystem::filesystem_error when the file cannot be written.
void write_binary_stl(const Mesh& mesh, const std::filesystem::path& path,
                      const std::string& header);

}  // namespace ces::exporter
