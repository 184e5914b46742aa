// Triangle meshes: BVH, closest-feature queries with one hit per contact
// region, and loading through assimp.
#include "geometry/shapes.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <new>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>

#include "common/isolate.hpp"
#include "common/serial.hpp"
#include "geometry/mesh_header.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

namespace ces::geo {
namespace {

constexpr std::uint32_t kLeafSize = 4;
// Median splits halve the triangle count, so depth <= 30 for 2^30 triangles;
// a depth-first walk holds at most depth + 1 nodes.
constexpr std::size_t kStackSize = 64;

// Voronoi region of a query point with respect to one triangle.
struct Region {
  enum Kind { kFace, kEdge, kVertex } kind;
  int index;  // edge k joins corners k and k + 1; vertex k is corner k
};

// A segment parameter of exactly 0 or 1 is the endpoint: report the vertex so
// the vertex's (stricter) neighbourhood test decides.
Region on_edge(int edge, int start, double to_start, int end, double to_end) {
  if (to_start == 0.0) return {Region::kVertex, start};
  if (to_end == 0.0) return {Region::kVertex, end};
  return {Region::kEdge, edge};
}

// Region tests of Ericson, Real-Time Collision Detection 5.1.5. Only the
// region is returned: points are rebuilt per feature so that every triangle
// sharing an edge or vertex produces bit-identical hits.
Region classify(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& p) {
  const Vec3 ab = b - a;
  const Vec3 ac = c - a;
  const Vec3 ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return {Region::kVertex, 0};

  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return {Region::kVertex, 1};

  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return on_edge(0, 0, d1, 1, d3);

  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return {Region::kVertex, 2};

  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return on_edge(2, 0, d2, 2, d6);

  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) return on_edge(1, 1, d4 - d3, 2, d5 - d6);
  return {Region::kFace, 0};
}

// Zero area, or a sliver whose height is rounding noise next to its longest
// edge: such a triangle has no usable normal and adds no surface.
bool is_degenerate(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double longest2 =
      std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  return !((b - a).cross(c - a).norm() > 1e-12 * longest2);
}

double squared_distance(const Aabb& box, const Vec3& p) {
  return (box.min - p).cwiseMax(p - box.max).cwiseMax(0.0).squaredNorm();
}

// Several triangles can report the same contact: a shared edge or vertex
// (same feature id), or a point over a shared vertex of a flat patch where
// rounding puts it in a different region of each triangle (same point).
// Sorted by id, faces come first, so the face hit with the lowest id wins.
void keep_one_hit_per_region(std::vector<SurfaceHit>& out, std::size_t first, double tolerance) {
  const auto begin = out.begin() + static_cast<std::ptrdiff_t>(first);
  std::sort(begin, out.end(),
            [](const SurfaceHit& a, const SurfaceHit& b) { return a.feature < b.feature; });
  const double tolerance2 = tolerance * tolerance;
  auto kept = begin;
  for (auto it = begin; it != out.end(); ++it) {
    const bool duplicate = std::any_of(begin, kept, [&](const SurfaceHit& k) {
      return k.feature == it->feature || (k.point - it->point).squaredNorm() <= tolerance2;
    });
    if (!duplicate) *kept++ = *it;
  }
  out.erase(kept, out.end());
}

}  // namespace

TriMesh::TriMesh(std::vector<Vec3> vertices, std::vector<std::array<std::uint32_t, 3>> triangles)
    : vertices_(std::move(vertices)), triangles_(std::move(triangles)) {
  if (vertices_.size() > kMaxIndex || triangles_.size() > kMaxIndex) {
    throw std::invalid_argument("TriMesh: too many vertices or triangles");
  }
  for (const Vec3& v : vertices_) {
    if (!v.allFinite()) throw std::invalid_argument("TriMesh: non-finite vertex");
  }
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    for (const std::uint32_t v : triangles_[t]) {
      if (v >= vertices_.size()) {
        throw std::invalid_argument("TriMesh: triangle " + std::to_string(t) +
                                    " references missing vertex " + std::to_string(v));
      }
    }
  }
  build();
}

void TriMesh::build() {
  const std::size_t n = triangles_.size();
  normals_.assign(n, Vec3::Zero());
  order_.clear();
  root_bounds_ = Aabb::empty();
  std::vector<Aabb> boxes(n, Aabb::empty());
  std::vector<Vec3> centroids(n, Vec3::Zero());
  for (std::uint32_t t = 0; t < n; ++t) {
    const Vec3& a = vertices_[triangles_[t][0]];
    const Vec3& b = vertices_[triangles_[t][1]];
    const Vec3& c = vertices_[triangles_[t][2]];
    if (is_degenerate(a, b, c)) continue;
    normals_[t] = (b - a).cross(c - a).normalized();
    for (const Vec3* v : {&a, &b, &c}) boxes[t].grow(*v);
    centroids[t] = (a + b + c) / 3.0;
    root_bounds_.grow(boxes[t]);
    order_.push_back(t);
  }
  // Rounding of coordinates scales with their magnitude, not only with the
  // mesh's size, so a mesh far from its origin gets a matching tolerance.
  if (!order_.empty()) {
    const double extent =
        std::max({(root_bounds_.max - root_bounds_.min).norm(),
                  root_bounds_.min.cwiseAbs().maxCoeff(), root_bounds_.max.cwiseAbs().maxCoeff()});
    tolerance_ = 1e-12 * extent;
  }
  build_adjacency();

  nodes_.clear();
  if (order_.empty()) return;
  struct Task {
    std::uint32_t node, begin, end;
  };
  std::vector<Task> tasks = {{0, 0, static_cast<std::uint32_t>(order_.size())}};
  nodes_.push_back({Aabb::empty(), 0, 0});
  while (!tasks.empty()) {
    const Task task = tasks.back();
    tasks.pop_back();
    Aabb box = Aabb::empty();
    Aabb centroid_box = Aabb::empty();
    for (std::uint32_t i = task.begin; i < task.end; ++i) {
      box.grow(boxes[order_[i]]);
      centroid_box.grow(centroids[order_[i]]);
    }
    if (task.end - task.begin <= kLeafSize) {
      nodes_[task.node] = {box, task.begin, task.end - task.begin};
      continue;
    }
    Eigen::Index axis = 0;
    (centroid_box.max - centroid_box.min).maxCoeff(&axis);
    // Median split by count keeps the tree balanced even when centroids
    // coincide; the index tie-break makes the partition deterministic.
    const std::uint32_t mid = task.begin + (task.end - task.begin) / 2;
    std::nth_element(order_.begin() + task.begin, order_.begin() + mid, order_.begin() + task.end,
                     [&](std::uint32_t a, std::uint32_t b) {
                       const double ca = centroids[a][axis];
                       const double cb = centroids[b][axis];
                       return ca < cb || (ca == cb && a < b);
                     });
    const auto left = static_cast<std::uint32_t>(nodes_.size());
    nodes_[task.node] = {box, left, 0};
    nodes_.push_back({Aabb::empty(), 0, 0});
    nodes_.push_back({Aabb::empty(), 0, 0});
    tasks.push_back({left + 1, mid, task.end});
    tasks.push_back({left, task.begin, mid});
  }
}

// Edge ids are ranks of sorted vertex pairs, so they depend only on the
// mesh, never on query order. Adjacency lists are in triangle order, which
// makes "the first incident triangle" the lowest-indexed one.
void TriMesh::build_adjacency() {
  struct EdgeRef {
    std::uint32_t lo, hi, triangle, slot;
  };
  std::vector<EdgeRef> refs;
  refs.reserve(3 * order_.size());
  for (const std::uint32_t t : order_) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const auto [lo, hi] = std::minmax(triangles_[t][k], triangles_[t][(k + 1) % 3]);
      refs.push_back({lo, hi, t, k});
    }
  }
  std::sort(refs.begin(), refs.end(), [](const EdgeRef& a, const EdgeRef& b) {
    return std::tie(a.lo, a.hi, a.triangle) < std::tie(b.lo, b.hi, b.triangle);
  });
  tri_edges_.assign(triangles_.size(), {0, 0, 0});
  edges_.clear();
  edge_start_.clear();
  edge_tris_.clear();
  for (std::uint32_t i = 0; i < refs.size(); ++i) {
    if (i == 0 || refs[i].lo != refs[i - 1].lo || refs[i].hi != refs[i - 1].hi) {
      edges_.push_back({refs[i].lo, refs[i].hi});
      edge_start_.push_back(i);
    }
    edge_tris_.push_back(refs[i].triangle);
    tri_edges_[refs[i].triangle][refs[i].slot] = static_cast<std::uint32_t>(edges_.size() - 1);
  }
  edge_start_.push_back(static_cast<std::uint32_t>(refs.size()));
  if (edges_.size() > kMaxIndex) throw std::invalid_argument("TriMesh: too many edges");

  // Counting sort of (vertex, triangle) pairs; order_ is ascending.
  vertex_start_.assign(vertices_.size() + 1, 0);
  for (const std::uint32_t t : order_) {
    for (const std::uint32_t v : triangles_[t]) ++vertex_start_[v + 1];
  }
  std::partial_sum(vertex_start_.begin(), vertex_start_.end(), vertex_start_.begin());
  vertex_tris_.resize(vertex_start_.back());
  std::vector<std::uint32_t> cursor(vertex_start_.begin(), vertex_start_.end() - 1);
  for (const std::uint32_t t : order_) {
    for (const std::uint32_t v : triangles_[t]) vertex_tris_[cursor[v]++] = t;
  }
}

void TriMesh::query(const Vec3& p, double max_distance, std::vector<SurfaceHit>& out) const {
  if (nodes_.empty() || !(max_distance >= 0.0)) return;
  // Boxes are culled on squared distances; the slack absorbs their rounding
  // so a triangle exactly at max_distance reaches the exact test.
  const double reach2 = max_distance * max_distance * (1.0 + 1e-12);
  const std::size_t first = out.size();
  std::array<std::uint32_t, kStackSize> stack;
  std::size_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (squared_distance(node.box, p) > reach2) continue;
    if (node.count > 0) {
      for (std::uint32_t i = 0; i < node.count; ++i) {
        query_triangle(order_[node.first + i], p, max_distance, out);
      }
    } else {
      stack[top++] = node.first + 1;
      stack[top++] = node.first;
    }
  }
  keep_one_hit_per_region(out, first, tolerance_);
}

void TriMesh::query_triangle(std::uint32_t t, const Vec3& p, double max_distance,
                             std::vector<SurfaceHit>& out) const {
  const auto& tri = triangles_[t];
  const Region region = classify(vertices_[tri[0]], vertices_[tri[1]], vertices_[tri[2]], p);
  switch (region.kind) {
    case Region::kFace: {
      // Projection along the unit normal: one dot product, no cancellation.
      const Vec3& n = normals_[t];
      const double s = n.dot(p - vertices_[tri[0]]);
      if (std::abs(s) > max_distance) return;
      out.push_back({p - s * n, s < 0.0 ? Vec3(-n) : n, std::abs(s), t});
      return;
    }
    case Region::kEdge: {
      const std::uint32_t e = tri_edges_[t][region.index];
      const Vec3& lo = vertices_[edges_[e][0]];
      const Vec3 axis = vertices_[edges_[e][1]] - lo;
      const double u = std::clamp((p - lo).dot(axis) / axis.squaredNorm(), 0.0, 1.0);
      const Vec3 q = lo + u * axis;
      const double distance = (p - q).norm();
      if (distance > max_distance || !is_edge_minimum(e, p - q)) return;
      const Vec3 normal = contact_normal(edge_tris_[edge_start_[e]], p, q, distance);
      out.push_back({q, normal, distance, kMeshEdge | e});
      return;
    }
    case Region::kVertex: {
      const std::uint32_t v = tri[region.index];
      const Vec3& q = vertices_[v];
      const double distance = (p - q).norm();
      if (distance > max_distance || !is_vertex_minimum(v, p - q)) return;
      const Vec3 normal = contact_normal(vertex_tris_[vertex_start_[v]], p, q, distance);
      out.push_back({q, normal, distance, kMeshVertex | v});
      return;
    }
  }
}

// A point on an edge is a separate contact only if no incident triangle gets
// closer to p when moving off the edge into it; otherwise that triangle's own
// (face) hit is the contact. d = p - q. The slack is half the coincidence
// radius: anything that passes lies within it of the neighbour's own hit,
// so keep_one_hit_per_region merges the pair instead of keeping both.
bool TriMesh::is_edge_minimum(std::uint32_t e, const Vec3& d) const {
  const Vec3& lo = vertices_[edges_[e][0]];
  const Vec3 axis = vertices_[edges_[e][1]] - lo;
  for (std::uint32_t i = edge_start_[e]; i < edge_start_[e + 1]; ++i) {
    const std::uint32_t t = edge_tris_[i];
    const int slot = static_cast<int>(std::find(tri_edges_[t].begin(), tri_edges_[t].end(), e) -
                                      tri_edges_[t].begin());
    const Vec3 w = vertices_[triangles_[t][(slot + 2) % 3]] - lo;
    const Vec3 inward = w - (w.dot(axis) / axis.squaredNorm()) * axis;
    if (d.dot(inward) > 0.5 * tolerance_ * inward.norm()) return false;
  }
  return true;
}

// Likewise for a vertex: every incident triangle is the cone spanned by its
// two edges at v, so checking those edge directions suffices.
bool TriMesh::is_vertex_minimum(std::uint32_t v, const Vec3& d) const {
  for (std::uint32_t i = vertex_start_[v]; i < vertex_start_[v + 1]; ++i) {
    for (const std::uint32_t w : triangles_[vertex_tris_[i]]) {
      if (w == v) continue;
      const Vec3 edge = vertices_[w] - vertices_[v];
      if (d.dot(edge) > 0.5 * tolerance_ * edge.norm()) return false;
    }
  }
  return true;
}

// Away from the surface the normal is the direction to p. On it that
// direction is noise, so use the face normal of triangle t, flipped to p's side.
Vec3 TriMesh::contact_normal(std::uint32_t t, const Vec3& p, const Vec3& q, double distance) const {
  if (distance > tolerance_) return (p - q) / distance;
  const Vec3& n = normals_[t];
  return n.dot(p - q) < 0.0 ? Vec3(-n) : n;
}

namespace {

struct RawMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

RawMesh read_scene(const std::string& path, double scale) {
  Assimp::Importer importer;
  const aiScene* scene =
      importer.ReadFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                  aiProcess_PreTransformVertices | aiProcess_ValidateDataStructure);
  if (scene == nullptr) {
    // assimp catches what it throws and keeps its text: memory runs out
    // on a header's counts, which the caller says in its own words.
    const std::string error = importer.GetErrorString();
    if (error == "std::bad_alloc") throw std::bad_alloc();
    throw std::runtime_error(error);
  }
  RawMesh raw;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh& mesh = *scene->mMeshes[m];
    const auto base = static_cast<std::uint64_t>(raw.vertices.size());
    if (base + mesh.mNumVertices > TriMesh::kMaxIndex) {
      throw std::runtime_error("too many vertices");
    }
    for (unsigned i = 0; i < mesh.mNumVertices; ++i) {
      const aiVector3D& v = mesh.mVertices[i];
      const Vec3 x = scale * Vec3(v.x, v.y, v.z);
      if (!x.allFinite()) throw std::runtime_error("non-finite vertex coordinate");
      raw.vertices.push_back(x);
    }
    // Points and lines survive triangulation as 1- and 2-index faces: skip.
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      if (face.mNumIndices != 3) continue;
      std::array<std::uint32_t, 3> tri{};
      for (int k = 0; k < 3; ++k) {
        if (face.mIndices[k] >= mesh.mNumVertices) {
          throw std::runtime_error("vertex index out of range");
        }
        tri[k] = static_cast<std::uint32_t>(base + face.mIndices[k]);
      }
      raw.triangles.push_back(tri);
    }
  }
  return raw;
}

// A mesh as bytes, and back.
std::string to_bytes(const RawMesh& m) {
  ByteWriter out;
  out.values(m.vertices);
  out.values(m.triangles);
  return std::move(out).take();
}

RawMesh from_bytes(const std::string& bytes) {
  ByteReader in(bytes);
  RawMesh m;
  in.values(m.vertices);
  in.values(m.triangles);
  if (!in.at_end()) throw std::runtime_error("its reader's result is not the size it says");
  return m;
}

// assimp reads in a child process: a file made to stop it (an assertion
// on counts a header promises and the data lacks) or to exhaust it ends
// the child, not the run, and the error names the file.
RawMesh read_isolated(const std::string& path, double scale) {
  return from_bytes(
      run_isolated([&] { return to_bytes(read_scene(path, scale)); }, reader_limits(path)));
}

// Exact weld: assimp welds within each mesh, this also welds across meshes.
// Identical coordinates map to the lowest index holding them; the sort keeps
// the result independent of anything but the data.
std::vector<std::uint32_t> weld(const std::vector<Vec3>& vertices) {
  std::vector<std::uint32_t> sorted(vertices.size());
  std::iota(sorted.begin(), sorted.end(), 0u);
  const auto key = [&](std::uint32_t i) {
    return std::tie(vertices[i].x(), vertices[i].y(), vertices[i].z());
  };
  std::sort(sorted.begin(), sorted.end(), [&](std::uint32_t a, std::uint32_t b) {
    return key(a) < key(b) || (key(a) == key(b) && a < b);
  });
  std::vector<std::uint32_t> rep(vertices.size());
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    const bool same = i > 0 && key(sorted[i]) == key(sorted[i - 1]);
    rep[sorted[i]] = same ? rep[sorted[i - 1]] : sorted[i];
  }
  return rep;
}

// Welds, drops degenerate triangles and keeps only referenced vertices,
// numbered in order of first use.
RawMesh clean(const RawMesh& raw) {
  const std::vector<std::uint32_t> rep = weld(raw.vertices);
  constexpr std::uint32_t kUnused = ~0u;
  std::vector<std::uint32_t> index(raw.vertices.size(), kUnused);
  RawMesh mesh;
  for (const auto& tri : raw.triangles) {
    const std::array<std::uint32_t, 3> w = {rep[tri[0]], rep[tri[1]], rep[tri[2]]};
    if (is_degenerate(raw.vertices[w[0]], raw.vertices[w[1]], raw.vertices[w[2]])) continue;
    std::array<std::uint32_t, 3> out{};
    for (int k = 0; k < 3; ++k) {
      if (index[w[k]] == kUnused) {
        index[w[k]] = static_cast<std::uint32_t>(mesh.vertices.size());
        mesh.vertices.push_back(raw.vertices[w[k]]);
      }
      out[k] = index[w[k]];
    }
    mesh.triangles.push_back(out);
  }
  return mesh;
}

}  // namespace

std::shared_ptr<const TriMesh> load_mesh(const std::string& path, double scale) {
  try {
    if (!(scale > 0.0) || !std::isfinite(scale)) {
      throw std::runtime_error("scale must be positive and finite");
    }
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) {
      throw std::runtime_error(std::filesystem::exists(path, ec) ? "not a regular file"
                                                                 : "no such file");
    }
    if (const std::string promised = promised_beyond_size(path); !promised.empty())
      throw std::runtime_error(promised);
    RawMesh mesh = clean(read_isolated(path, scale));
    if (mesh.triangles.empty()) throw std::runtime_error("no non-degenerate triangles");
    return std::make_shared<const TriMesh>(std::move(mesh.vertices), std::move(mesh.triangles));
  } catch (const std::exception& e) {
    // One place names the file, whatever failed: reader, checks or TriMesh.
    throw std::runtime_error(path + ": " + e.what());
  }
}

}  // namespace ces::geo
