// The exporter's geometry: mesh cleaning (welding, degenerate triangles,
// winding) and the primitives recovered from triangles (oriented boxes at any
// tilt, cylinders along any axis), measured against what is not one.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "export_support.hpp"
#include "fit.hpp"
#include "mesh.hpp"

namespace {

using namespace ces::exporter;
using namespace ces::export_test;
using ces::kPi;
using ces::Vec3;

Mesh soup(const std::vector<Triangle>& triangles) {
  Mesh m;
  for (const Triangle& t : triangles) {
    const auto base = std::uint32_t(m.vertices.size());
    for (const Vec3& v : t) m.vertices.push_back(v);
    m.triangles.push_back({base, base + 1, base + 2});
  }
  return m;
}

double signed_volume(const Mesh& m) {
  double v = 0;
  for (const auto& t : m.triangles)
    v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]])) / 6;
  return v;
}

TEST(ExportMesh, WeldsDropsDegenerateAndOrientsOutward) {
  std::vector<Triangle> t = box({0, 0, 0}, {1, 2, 3});
  for (Triangle& tri : t) std::swap(tri[1], tri[2]);           // all inward...
  std::swap(t[4][1], t[4][2]);                                 // ...but one
  t.push_back({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)});  // zero area
  Mesh m = soup(t);
  const MeshQuality q = clean(m, 1e-9);
  EXPECT_EQ(q.vertices, 8u);
  EXPECT_EQ(q.merged_vertices, 39u - 9u);  // (2, 0, 0) stays until its triangle goes
  EXPECT_EQ(q.degenerate_triangles, 1u);
  EXPECT_EQ(q.triangles, 12u);
  EXPECT_EQ(q.open_edges + q.non_manifold_edges + q.orientation_conflicts, 0u);
  EXPECT_EQ(q.closed_pieces, 1u);
  EXPECT_EQ(q.flipped_triangles, 11u);
  EXPECT_NEAR(signed_volume(m), 6.0, 1e-12);
}

TEST(ExportMesh, CountsOpenAndNonManifoldEdges) {
  Mesh sheet = soup({{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)},
                     {Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}});
  const MeshQuality open = clean(sheet, 1e-9);
  EXPECT_EQ(open.open_edges, 4u);
  EXPECT_EQ(open.flipped_triangles, 1u);  // the second ran the shared edge the same way
  EXPECT_EQ(open.closed_pieces, 0u);
  Mesh fin = soup({{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)},
                   {Vec3(1, 0, 0), Vec3(0, 0, 0), Vec3(0, -1, 0)},
                   {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)}});
  EXPECT_EQ(clean(fin, 1e-9).non_manifold_edges, 1u);
}

// A part as CAD exports it to STL: float coordinates in mm (here 700 mm
// from the origin, where a float is off by up to 3e-5 mm), read as metres.
Mesh stl_part(std::vector<Triangle> t, const Eigen::AngleAxisd& turn,
              const Vec3& at = Vec3(737.7, 659.1, -120.0)) {
  for (Triangle& tri : t)
    for (Vec3& v : tri) v = 1e-3 * (turn * v + at).cast<float>().cast<double>();
  Mesh m = soup(t);
  clean(m, weld_tolerance(m));
  return m;
}

// The fitted box is the box of `size` (mm) turned by `turn` about `at`:
// each of its edges along a column of the frame, with its length, to 1 um.
void expect_box(const BoxFit& f, const Vec3& size, const Eigen::AngleAxisd& turn,
                const Vec3& at = Vec3(737.7, 659.1, -120.0)) {
  EXPECT_TRUE(f.within(kBoxTolerance))
      << f.volume_error << " " << f.face_error << " " << f.other_area;
  // Float coordinates, not the shape: up to 3e-5 mm on each side of a 3 mm
  // plate is 2e-5 of its thickness.
  EXPECT_LT(f.volume_error, 3e-5);
  EXPECT_LT(f.face_error, 3e-5);
  EXPECT_LT(f.other_area, 1e-12);
  EXPECT_LT((f.box.center - 1e-3 * at).norm(), 1e-6);
  EXPECT_NEAR(f.box.frame.determinant(), 1.0, 1e-12);
  const ces::Mat3 r = turn.toRotationMatrix();
  for (int k = 0; k < 3; ++k) {
    Eigen::Index j = 0;
    (f.box.frame.transpose() * r.col(k)).cwiseAbs().maxCoeff(&j);
    EXPECT_GT(std::abs(f.box.frame.col(j).dot(r.col(k))), 1.0 - 1e-9) << "edge " << k;
    EXPECT_NEAR(f.box.size[j], 1e-3 * size[k], 1e-6) << "edge " << k;
  }
}

// The reference machine's second splitter is tilted 27 degrees; a user's
// -20. Plates, a square plate (two faces alike: the normals' principal axes
// leave a plane) and a cube (all alike) at many tilts, about z and about
// oblique axes.
TEST(ExportFit, BoxesAtAnyTiltAreBoxes) {
  const std::vector<Vec3> sizes = {{4, 150, 300}, {3, 120, 100}, {4, 150, 150}, {50, 50, 50}};
  const std::vector<Eigen::AngleAxisd> turns = {{0.0, Vec3::UnitZ()},
                                                {-20 * kPi / 180, Vec3::UnitZ()},
                                                {27 * kPi / 180, Vec3::UnitZ()},
                                                {45 * kPi / 180, Vec3::UnitZ()},
                                                {60 * kPi / 180, Vec3::UnitZ()},
                                                {89 * kPi / 180, Vec3::UnitZ()},
                                                {135 * kPi / 180, Vec3::UnitZ()},
                                                {-27 * kPi / 180, Vec3::UnitX()},
                                                {40 * kPi / 180, Vec3(1, 1, 1).normalized()},
                                                {1.0, Vec3(1, 2, 3).normalized()}};
  for (const Vec3& size : sizes)
    for (const Eigen::AngleAxisd& turn : turns) {
      SCOPED_TRACE(testing::Message()
                   << "size " << size.transpose() << ", " << turn.angle() * 180 / kPi
                   << " deg about " << turn.axis().transpose());
      const auto f = fit_box(stl_part(centred_box(size), turn));
      ASSERT_TRUE(f);
      expect_box(*f, size, turn);
    }
}

// Four quads around a rectangular hole through a plate (x by y, thickness
// t along z, centred on the origin): the ring's top and bottom, the outer
// sides and the hole's walls.
std::vector<Triangle> plate_with_hole(double x, double y, double t, double hx, double hy) {
  std::vector<Triangle> out;
  const auto quad = [&](const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    out.push_back({a, b, c});
    out.push_back({a, c, d});
  };
  const auto corner = [](double w, double h, int i, double z) {
    return Vec3((i == 1 || i == 2 ? 0.5 : -0.5) * w, (i >= 2 ? 0.5 : -0.5) * h, z);
  };
  for (int i = 0; i < 4; ++i) {
    const int j = (i + 1) % 4;
    for (double z : {-0.5 * t, 0.5 * t})
      quad(corner(x, y, i, z), corner(x, y, j, z), corner(hx, hy, j, z), corner(hx, hy, i, z));
    for (const auto& [w, h] : {std::pair{x, y}, std::pair{hx, hy}})
      quad(corner(w, h, i, -0.5 * t), corner(w, h, j, -0.5 * t), corner(w, h, j, 0.5 * t),
           corner(w, h, i, 0.5 * t));
  }
  return out;
}

// A right triangle (legs a along x, b along y) drawn out along z.
std::vector<Triangle> wedge(double a, double b, double length) {
  const Vec3 p[3] = {{0, 0, 0}, {a, 0, 0}, {0, b, 0}};
  const Vec3 l(0, 0, length);
  std::vector<Triangle> t = {{p[0], p[2], p[1]}, {p[0] + l, p[1] + l, p[2] + l}};
  for (int i = 0; i < 3; ++i) {
    const Vec3 &u = p[i], &v = p[(i + 1) % 3];
    t.push_back({u, v, v + l});
    t.push_back({u, v + l, u + l});
  }
  return t;
}

// What is not a box is measured against its box: the errors are the
// missing (or extra) volume and face area, exactly.
TEST(ExportFit, WhatIsNotABoxMissesItsBox) {
  const Eigen::AngleAxisd tilt(27 * kPi / 180, Vec3::UnitZ());
  // A 100 x 10 mm slot through a 150 x 300 x 4 plate: 2.2 % of its volume
  // gone, and its long walls add a third to the plate's 300 x 4 sides.
  const auto slot = fit_box(stl_part(plate_with_hole(150, 300, 4, 10, 100), tilt));
  ASSERT_TRUE(slot);
  EXPECT_FALSE(slot->within(kBoxTolerance));
  EXPECT_NEAR(slot->volume_error, 1000.0 / 45000.0, 1e-5);
  EXPECT_NEAR(slot->face_error, 400.0 / 1200.0, 1e-5);
  EXPECT_NEAR(slot->other_area, 0.0, 1e-12);
  // A 2 x 2 mm hole: 0.009 % of the volume, within the tolerance, but its
  // walls add 1.3 % to the plate's 150 x 4 sides.
  const auto hole = fit_box(stl_part(plate_with_hole(150, 300, 4, 2, 2), tilt));
  ASSERT_TRUE(hole);
  EXPECT_NEAR(hole->volume_error, 4.0 / 45000.0, 1e-6);
  EXPECT_NEAR(hole->face_error, 8.0 / 600.0, 1e-6);
  EXPECT_FALSE(hole->within(kBoxTolerance));
  // A wedge: any box around a triangular prism has at least twice its
  // volume, and its slope faces none of the box's faces.
  const auto half = fit_box(stl_part(wedge(40, 30, 100), tilt));
  ASSERT_TRUE(half);
  EXPECT_GE(half->volume_error, 0.5 - 1e-6);
  EXPECT_GT(half->other_area, 0.1);
  // An open box: one face has half its area (one triangle of two).
  std::vector<Triangle> open = centred_box({4, 150, 300});
  open.pop_back();
  const auto lid = fit_box(stl_part(open, tilt));
  ASSERT_TRUE(lid);
  EXPECT_NEAR(lid->face_error, 0.5, 1e-5);
  // Two plates side by side, 10 mm apart: a third of their box is empty.
  std::vector<Triangle> two = box({0, 0, 0}, {4, 150, 300});
  for (const Triangle& t : box({14, 0, 0}, {18, 150, 300})) two.push_back(t);
  const auto pair = fit_box(stl_part(two, tilt));
  ASSERT_TRUE(pair);
  EXPECT_NEAR(pair->volume_error, 10.0 / 18.0, 1e-5);
  // A drum.
  const auto drum = fit_box(stl_part(cylinder(160, 300, 96), tilt));
  ASSERT_TRUE(drum);
  EXPECT_FALSE(drum->within(kBoxTolerance));
}

TEST(ExportFit, CylinderAlongAnyAxis) {
  std::vector<Triangle> t = cylinder(0.053, 0.3, 128);
  const Eigen::AngleAxisd tilt(0.7, Vec3(1, 2, 3).normalized());
  for (Triangle& tri : t)
    for (Vec3& v : tri) v = tilt * v + Vec3(-0.213, 0.1, 0.05);
  Mesh m = soup(t);
  clean(m, 1e-12);
  const auto f = fit_cylinder(m);
  ASSERT_TRUE(f);
  EXPECT_NEAR(f->cylinder.radius, 0.053, 1e-12);
  EXPECT_NEAR(f->cylinder.length, 0.3, 1e-12);
  EXPECT_LT(f->cylinder.axis.cross(tilt * Vec3::UnitZ()).norm(), 1e-12);
  EXPECT_LT((f->cylinder.center - Vec3(-0.213, 0.1, 0.05)).norm(), 1e-12);
  EXPECT_LT(f->rms / f->cylinder.radius, 0.005);
}

}  // namespace
