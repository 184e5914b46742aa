// Writes meshes/example/: a small separator as a CAD user would export it,
// one binary STL per part, in millimetres, z up and the drum along x, each
// part placed where it stands in the machine (STL keeps no assembly):
// a 96-facet drum, an electrode, a splitter plate tilted by -20 degrees, a
// hopper and the feed outlet under it, a floor and a bolt.
//
//   cmake --build build --target make_example_stl && build/exporter/make_example_stl
//   meshes/example
#include <array>
#include <cmath>
#include <filesystem>
#include <iostream>

#include "mesh.hpp"

namespace {

using ces::Mat3;
using ces::Vec3;
using ces::exporter::Mesh;
namespace fs = std::filesystem;

// Scene (x toward the electrode, y up, z along the drum; mm, from the drum
// axis) to CAD (x along the drum, z up; the drum axis 400 mm above the
// floor's origin).
Vec3 to_cad(const Vec3& p) { return {p.z() + 50.0, p.x(), p.y() + 400.0}; }

void add_quad(Mesh& m, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const auto base = std::uint32_t(m.vertices.size());
  for (const Vec3& v : {a, b, c, d}) m.vertices.push_back(v);
  m.triangles.push_back({base, base + 1, base + 2});
  m.triangles.push_back({base, base + 2, base + 3});
}

// A closed cylinder along z, centred on the origin, of `sides` facets.
Mesh cylinder(double radius, double length, int sides) {
  Mesh m;
  const double h = 0.5 * length;
  for (int i = 0; i < sides; ++i) {
    const double a0 = 2.0 * M_PI * i / sides, a1 = 2.0 * M_PI * (i + 1) / sides;
    const Vec3 r0(radius * std::cos(a0), radius * std::sin(a0), 0.0);
    const Vec3 r1(radius * std::cos(a1), radius * std::sin(a1), 0.0);
    const Vec3 lo(0.0, 0.0, -h), hi(0.0, 0.0, h);
    add_quad(m, lo + r0, lo + r1, hi + r1, hi + r0);
    const auto base = std::uint32_t(m.vertices.size());
    for (const Vec3& v : {hi, Vec3(hi + r0), Vec3(hi + r1), lo, Vec3(lo + r1), Vec3(lo + r0)})
      m.vertices.push_back(v);
    m.triangles.push_back({base, base + 1, base + 2});
    m.triangles.push_back({base + 3, base + 4, base + 5});
  }
  return m;
}

// A box centred on the origin.
Mesh box(double x, double y, double z) {
  Mesh m;
  const Vec3 h(0.5 * x, 0.5 * y, 0.5 * z);
  const auto c = [&](int i, int j, int k) {
    return Vec3(i ? h.x() : -h.x(), j ? h.y() : -h.y(), k ? h.z() : -h.z());
  };
  add_quad(m, c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0));
  add_quad(m, c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1));
  add_quad(m, c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1));
  add_quad(m, c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0));
  add_quad(m, c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0));
  add_quad(m, c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1));
  return m;
}

// A hopper: the four sides of a funnel from a top opening (x by z) at
// height `top` to a bottom one at `bottom`, open at both ends.
Mesh funnel(double top_x, double top_z, double top, double bottom_x, double bottom_z,
            double bottom) {
  const auto ring = [](double x, double z, double y) {
    return std::array<Vec3, 4>{Vec3(-x / 2, y, -z / 2), Vec3(x / 2, y, -z / 2),
                               Vec3(x / 2, y, z / 2), Vec3(-x / 2, y, z / 2)};
  };
  const auto hi = ring(top_x, top_z, top), lo = ring(bottom_x, bottom_z, bottom);
  Mesh m;
  for (int i = 0; i < 4; ++i) add_quad(m, lo[i], lo[(i + 1) % 4], hi[(i + 1) % 4], hi[i]);
  return m;
}

// The part turned by `degrees` about the scene's z, moved to (x, y) of the
// scene, and put into CAD coordinates.
Mesh placed(Mesh m, double x, double y, double degrees = 0.0) {
  const Mat3 turn = Eigen::AngleAxisd(degrees * M_PI / 180.0, Vec3::UnitZ()).toRotationMatrix();
  for (Vec3& v : m.vertices) v = to_cad(turn * v + Vec3(x, y, 0.0));
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: make_example_stl FOLDER\n";
    return 2;
  }
  const fs::path out = argv[1];
  fs::create_directories(out);
  const double a = 35.0 * M_PI / 180.0;
  const std::pair<const char*, Mesh> parts[] = {
      {"drum", placed(cylinder(100.0, 100.0, 96), 0.0, 0.0)},
      {"electrode", placed(cylinder(12.0, 100.0, 48), 180.0 * std::cos(a), 180.0 * std::sin(a))},
      {"splitter", placed(box(3.0, 80.0, 100.0), 160.0, -215.0, -20.0)},
      {"hopper", placed(funnel(120.0, 100.0, 230.0, 60.0, 80.0, 140.0), -40.0, 0.0)},
      {"outlet", placed(box(60.0, 2.0, 80.0), -40.0, 130.0)},
      {"floor", placed(box(600.0, 2.0, 200.0), 100.0, -260.0)},
      {"bolt", placed(box(13.0, 13.0, 8.0), 280.0, -255.0)}};
  try {
    for (const auto& [name, mesh] : parts)
      ces::exporter::write_binary_stl(mesh, out / (std::string(name) + ".stl"),
                                      std::string("ces-sim example machine: ") + name + ", mm");
  } catch (const std::exception& e) {
    std::cerr << "cannot write " << out << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}
