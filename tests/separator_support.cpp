#include "separator_support.hpp"

#include <array>
#include <cmath>

namespace ces::fields::test {

std::shared_ptr<Model> make_model(double step, const std::vector<MaterialSpec>& particles,
                                  double drum_friction) {
  auto m = std::make_shared<Model>();
  m->step = step;
  std::vector<Material> mats = {{"steel", 7800.0, drum_friction, 0.0}};
  for (const MaterialSpec& p : particles) mats.push_back({"particle", p.density, p.friction, 0.0});
  m->materials = MaterialTable(mats, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  m->shapes.push_back(make_particle_shape({Vec3(-1, 0, 0), Vec3(1, 0, 0)}, {1.0, 1.0}));
  m->solver.max_iterations = 200;
  m->solver.tolerance = 1e-9;
  return m;
}

std::vector<ElectricalMaterial> electrical(const std::vector<MaterialSpec>& particles) {
  std::vector<ElectricalMaterial> e = {ElectricalMaterial::conductor()};  // steel
  for (const MaterialSpec& p : particles) e.push_back(p.electrical);
  return e;
}

RigidBody drum(double omega) {
  RigidBody b;
  b.name = "drum";
  b.kind = BodyKind::Kinematic;
  b.shape = geo::Cylinder{kDrumRadius, kHalfWidth, 0.0};
  b.motion.angular_speed = -omega;
  return b;
}

ElectricField reference_field() {
  return BipolarField(Drum{kDrumRadius, kHalfWidth},
                      Electrode::at_polar(0.267, 30.0 * kDeg, 0.019, -35e3));
}

ElectricField no_field() {
  const GridField::Axis axis{-1.0, 2.0, 2};
  return std::make_shared<const GridField>(std::array{axis, axis, axis},
                                           std::vector<Vec3>(8, Vec3::Zero()));
}

ElectrostaticsSpec electrostatics(ElectricField field, const std::vector<MaterialSpec>& particles) {
  ElectrostaticsSpec s(std::move(field));
  s.drum = {kDrumRadius, kHalfWidth};
  s.drum_body = 0;
  s.materials = electrical(particles);
  return s;
}

Vec3 on_drum(double rho, double theta, double z) {
  return {rho * std::sin(theta), rho * std::cos(theta), z};
}

Vec3 carried_velocity(double omega, const Vec3& x) { return Vec3(0, 0, -omega).cross(x); }
Vec3 carried_spin(double omega) { return {0, 0, -omega}; }

double theta_of(const Vec3& x) { return std::atan2(x.x(), x.y()); }

double drum_load(const World& w, std::size_t i) {
  const Contacts& c = w.contacts();
  const int drum_index = int(w.particles().size());
  double load = 0.0;
  for (std::size_t k = 0; k < c.size(); ++k)
    if (c.body_a[k] == drum_index && c.body_b[k] == int(i))
      load += w.impulses()[std::ptrdiff_t(3 * k)];
  return load;
}

double induced_charge(double r, double en) {
  return 2.0 / 3.0 * kPi * kPi * kPi * kEps0 * kEpsAir * r * r * en;
}
double lift_force(double r, double en) { return 0.832 * induced_charge(r, en) * en; }
double image_pull(double q, double r) {
  return q * q / (4.0 * kPi * kEps0 * kEpsAir * 4.0 * r * r);
}

CoronaZone saturation_zone() {
  CoronaZone zone;
  zone.angle_begin = 80.0 * kDeg;
  zone.angle_end = 100.0 * kDeg;
  zone.depth = 5e-3;
  zone.mode = CoronaCharging::Saturation;
  zone.field = 4.13e5;  // V/m
  return zone;
}

}  // namespace ces::fields::test
