#include "mesh.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <tuple>
#include <unordered_map>

#include "common/hash.hpp"

namespace ces::exporter {
namespace {

using Cell = std::array<std::int64_t, 3>;

struct CellHash {
  std::size_t operator()(const Cell& c) const {
    // Lookup only (never iterated), so the hash cannot change any output.
    std::uint64_t h = 0;
    for (std::int64_t v : c) h = splitmix64(h ^ std::uint64_t(v));
    return std::size_t(h);
  }
};

// Maps every vertex to the first earlier vertex within `tolerance`, found
// through a grid of cells `tolerance` wide (the 27 cells around a point hold
// every candidate).
std::vector<std::uint32_t> weld(Mesh& mesh, double tolerance, std::size_t& merged) {
  std::unordered_map<Cell, std::vector<std::uint32_t>, CellHash> grid;
  std::vector<Vec3> kept;
  std::vector<std::uint32_t> remap(mesh.vertices.size());
  const double tol2 = tolerance * tolerance;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3& p = mesh.vertices[i];
    const Cell c{std::int64_t(std::floor(p.x() / tolerance)),
                 std::int64_t(std::floor(p.y() / tolerance)),
                 std::int64_t(std::floor(p.z() / tolerance))};
    std::int64_t found = -1;
    for (int dx = -1; dx <= 1 && found < 0; ++dx)
      for (int dy = -1; dy <= 1 && found < 0; ++dy)
        for (int dz = -1; dz <= 1 && found < 0; ++dz) {
          const auto it = grid.find({c[0] + dx, c[1] + dy, c[2] + dz});
          if (it == grid.end()) continue;
          for (std::uint32_t k : it->second)
            if ((kept[k] - p).squaredNorm() <= tol2) {
              found = k;
              break;
            }
        }
    if (found < 0) {
      found = std::int64_t(kept.size());
      grid[c].push_back(std::uint32_t(found));
      kept.push_back(p);
    }
    remap[i] = std::uint32_t(found);
  }
  merged = mesh.vertices.size() - kept.size();
  mesh.vertices = std::move(kept);
  return remap;
}

// The core's test (geometry/mesh.cpp): no usable normal, no surface.
bool degenerate(const Mesh& m, const std::array<std::uint32_t, 3>& t) {
  if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) return true;
  const Vec3& a = m.vertices[t[0]];
  const Vec3& b = m.vertices[t[1]];
  const Vec3& c = m.vertices[t[2]];
  const double longest2 =
      std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  return !((b - a).cross(c - a).norm() > 1e-12 * longest2);
}

std::size_t remove_degenerate(Mesh& mesh, const std::vector<std::uint32_t>& remap) {
  std::vector<std::array<std::uint32_t, 3>> kept;
  kept.reserve(mesh.triangles.size());
  for (auto t : mesh.triangles) {
    for (auto& v : t) v = remap[v];
    if (!degenerate(mesh, t)) kept.push_back(t);
  }
  const std::size_t removed = mesh.triangles.size() - kept.size();
  mesh.triangles = std::move(kept);
  return removed;
}

// Drops vertices no triangle uses (corners of removed triangles).
void drop_unused_vertices(Mesh& mesh) {
  std::vector<std::int64_t> index(mesh.vertices.size(), -1);
  std::vector<Vec3> kept;
  for (auto& t : mesh.triangles)
    for (auto& v : t) {
      if (index[v] < 0) {
        index[v] = std::int64_t(kept.size());
        kept.push_back(mesh.vertices[v]);
      }
      v = std::uint32_t(index[v]);
    }
  mesh.vertices = std::move(kept);
}

// One use of an undirected edge: the triangle, and whether it runs low to
// high vertex index.
struct EdgeUse {
  std::uint32_t low, high, triangle;
  bool forward;
};

// Edge uses sorted by edge, so the uses of one edge are adjacent.
std::vector<EdgeUse> edge_uses(const Mesh& mesh) {
  std::vector<EdgeUse> uses;
  uses.reserve(3 * mesh.triangles.size());
  for (std::uint32_t t = 0; t < mesh.triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = mesh.triangles[t][k], b = mesh.triangles[t][(k + 1) % 3];
      uses.push_back({std::min(a, b), std::max(a, b), t, a < b});
    }
  std::sort(uses.begin(), uses.end(), [](const EdgeUse& x, const EdgeUse& y) {
    return std::tie(x.low, x.high, x.triangle) < std::tie(y.low, y.high, y.triangle);
  });
  return uses;
}

// Neighbours across manifold edges, with whether the two triangles run the
// shared edge the same way (then one of them must be rewound).
struct Link {
  std::uint32_t other;
  bool same_direction;
};

std::vector<std::vector<Link>> count_edges(const std::vector<EdgeUse>& uses, std::size_t triangles,
                                           MeshQuality& q, std::vector<bool>& on_bad_edge) {
  std::vector<std::vector<Link>> links(triangles);
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    while (j < uses.size() && uses[j].low == uses[i].low && uses[j].high == uses[i].high) ++j;
    const std::size_t n = j - i;
    if (n == 2) {
      const bool same = uses[i].forward == uses[i + 1].forward;
      links[uses[i].triangle].push_back({uses[i + 1].triangle, same});
      links[uses[i + 1].triangle].push_back({uses[i].triangle, same});
    } else {
      (n == 1 ? q.open_edges : q.non_manifold_edges)++;
      for (std::size_t k = i; k < j; ++k) on_bad_edge[uses[k].triangle] = true;
    }
    i = j;
  }
  return links;
}

double signed_volume(const Mesh& m, const std::vector<std::uint32_t>& piece,
                     const std::vector<bool>& flip) {
  double v = 0.0;
  for (std::uint32_t t : piece) {
    const auto& tri = m.triangles[t];
    const Vec3& a = m.vertices[tri[0]];
    const Vec3& b = m.vertices[tri[flip[t] ? 2 : 1]];
    const Vec3& c = m.vertices[tri[flip[t] ? 1 : 2]];
    v += a.dot(b.cross(c));
  }
  return v / 6.0;
}

// Breadth-first over manifold edges from `seed`: the piece's triangles, each
// with the flip that makes it agree with the seed.
std::vector<std::uint32_t> grow_piece(std::uint32_t seed,
                                      const std::vector<std::vector<Link>>& links,
                                      std::vector<bool>& visited, std::vector<bool>& flip,
                                      std::size_t& conflicts) {
  std::vector<std::uint32_t> piece{seed};
  visited[seed] = true;
  for (std::size_t head = 0; head < piece.size(); ++head) {
    const std::uint32_t t = piece[head];
    for (const Link& l : links[t]) {
      const bool wanted = flip[t] != l.same_direction;
      if (!visited[l.other]) {
        visited[l.other] = true;
        flip[l.other] = wanted;
        piece.push_back(l.other);
      } else if (flip[l.other] != wanted && t < l.other) {
        ++conflicts;  // a Moebius-like piece: counted once per edge
      }
    }
  }
  return piece;
}

// Chooses the winding of one piece: outward if it is closed, else the one
// that rewinds fewer triangles.
void settle_piece(const Mesh& m, const std::vector<std::uint32_t>& piece, bool closed,
                  std::vector<bool>& flip) {
  std::size_t flipped = 0;
  for (std::uint32_t t : piece) flipped += flip[t];
  const bool invert = closed ? signed_volume(m, piece, flip) < 0.0 : 2 * flipped > piece.size();
  if (invert)
    for (std::uint32_t t : piece) flip[t] = !flip[t];
}

void orient(Mesh& mesh, MeshQuality& q) {
  const std::size_t n = mesh.triangles.size();
  std::vector<bool> on_bad_edge(n, false), visited(n, false), flip(n, false);
  const auto links = count_edges(edge_uses(mesh), n, q, on_bad_edge);
  for (std::uint32_t seed = 0; seed < n; ++seed) {
    if (visited[seed]) continue;
    std::size_t conflicts = 0;
    const auto piece = grow_piece(seed, links, visited, flip, conflicts);
    const bool closed =
        conflicts == 0 && std::none_of(piece.begin(), piece.end(),
                                       [&](std::uint32_t t) { return bool(on_bad_edge[t]); });
    settle_piece(mesh, piece, closed, flip);
    q.orientation_conflicts += conflicts;
    ++q.pieces;
    q.closed_pieces += closed;
  }
  for (std::size_t t = 0; t < n; ++t)
    if (flip[t]) {
      std::swap(mesh.triangles[t][1], mesh.triangles[t][2]);
      ++q.flipped_triangles;
    }
}

}  // namespace

nlohmann::ordered_json vec_json(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

Bounds Mesh::bounds() const {
  Bounds b;
  for (const Vec3& v : vertices) b.add(v);
  return b;
}

Vec3 Mesh::normal(std::size_t t) const {
  const auto& tri = triangles[t];
  const Vec3 n = (vertices[tri[1]] - vertices[tri[0]]).cross(vertices[tri[2]] - vertices[tri[0]]);
  const double len = n.norm();
  return len > 0.0 ? Vec3(n / len) : Vec3::Zero();
}

double Mesh::area(std::size_t t) const {
  const auto& tri = triangles[t];
  return 0.5 *
         (vertices[tri[1]] - vertices[tri[0]]).cross(vertices[tri[2]] - vertices[tri[0]]).norm();
}

void Mesh::append(const Mesh& other, double scale) {
  const auto base = std::uint32_t(vertices.size());
  for (const Vec3& v : other.vertices) vertices.push_back(scale * v);
  for (const auto& t : other.triangles)
    triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
}

nlohmann::ordered_json MeshQuality::to_json() const {
  return {{"triangles", triangles},
          {"vertices", vertices},
          {"input_triangles", input_triangles},
          {"merged_vertices", merged_vertices},
          {"degenerate_triangles", degenerate_triangles},
          {"open_edges", open_edges},
          {"non_manifold_edges", non_manifold_edges},
          {"flipped_triangles", flipped_triangles},
          {"orientation_conflicts", orientation_conflicts},
          {"pieces", pieces},
          {"closed_pieces", closed_pieces},
          {"bounding_box", {{"min", vec_json(bounds.min)}, {"max", vec_json(bounds.max)}}}};
}

double weld_tolerance(const Mesh& mesh) {
  const Bounds b = mesh.bounds();
  return b.empty() ? 1e-12 : std::max(1e-6 * b.size().norm(), 1e-12);
}

MeshQuality clean(Mesh& mesh, double tolerance) {
  MeshQuality q;
  q.input_triangles = mesh.triangles.size();
  const auto remap = weld(mesh, tolerance, q.merged_vertices);
  q.degenerate_triangles = remove_degenerate(mesh, remap);
  drop_unused_vertices(mesh);
  orient(mesh, q);
  q.triangles = mesh.triangles.size();
  q.vertices = mesh.vertices.size();
  q.bounds = mesh.bounds();
  return q;
}

void write_binary_stl(const Mesh& mesh, const std::filesystem::path& path,
                      const std::string& header) {
  std::ofstream out(path, std::ios::binary);
  char head[80] = {};
  std::memcpy(head, header.data(), std::min<std::size_t>(header.size(), sizeof head));
  out.write(head, sizeof head);
  const auto count = std::uint32_t(mesh.triangles.size());
  out.write(reinterpret_cast<const char*>(&count), 4);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    float record[12];
    const Vec3 n = mesh.normal(t);
    for (int k = 0; k < 3; ++k) record[k] = float(n[k]);
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k)
        record[3 + 3 * c + k] = float(mesh.vertices[mesh.triangles[t][c]][k]);
    out.write(reinterpret_cast<const char*>(record), sizeof record);
    const std::uint16_t attributes = 0;
    out.write(reinterpret_cast<const char*>(&attributes), 2);
  }
  if (!out)
    throw std::filesystem::filesystem_error("cannot write", path,
                                            std::make_error_code(std::errc::io_error));
}

}  // namespace ces::exporter
