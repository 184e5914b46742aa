// Geometry queries: analytic shapes against hand-computed values, meshes
// against boxes and brute force, mesh loading and its failures.
#include <gtest/gtest.h>
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <set>

#include "collision/broadphase.hpp"
#include "collision/contacts.hpp"
#include "common/isolate.hpp"
#include "geometry/shapes.hpp"

namespace ces::geo {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::vector<SurfaceHit> hits(const Shape& shape, const Vec3& p, double max_distance = kInf) {
  std::vector<SurfaceHit> out;
  query(shape, p, max_distance, out);
  return out;
}

// The one hit a shape reports for p; fails the test if there is not exactly one.
SurfaceHit only_hit(const Shape& shape, const Vec3& p) {
  const std::vector<SurfaceHit> out = hits(shape, p);
  EXPECT_EQ(out.size(), 1u) << "at " << p.transpose();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return out.empty() ? SurfaceHit{Vec3::Constant(nan), Vec3::Constant(nan), nan, ~0u} : out[0];
}

void expect_hit(const SurfaceHit& hit, const Vec3& point, const Vec3& normal, double distance,
                double tolerance) {
  EXPECT_NEAR(hit.distance, distance, tolerance);
  EXPECT_LE((hit.point - point).norm(), tolerance) << hit.point.transpose();
  EXPECT_LE((hit.normal - normal).norm(), tolerance) << hit.normal.transpose();
}

std::uint32_t tag(std::uint32_t feature) { return feature >> 30; }

// ---------------------------------------------------------------- plane

// Tolerance 1e-15: one dot product and one subtraction of O(1) numbers.
TEST(GeometryPlane, SignedDistanceOnBothSides) {
  const Plane plane{Vec3::UnitY(), 0.5};
  expect_hit(only_hit(plane, Vec3(1, 2, 3)), Vec3(1, 0.5, 3), Vec3::UnitY(), 1.5, 1e-15);
  expect_hit(only_hit(plane, Vec3(1, 0, 3)), Vec3(1, 0.5, 3), Vec3::UnitY(), -0.5, 1e-15);
  EXPECT_EQ(only_hit(plane, Vec3(1, 0, 3)).feature, 0u);

  const Plane tilted{Vec3(1, 1, 0).normalized(), 0.0};
  expect_hit(only_hit(tilted, Vec3(1, 1, 5)), Vec3(0, 0, 5), tilted.normal, std::sqrt(2.0), 1e-15);
}

// Exact: the filter compares the computed distance with max_distance.
TEST(GeometryPlane, MaxDistanceFilters) {
  const Plane plane{Vec3::UnitZ(), 0.0};
  EXPECT_TRUE(hits(plane, Vec3(0, 0, 2), 1.0).empty());
  EXPECT_EQ(hits(plane, Vec3(0, 0, 1), 1.0).size(), 1u);      // at the limit: kept
  EXPECT_EQ(hits(plane, Vec3(0, 0, -0.5), -0.1).size(), 1u);  // penetration within a negative limit
}

// ---------------------------------------------------------------- box

const Box kBox{Vec3(1, 2, 3)};

// Tolerance 1e-15: inside distances are one subtraction of O(1) numbers.
TEST(GeometryBox, InsidePointsUseNearestFace) {
  expect_hit(only_hit(kBox, Vec3(0.5, 1.9, 0)), Vec3(0.5, 2, 0), Vec3::UnitY(), -0.1, 1e-15);
  EXPECT_EQ(only_hit(kBox, Vec3(0.5, 1.9, 0)).feature, 3u);
  expect_hit(only_hit(kBox, Vec3(0, 0, -2.8)), Vec3(0, 0, -3), -Vec3::UnitZ(), -0.2, 1e-15);
  // The centre is closest to the x faces; the + face wins the tie.
  expect_hit(only_hit(kBox, Vec3::Zero()), Vec3(1, 0, 0), Vec3::UnitX(), -1.0, 1e-15);
  expect_hit(only_hit(kBox, Vec3(1, 0.5, 0.5)), Vec3(1, 0.5, 0.5), Vec3::UnitX(), 0.0, 0.0);
}

// Tolerance 1e-15: hand-computed sqrt(2) and sqrt(3) agree to an ulp.
TEST(GeometryBox, OutsideFaceEdgeCorner) {
  expect_hit(only_hit(kBox, Vec3(3, 0.5, -1)), Vec3(1, 0.5, -1), Vec3::UnitX(), 2.0, 1e-15);
  expect_hit(only_hit(kBox, Vec3(2, 3, 0)), Vec3(1, 2, 0), Vec3(1, 1, 0) / std::sqrt(2.0),
             std::sqrt(2.0), 1e-15);
  expect_hit(only_hit(kBox, Vec3(-2, -3, -4)), Vec3(-1, -2, -3), -Vec3(1, 1, 1) / std::sqrt(3.0),
             std::sqrt(3.0), 1e-15);
  EXPECT_EQ(only_hit(kBox, Vec3(3, 0.5, -1)).feature, 1u);
  EXPECT_EQ(only_hit(kBox, Vec3(2, 3, 0)).feature, 1u + 3u);
  EXPECT_EQ(only_hit(kBox, Vec3(-2, -3, -4)).feature, 2u + 6u + 18u);
}

// Exact: feature ids are integers.
TEST(GeometryBox, FeatureIdsAreDistinctAndMatchInsideFaces) {
  std::set<std::uint32_t> ids;
  for (int x = -1; x <= 1; ++x) {
    for (int y = -1; y <= 1; ++y) {
      for (int z = -1; z <= 1; ++z) {
        if (x == 0 && y == 0 && z == 0) continue;
        ids.insert(only_hit(kBox, Vec3(2 * x, 3 * y, 4 * z)).feature);
      }
    }
  }
  EXPECT_EQ(ids.size(), 26u);
  EXPECT_EQ(*ids.begin(), 1u);
  EXPECT_EQ(*ids.rbegin(), 26u);
  // A point just inside a face and one just outside it name the same face.
  EXPECT_EQ(only_hit(kBox, Vec3(0, -1.99, 0)).feature, only_hit(kBox, Vec3(0, -2.01, 0)).feature);
}

// ---------------------------------------------------------------- cylinder

const Cylinder kSolid{0.5, 1.0, 0.0};
const Cylinder kShell{0.5, 1.0, 0.1};  // inner radius 0.4

// Tolerance 1e-15 for faces (one subtraction each), 1e-14 for rims (hypot
// of two rounded differences, then a division for the normal).
TEST(GeometryCylinder, SolidLateralCapsAndRims) {
  SurfaceHit hit = only_hit(kSolid, Vec3(0, 0.8, 0.3));
  expect_hit(hit, Vec3(0, 0.5, 0.3), Vec3::UnitY(), 0.3, 1e-15);
  EXPECT_EQ(hit.feature, kCylOuter);
  expect_hit(only_hit(kSolid, Vec3(0.6, 0.8, 0)), Vec3(0.3, 0.4, 0), Vec3(0.6, 0.8, 0), 0.5, 1e-15);

  hit = only_hit(kSolid, Vec3(0.1, 0.2, 1.5));
  expect_hit(hit, Vec3(0.1, 0.2, 1), Vec3::UnitZ(), 0.5, 1e-15);
  EXPECT_EQ(hit.feature, kCylTop);
  hit = only_hit(kSolid, Vec3(0.1, -0.2, -1.25));
  expect_hit(hit, Vec3(0.1, -0.2, -1), -Vec3::UnitZ(), 0.25, 1e-15);
  EXPECT_EQ(hit.feature, kCylBottom);

  hit = only_hit(kSolid, Vec3(0, -0.9, 1.3));  // (d_rho, d_z) = (0.4, 0.3)
  expect_hit(hit, Vec3(0, -0.5, 1), Vec3(0, -0.8, 0.6), 0.5, 1e-14);
  EXPECT_EQ(hit.feature, kCylOuterTop);
  hit = only_hit(kSolid, Vec3(0.6, 0, -1.4));  // (0.1, -0.4)
  expect_hit(hit, Vec3(0.5, 0, -1), Vec3(0.1, 0, -0.4) / std::sqrt(0.17), std::sqrt(0.17), 1e-14);
  EXPECT_EQ(hit.feature, kCylOuterBottom);
}

// Tolerance 1e-15: one subtraction per side.
TEST(GeometryCylinder, SolidInsidePoints) {
  SurfaceHit hit = only_hit(kSolid, Vec3(0.3, 0, 0.9));  // cap 0.1 away, side 0.2
  expect_hit(hit, Vec3(0.3, 0, 1), Vec3::UnitZ(), -0.1, 1e-15);
  EXPECT_EQ(hit.feature, kCylTop);
  hit = only_hit(kSolid, Vec3(0, 0.45, 0));
  expect_hit(hit, Vec3(0, 0.5, 0), Vec3::UnitY(), -0.05, 1e-15);
  EXPECT_EQ(hit.feature, kCylOuter);
  // On the axis every radial direction is equally close; +x is the fixed choice.
  expect_hit(only_hit(kSolid, Vec3::Zero()), Vec3(0.5, 0, 0), Vec3::UnitX(), -0.5, 0.0);
}

// Tolerance 1e-15 for faces, 1e-14 for rims (see above).
TEST(GeometryCylinder, ShellHollowWallAndRims) {
  // Inside the hollow: the inner surface, normal pointing at the axis.
  SurfaceHit hit = only_hit(kShell, Vec3(0.1, 0, 0.2));
  expect_hit(hit, Vec3(0.4, 0, 0.2), -Vec3::UnitX(), 0.3, 1e-15);
  EXPECT_EQ(hit.feature, kCylInner);
  expect_hit(only_hit(kShell, Vec3::Zero()), Vec3(0.4, 0, 0), -Vec3::UnitX(), 0.4, 1e-15);

  // Inside the wall: nearest of outer, inner and end faces.
  expect_hit(only_hit(kShell, Vec3(0.47, 0, 0)), Vec3(0.5, 0, 0), Vec3::UnitX(), -0.03, 1e-15);
  hit = only_hit(kShell, Vec3(0, -0.42, 0.5));
  expect_hit(hit, Vec3(0, -0.4, 0.5), Vec3::UnitY(), -0.02, 1e-15);
  EXPECT_EQ(hit.feature, kCylInner);
  expect_hit(only_hit(kShell, Vec3(0.45, 0, 0.99)), Vec3(0.45, 0, 1), Vec3::UnitZ(), -0.01, 1e-15);

  // Annular end face and the four rims.
  hit = only_hit(kShell, Vec3(0.45, 0, 1.2));
  expect_hit(hit, Vec3(0.45, 0, 1), Vec3::UnitZ(), 0.2, 1e-15);
  EXPECT_EQ(hit.feature, kCylTop);
  hit = only_hit(kShell, Vec3(0.3, 0, 1.1));
  expect_hit(hit, Vec3(0.4, 0, 1), Vec3(-1, 0, 1) / std::sqrt(2.0), std::sqrt(0.02), 1e-14);
  EXPECT_EQ(hit.feature, kCylInnerTop);
  hit = only_hit(kShell, Vec3(0, 0, -1.3));  // on the axis: rim point on +x
  expect_hit(hit, Vec3(0.4, 0, -1), Vec3(-0.8, 0, -0.6), 0.5, 1e-14);
  EXPECT_EQ(hit.feature, kCylInnerBottom);
  hit = only_hit(kShell, Vec3(0.6, 0, 1.1));
  expect_hit(hit, Vec3(0.5, 0, 1), Vec3(1, 0, 1) / std::sqrt(2.0), std::sqrt(0.02), 1e-14);
  EXPECT_EQ(hit.feature, kCylOuterTop);
  hit = only_hit(kShell, Vec3(0, 0.8, -1.4));
  expect_hit(hit, Vec3(0, 0.5, -1), Vec3(0, 0.6, -0.8), 0.5, 1e-14);
  EXPECT_EQ(hit.feature, kCylOuterBottom);
}

// A 0.1 mm sphere 1 nm from a 0.16 m drum. Tolerance 1e-15, a few ulps of
// 0.16: only possible without squared differences of large numbers.
TEST(GeometryCylinder, PrecisionAtDrumScale) {
  const Cylinder drum{0.16, 0.1, 0.0};
  const double rho = 0.16 + 0.0001 + 1e-9;
  const double expected = 0.0001 + 1e-9;
  EXPECT_NEAR(only_hit(drum, Vec3(rho, 0, 0.05)).distance, expected, 1e-15);
  EXPECT_NEAR(only_hit(drum, Vec3(rho, 0, 0.05)).distance - 1e-4, 1e-9, 1e-15);  // the gap
  EXPECT_NEAR(only_hit(drum, Vec3(0.16 + 1.0001e-4 + 1e-9, 0, 0)).distance, 1.0001e-4 + 1e-9,
              1e-15);
  const double angle = 0.7;  // hypot costs at most an ulp off the axes
  const Vec3 p(rho * std::cos(angle), rho * std::sin(angle), -0.02);
  EXPECT_NEAR(only_hit(drum, p).distance, expected, 1e-15);

  // Particles inside a shell drum ride on its inner surface.
  const Cylinder shell{0.16, 0.1, 0.005};
  const SurfaceHit hit = only_hit(shell, Vec3(0, -(0.155 - 0.0001 - 1e-9), 0));
  EXPECT_NEAR(hit.distance, expected, 1e-15);
  EXPECT_EQ(hit.feature, kCylInner);
  EXPECT_LE((hit.normal - Vec3::UnitY()).norm(), 1e-15);
}

// ---------------------------------------------------------------- bounds

// Exact: bounds are copies of the shape parameters.
TEST(GeometryBounds, ShapesAndAabbHelpers) {
  const Aabb plane = local_bounds(Plane{});
  EXPECT_TRUE((plane.min.array() == -kInf).all() && (plane.max.array() == kInf).all());
  const Aabb box = local_bounds(kBox);
  EXPECT_EQ(box.min, Vec3(-1, -2, -3));
  EXPECT_EQ(box.max, Vec3(1, 2, 3));
  const Aabb cyl = local_bounds(kShell);
  EXPECT_EQ(cyl.min, Vec3(-0.5, -0.5, -1));
  EXPECT_EQ(cyl.max, Vec3(0.5, 0.5, 1));
  EXPECT_TRUE(plane.overlaps(box));

  Aabb a = Aabb::empty();
  EXPECT_FALSE(a.overlaps(box));
  a.grow(Vec3(2, 0, 0));
  a.grow(Vec3(3, 1, -1));
  EXPECT_EQ(a.min, Vec3(2, 0, -1));
  EXPECT_EQ(a.max, Vec3(3, 1, 0));
  EXPECT_FALSE(a.overlaps(box));
  EXPECT_TRUE(a.inflated(1.0).overlaps(box));  // touching counts
  Aabb b = Aabb::empty();
  b.grow(a);
  EXPECT_EQ(b.min, a.min);
  EXPECT_EQ(b.max, a.max);
}

// ---------------------------------------------------------------- meshes

// A fresh directory per test and process, removed afterwards: ctest runs
// tests in parallel processes, so fixed file names would race.
class ScratchDir {
 public:
  ScratchDir()
      : path_(std::filesystem::path(::testing::TempDir()) /
              ("ces_geometry_" +
               std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
               std::to_string(::getpid()))) {
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::string path() const { return path_.string(); }

 private:
  std::filesystem::path path_;
};

// Unit cube [-0.5, 0.5]^3 as an ASCII STL, outward counter-clockwise facets.
std::string write_cube_stl(const ScratchDir& dir) {
  const auto corner = [](int i) {
    return Vec3(i & 1 ? 0.5 : -0.5, i & 2 ? 0.5 : -0.5, i & 4 ? 0.5 : -0.5);
  };
  const int quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  const std::string path = dir.file("cube.stl");
  std::ofstream stl(path);
  stl << "solid cube\n";
  for (const auto& q : quads) {
    for (const auto& tri : {std::array{q[0], q[1], q[2]}, std::array{q[0], q[2], q[3]}}) {
      stl << " facet normal 0 0 0\n  outer loop\n";
      for (const int i : tri) {
        const Vec3 v = corner(i);
        stl << "   vertex " << v.x() << ' ' << v.y() << ' ' << v.z() << '\n';
      }
      stl << "  endloop\n endfacet\n";
    }
  }
  stl << "endsolid cube\n";
  return path;
}

// Tolerance 1e-12: mesh edges and faces are recomputed from float-exact
// corners, so they agree with Box to rounding.
TEST(GeometryMesh, LoadedCubeMatchesBoxOutside) {
  const ScratchDir dir;
  const auto mesh = load_mesh(write_cube_stl(dir), 1.0);
  EXPECT_EQ(mesh->vertices().size(), 8u);
  EXPECT_EQ(mesh->triangles().size(), 12u);
  EXPECT_EQ(mesh->bounds().min, Vec3::Constant(-0.5));
  EXPECT_EQ(mesh->bounds().max, Vec3::Constant(0.5));

  const Box box{Vec3::Constant(0.5)};
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> coord(-1.2, 1.2);
  int tested = 0;
  while (tested < 2000) {
    const Vec3 p(coord(rng), coord(rng), coord(rng));
    if (p.cwiseAbs().maxCoeff() <= 0.5) continue;
    const SurfaceHit expected = only_hit(box, p);
    if (expected.distance >= 0.5) continue;  // beyond: opposite faces also qualify
    ++tested;
    // Within the limit only the nearest region qualifies: exactly one hit.
    const std::vector<SurfaceHit> got = hits(mesh, p, expected.distance + 1e-9);
    ASSERT_EQ(got.size(), 1u) << p.transpose();
    expect_hit(got[0], expected.point, expected.normal, expected.distance, 1e-12);
    // Box faces, edges and corners map to mesh faces, edges and vertices.
    const int box_digits =
        (expected.feature % 3 != 0) + (expected.feature / 3 % 3 != 0) + (expected.feature / 9 != 0);
    EXPECT_EQ(tag(got[0].feature), static_cast<std::uint32_t>(box_digits - 1)) << p.transpose();
  }
}

// Tolerance 1e-15: scaling multiplies float-exact coordinates by 1e-3.
TEST(GeometryMesh, LoadAppliesScale) {
  const ScratchDir dir;
  const auto mesh = load_mesh(write_cube_stl(dir), 1e-3);
  EXPECT_NEAR(mesh->bounds().max.x(), 5e-4, 1e-15);
  const std::shared_ptr<const TriMesh> shape = mesh;
  const std::vector<SurfaceHit> out = hits(shape, Vec3(0, 0, 1e-3), 1e-3);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_NEAR(out[0].distance, 5e-4, 1e-15);
  EXPECT_EQ(local_bounds(shape).min, mesh->bounds().min);
}

std::string load_error(const std::string& path, double scale = 1.0) {
  try {
    load_mesh(path, scale);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no exception";
}

void write_file(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

TEST(GeometryMesh, LoadFailuresNameTheFile) {
  const ScratchDir dir;
  const std::string missing = dir.file("missing.stl");
  EXPECT_EQ(load_error(missing).rfind(missing + ": ", 0), 0u) << load_error(missing);

  std::mt19937 rng(7);
  std::string garbage(4096, '\0');
  for (char& c : garbage) c = static_cast<char>(rng());
  for (const std::string name : {"garbage.stl", "garbage.obj", "garbage.ply", "garbage.xyz"}) {
    const std::string path = dir.file(name);
    write_file(path, garbage);
    EXPECT_EQ(load_error(path).rfind(path + ": ", 0), 0u) << load_error(path);
  }
  const std::string text = dir.file("text.obj");
  write_file(text, "this is not\na mesh at all\n");
  EXPECT_EQ(load_error(text).rfind(text + ": ", 0), 0u) << load_error(text);
  const std::string empty = dir.file("empty.stl");
  write_file(empty, "");
  EXPECT_EQ(load_error(empty).rfind(empty + ": ", 0), 0u) << load_error(empty);
  const std::string folder = dir.path();
  EXPECT_EQ(load_error(folder).rfind(folder + ": ", 0), 0u) << load_error(folder);
  const std::string cube = write_cube_stl(dir);
  EXPECT_EQ(load_error(cube, 0.0).rfind(cube + ": ", 0), 0u) << load_error(cube, 0.0);
}

// Files made to stop the reader or exhaust the process: a PLY whose header
// promises more than it holds (assimp asserts), and headers of a few bytes
// promising half a billion vertices, refused on the file's size before the
// reader would allocate them. Each is an error naming the file, not a
// crash, at once; a PLY that holds what it promises loads.
TEST(GeometryMesh, HostileHeadersAreErrorsNotCrashes) {
  const ScratchDir dir;
  auto ply = [&](const std::string& name, const std::string& vertices, const std::string& body) {
    const std::string path = dir.file(name);
    write_file(path, "ply\nformat ascii 1.0\nelement vertex " + vertices +
                         "\nproperty float x\nproperty float y\nproperty float z\nelement face "
                         "4\nproperty list uchar int vertex_indices\nend_header\n" +
                         body);
    return path;
  };
  const std::string short_of = ply("short.ply", "4", "0 0 0\n");
  EXPECT_NE(load_error(short_of).find(short_of + ": its reader stopped"), std::string::npos)
      << load_error(short_of);
  const std::string bomb = ply("bomb.ply", "500000000", "0 0 0\n");
  EXPECT_NE(load_error(bomb).find(bomb + ": its header promises elements of at least 3e+09 bytes"),
            std::string::npos)
      << load_error(bomb);
  const std::string off = dir.file("bomb.off");
  write_file(off, "OFF\n500000000 1 0\n0 0 0\n");
  EXPECT_NE(load_error(off).find(off + ": its header promises"), std::string::npos)
      << load_error(off);
  const std::string tetrahedron = ply(
      "tetrahedron.ply", "4", "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
  EXPECT_EQ(load_error(tetrahedron), "no exception");
}

// What ends the child of run_isolated comes back as an error saying what:
// its exception's message, an abort, memory past its limit.
TEST(Isolation, WhatEndsTheChildIsSaid) {
  const IsolationLimits limits{1.0 * (1 << 30), 10.0};
  EXPECT_EQ(run_isolated([] { return std::string("done"); }, limits), "done");
  auto error = [&](const std::function<std::string()>& work) -> std::string {
    try {
      run_isolated(work, limits);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "no exception";
  };
  EXPECT_EQ(error([]() -> std::string { throw std::runtime_error("bad row"); }), "bad row");
  EXPECT_NE(error([]() -> std::string { std::abort(); }).find("stopped (Aborted)"),
            std::string::npos);
#if !defined(__SANITIZE_ADDRESS__)
  EXPECT_NE(error([] {
              return std::string(std::size_t(4) << 30, 'x');
            }).find("it needs more memory than the 1 GiB"),
            std::string::npos);
#endif
}

// (n+1)^2 grid vertices spanning [0, n]^2 at z = 0, mapped by `place`; each
// cell is split along alternating diagonals so vertices have 4 or 8 triangles.
template <class Place>
std::shared_ptr<const TriMesh> grid_mesh(int n, Place place) {
  std::vector<Vec3> vertices;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) vertices.push_back(place(Vec3(i, j, 0)));
  }
  std::vector<std::array<std::uint32_t, 3>> triangles;
  const auto id = [n](int i, int j) { return static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const std::uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      if ((i + j) % 2 == 0) {
        triangles.push_back({a, b, c});
        triangles.push_back({a, c, d});
      } else {
        triangles.push_back({a, b, d});
        triangles.push_back({b, c, d});
      }
    }
  }
  return std::make_shared<const TriMesh>(std::move(vertices), std::move(triangles));
}

// Vertices, edge midpoints and points a hair away from them, over the
// interior of a 4x4 grid, in grid coordinates.
std::vector<Vec3> feature_points() {
  std::vector<Vec3> points;
  for (double y = 0.5; y <= 3.5; y += 0.5) {
    for (double x = 0.5; x <= 3.5; x += 0.5) {
      for (const double e : {0.0, 1e-9, -1e-6, 1e-3}) points.push_back(Vec3(x + e, y - 0.5 * e, 0));
    }
  }
  return points;
}

// Exact grid: tolerance 1e-15 (distances are the height itself).
TEST(GeometryMesh, FlatGridGivesOneHitOverSharedVerticesAndEdges) {
  const auto mesh = grid_mesh(4, [](const Vec3& v) { return v; });
  for (const Vec3& g : feature_points()) {
    for (const double h : {0.3, -0.05}) {
      const Vec3 p = g + h * Vec3::UnitZ();
      const std::vector<SurfaceHit> out = hits(mesh, p, 1.0);
      ASSERT_EQ(out.size(), 1u) << p.transpose();
      expect_hit(out[0], g, std::copysign(1.0, h) * Vec3::UnitZ(), std::abs(h), 1e-15);
    }
  }
  // Exactly over vertex (2, 2): every incident triangle reports the vertex.
  EXPECT_EQ(only_hit(mesh, Vec3(2, 2, 0.3)).feature, TriMesh::kMeshVertex | 12u);
  // On the surface the stored face normal (+z for this winding) is used.
  expect_hit(only_hit(mesh, Vec3(1.3, 2.6, 0)), Vec3(1.3, 2.6, 0), Vec3::UnitZ(), 0.0, 0.0);
  expect_hit(only_hit(mesh, Vec3(2, 2, 0)), Vec3(2, 2, 0), Vec3::UnitZ(), 0.0, 0.0);
}

// Tilted, off-origin grid with inexact coordinates: rounding scatters a point
// over a vertex among face, edge and vertex regions of its triangles, and it
// must still give one hit. Tolerance 1e-12 (rounding of 0.1-scale values).
TEST(GeometryMesh, TiltedGridGivesOneHitDespiteRounding) {
  const Quat rotation = rotation_from_z(Vec3(0.3, -0.2, 1.0).normalized());
  const Vec3 origin(0.0123, -0.037, 0.2);
  const auto place = [&](const Vec3& g) { return Vec3(origin + rotation * (0.1 * g)); };
  const auto mesh = grid_mesh(4, place);
  const Vec3 up = rotation * Vec3::UnitZ();
  for (const Vec3& g : feature_points()) {
    for (const double h : {0.03, -0.001}) {
      const Vec3 p = place(g) + h * up;
      const std::vector<SurfaceHit> out = hits(mesh, p, 0.05);
      ASSERT_EQ(out.size(), 1u) << g.transpose();
      expect_hit(out[0], place(g), std::copysign(1.0, h) * up, std::abs(h), 1e-12);
      const std::vector<SurfaceHit> again = hits(mesh, p, 0.05);
      EXPECT_EQ(again[0].feature, out[0].feature);  // deterministic
    }
  }
}

// Two unit-square wings meeting along the y axis at z = 0, their far edges at
// z = wing_z: a ridge for wing_z < 0, a valley for wing_z > 0.
std::shared_ptr<const TriMesh> fold(double wing_z) {
  std::vector<Vec3> v = {{0, -1, 0},      {0, 1, 0},       {-1, -1, wing_z},
                         {-1, 1, wing_z}, {1, -1, wing_z}, {1, 1, wing_z}};
  return std::make_shared<const TriMesh>(
      std::move(v),
      std::vector<std::array<std::uint32_t, 3>>{{0, 2, 3}, {0, 3, 1}, {0, 1, 5}, {0, 5, 4}});
}

// Tolerance 1e-15: projections onto 45-degree planes.
TEST(GeometryMesh, RidgeGivesOneEdgeHitValleyGivesTwoFaceHits) {
  const SurfaceHit ridge = only_hit(fold(-1.0), Vec3(0, 0.3, 0.5));
  expect_hit(ridge, Vec3(0, 0.3, 0), Vec3::UnitZ(), 0.5, 1e-15);
  EXPECT_EQ(tag(ridge.feature), 1u);

  const std::vector<SurfaceHit> valley = hits(fold(1.0), Vec3(0, 0.3, 0.5));
  ASSERT_EQ(valley.size(), 2u);
  const double d = 0.5 / std::sqrt(2.0);
  expect_hit(valley[0], Vec3(-0.25, 0.3, 0.25), Vec3(1, 0, 1) / std::sqrt(2.0), d, 1e-15);
  expect_hit(valley[1], Vec3(0.25, 0.3, 0.25), Vec3(-1, 0, 1) / std::sqrt(2.0), d, 1e-15);
  EXPECT_LT(valley[0].feature, valley[1].feature);
}

// Independent reference: project onto the plane, else the nearest edge.
Vec3 closest_on_segment(const Vec3& a, const Vec3& b, const Vec3& p) {
  const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
  return a + t * (b - a);
}

Vec3 closest_on_triangle(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& p) {
  const Vec3 n = (b - a).cross(c - a);
  const Vec3 q = p - (p - a).dot(n) / n.squaredNorm() * n;
  if ((b - a).cross(q - a).dot(n) >= 0 && (c - b).cross(q - b).dot(n) >= 0 &&
      (a - c).cross(q - c).dot(n) >= 0) {
    return q;
  }
  Vec3 best = closest_on_segment(a, b, p);
  for (const Vec3& e : {closest_on_segment(b, c, p), closest_on_segment(c, a, p)}) {
    if ((p - e).squaredNorm() < (p - best).squaredNorm()) best = e;
  }
  return best;
}

std::vector<double> brute_force_distances(const TriMesh& mesh, const Vec3& p) {
  std::vector<double> d;
  for (const auto& t : mesh.triangles()) {
    const auto& v = mesh.vertices();
    d.push_back((p - closest_on_triangle(v[t[0]], v[t[1]], v[t[2]], p)).norm());
  }
  return d;
}

// Unconnected triangles: each one within reach is its own contact, so the
// BVH must return exactly the brute-force set. Tolerance 1e-12 (two
// closest-point formulations on O(1) coordinates).
TEST(GeometryMesh, BvhMatchesBruteForceOnTriangleSoup) {
  std::mt19937_64 rng(1234);
  std::uniform_real_distribution<double> unit(0.0, 1.0), jitter(-0.05, 0.05);
  std::vector<Vec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  for (std::uint32_t t = 0; t < 500; ++t) {
    const Vec3 centre(unit(rng), unit(rng), unit(rng));
    for (int k = 0; k < 3; ++k)
      vertices.push_back(centre + Vec3(jitter(rng), jitter(rng), jitter(rng)));
    triangles.push_back({3 * t, 3 * t + 1, 3 * t + 2});
  }
  const auto mesh = std::make_shared<const TriMesh>(vertices, triangles);
  const double reach = 0.06;
  std::uniform_real_distribution<double> coord(-0.1, 1.1);
  std::size_t total = 0;
  for (int i = 0; i < 500; ++i) {
    const Vec3 p(coord(rng), coord(rng), coord(rng));
    std::vector<double> expected;
    for (const double d : brute_force_distances(*mesh, p)) {
      if (d <= reach) expected.push_back(d);
    }
    std::sort(expected.begin(), expected.end());
    std::vector<double> got;
    for (const SurfaceHit& h : hits(mesh, p, reach)) {
      got.push_back(h.distance);
      EXPECT_NEAR((p - h.point).norm(), h.distance, 1e-12);
      EXPECT_NEAR(h.normal.norm(), 1.0, 1e-12);
    }
    std::sort(got.begin(), got.end());
    ASSERT_EQ(got.size(), expected.size()) << p.transpose();
    for (std::size_t k = 0; k < got.size(); ++k) EXPECT_NEAR(got[k], expected[k], 1e-12);
    total += got.size();
  }
  EXPECT_GT(total, 100u);  // the test exercised real hits
}

// Welded, bumpy surface: the nearest hit equals the brute-force minimum, no
// hit is nearer than it, and hits come sorted by unique feature id.
// Tolerance 1e-12 as above.
TEST(GeometryMesh, BvhMatchesBruteForceOnWeldedSurface) {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> bump(0.0, 0.3);
  const auto mesh =
      grid_mesh(15, [&](const Vec3& g) { return Vec3(g.x() / 15, g.y() / 15, bump(rng)); });
  const double reach = 0.2;
  std::uniform_real_distribution<double> coord(-0.2, 1.2), height(-0.4, 0.7);
  for (int i = 0; i < 1000; ++i) {
    const Vec3 p(coord(rng), coord(rng), height(rng));
    const std::vector<double> all = brute_force_distances(*mesh, p);
    const double nearest = *std::min_element(all.begin(), all.end());
    const std::vector<SurfaceHit> out = hits(mesh, p, reach);
    if (nearest > reach) {
      EXPECT_TRUE(out.empty());
      continue;
    }
    ASSERT_FALSE(out.empty()) << p.transpose();
    double got = kInf;
    for (std::size_t k = 0; k < out.size(); ++k) {
      got = std::min(got, out[k].distance);
      EXPECT_LE(out[k].distance, reach);
      if (k > 0) {
        EXPECT_LT(out[k - 1].feature, out[k].feature);
      }
    }
    EXPECT_NEAR(got, nearest, 1e-12) << p.transpose();
  }
}

// Exact: bookkeeping only.
TEST(GeometryMesh, DegenerateTrianglesAreIgnoredAndBadIndicesRejected) {
  const auto mesh = std::make_shared<const TriMesh>(
      std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}},
      std::vector<std::array<std::uint32_t, 3>>{{0, 1, 3}, {0, 1, 2}, {2, 2, 1}});
  const std::vector<SurfaceHit> out = hits(mesh, Vec3(1.5, 0, 1), 10.0);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].point, Vec3(1, 0, 0));  // vertex of the only real triangle
  EXPECT_EQ(mesh->bounds().max, Vec3(1, 1, 0));

  EXPECT_THROW(TriMesh({{0, 0, 0}}, {{0, 0, 1}}), std::invalid_argument);
  EXPECT_TRUE(hits(std::shared_ptr<const TriMesh>(), Vec3::Zero()).empty());
}

}  // namespace
}  // namespace ces::geo

// The grid broadphase against every pair tested directly, on a random cloud
// of mixed radii (so cells hold several particles and pairs cross cell
// faces, edges and corners), part of it below the grid's origin: the same
// pairs, in (i, j) order. Three times, so later calls reuse the buffers;
// the third cloud is two clusters 1 m apart, in alternate particles, so the
// sweep's cursors jump across the empty space between them. On 1, 2 and 3
// threads: the entries are sorted in one piece per thread and merged in
// pairs, and three pieces leave one unpaired in the first round.
TEST(GridBroadphase, FindsExactlyTheOverlappingPairsInOrder) {
  using ces::GridBroadphase, ces::Vec3;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-0.02, 0.03), rad(0.0005, 0.002);
  GridBroadphase grid;
  for (int round = 0; round < 3; ++round) {
    const std::size_t n = round == 1 ? 1500 : 3000;
    std::vector<Vec3> c(n);
    std::vector<double> r(n);
    for (std::size_t i = 0; i < n; ++i) {
      c[i] = Vec3(pos(rng), pos(rng), pos(rng));
      if (round == 2 && i % 2 == 1) c[i] += Vec3(1.0, -1.0, 0.5);
      r[i] = rad(rng);
    }
    std::vector<std::pair<std::int32_t, std::int32_t>> found, expected;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j)
        if ((c[i] - c[j]).squaredNorm() < (r[i] + r[j]) * (r[i] + r[j]))
          expected.emplace_back(std::int32_t(i), std::int32_t(j));
    EXPECT_GT(expected.size(), n / 10);  // a dense enough cloud to test something
    for (const int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      grid.find_pairs(c, r, found);
      EXPECT_EQ(found, expected) << threads << " threads";
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

// The contact memory against std::map: random keys (many sharing particle
// ids, as a clump's contacts do), stored in random order, then every stored
// key and as many absent ones looked up, with and without a cursor. Three
// rounds on one table, of 20000, 50000 and 300 keys: nothing of an earlier
// round may be found.
TEST(ContactMemory, FindsWhatWasStoredAndNothingElse) {
  using ces::ContactKey, ces::ContactMemory, ces::Vec3;
  std::mt19937 rng(11);
  std::uniform_int_distribution<std::uint64_t> id(0, 300);
  std::uniform_int_distribution<std::uint32_t> feature(0, 18);
  auto random_key = [&] {
    const bool body = feature(rng) == 0;
    return ContactKey{body ? ces::kBodyTag | (id(rng) % 4) : id(rng), id(rng), feature(rng),
                      feature(rng)};
  };
  ContactMemory memory;
  std::vector<ContactKey> earlier;
  for (const std::size_t n : {20000u, 50000u, 300u}) {
    std::map<ContactKey, Vec3> expected;
    std::vector<ContactKey> keys;
    std::vector<Vec3> values;
    while (keys.size() < n) {  // distinct keys, as the collider's
      const ContactKey key = random_key();
      const Vec3 value(double(keys.size()), -double(keys.size()), 0.5);
      if (!expected.emplace(key, value).second) continue;
      keys.push_back(key);
      values.push_back(value);
    }
    std::vector<Vec3> given = values;
    memory.assign(keys, given);  // swapped in: given holds the last round's values
    EXPECT_EQ(given.size(), earlier.size());
    EXPECT_EQ(memory.size(), n);
    // With a cursor, in the order stored: it moves one key at a time, and
    // the hash table is not needed.
    std::size_t cursor = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3* found = memory.find(keys[i], cursor);
      ASSERT_NE(found, nullptr);
      EXPECT_EQ(*found, values[i]);
      EXPECT_EQ(cursor, i + 1);
    }
    // From the wrong place, on two threads at once (the first miss builds
    // the table): by the hash, and the cursor moves past the key found.
    std::vector<std::size_t> wrong(n, n);
#pragma omp parallel for num_threads(2)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) {
      std::size_t c = (std::size_t(i) + 7) % n;
      const Vec3* found = memory.find(keys[std::size_t(i)], c);
      wrong[std::size_t(i)] = found && *found == values[std::size_t(i)] ? c : n + 1;
    }
    for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(wrong[i], i + 1) << i;
    for (const auto& [key, value] : expected) {
      const Vec3* found = memory.find(key);
      ASSERT_NE(found, nullptr);
      EXPECT_EQ(*found, value);
    }
    std::size_t absent = 0;
    for (const ContactKey& key : earlier) {
      if (expected.count(key)) continue;
      std::size_t cursor = 0;
      EXPECT_EQ(memory.find(key), nullptr);
      EXPECT_EQ(memory.find(key, cursor), nullptr);
      ++absent;
    }
    if (!earlier.empty()) {
      EXPECT_GT(absent, 100u);
    }
    earlier.clear();
    for (const auto& entry : expected) earlier.push_back(entry.first);
  }
}

// The hash table built on the threads (ContactMemory::index) finds what a
// lookup from the wrong place finds, and of a repeated key the value stored
// first, as a table filled in order would: 40,000 keys of which every
// fifth repeats an earlier one, on 1 and 3 threads.
TEST(ContactMemory, TableBuiltOnThreadsFindsTheFirstOfARepeatedKey) {
  using ces::ContactKey, ces::ContactMemory, ces::Vec3;
  std::vector<ContactKey> keys;
  std::vector<Vec3> values;
  for (std::uint32_t k = 0; k < 40000; ++k) {
    const std::uint32_t source = k % 5 == 4 ? k / 2 : k;  // a repeat of an earlier key
    keys.push_back({source % 301, source / 301, source % 19, source % 7});
    values.emplace_back(double(k), 0.0, 0.0);
  }
  for (const int threads : {1, 3}) {
    omp_set_num_threads(threads);
    ContactMemory memory;
    std::vector<Vec3> given = values;
    memory.assign(keys, given);
    memory.index();
    std::map<ContactKey, std::size_t> first;  // each key's first stored copy
    for (std::size_t k = 0; k < keys.size(); ++k) first.emplace(keys[k], k);
    ASSERT_LT(first.size(), keys.size());
    for (std::size_t k = 0; k < keys.size(); ++k) {
      const Vec3* found = memory.find(keys[k]);
      ASSERT_NE(found, nullptr) << k;
      ASSERT_EQ(found->x(), double(first.at(keys[k]))) << k << ", " << threads << " threads";
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}
