#include "nip.hpp"

#include <cmath>

namespace ces::test {
namespace {
constexpr double kDrum = 0.16, kBrush = 0.053;
}  // namespace

void add_drum_and_brush(Model& m, double omega, int drum_material, int brush_material) {
  RigidBody drum, brush;
  drum.kind = brush.kind = BodyKind::Kinematic;
  drum.shape = geo::Cylinder{kDrum, 0.05, 0.0};
  drum.material = drum_material;
  drum.motion.angular_speed = -omega;
  brush.shape = geo::Cylinder{kBrush, 0.05, 0.0};
  brush.material = brush_material;
  brush.pose.position = Vec3(-(kDrum + kBrush), 0, 0);
  brush.motion.center = brush.pose.position;
  brush.motion.angular_speed = -omega;
  m.bodies.push_back(drum);
  m.bodies.push_back(brush);
}

void add_nip_grains(World& w, int flake_shape, double omega) {
  const double R = kDrum, rb = kBrush;
  const Quat on_edge(Eigen::AngleAxisd(0.5 * kPi, Vec3::UnitY()));  // its plane facing the drum
  auto wedge_x = [&](double y) {  // midway between the two surfaces at height y
    return 0.5 * (-std::sqrt(R * R - y * y) + (-(R + rb) + std::sqrt(rb * rb - y * y)));
  };
  for (int i = 0; i < 6; ++i) {
    const double y = 0.007 + 0.002 * i, z = -0.03 + 0.012 * i;
    w.add_particle(flake_shape, 1.2e-3, 0, Vec3(wedge_x(y), y, z), on_edge, Vec3(0, -1.0, 0));
  }
  for (int i = 0; i < 6; ++i) {
    const double r = 0.5e-3, a = kPi + 0.06 + 0.02 * i, z = -0.03 + 0.012 * i;
    const Vec3 c((R + r) * std::cos(a), (R + r) * std::sin(a), z);
    w.add_particle(0, r, 0, c, Quat::Identity(), Vec3(0, omega * R, 0));
  }
}

}  // namespace ces::test
