// DEM baseline (Hertz-Mindlin with damping) against closed forms.
// Each test states its tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>

#include "sim/world.hpp"
#include "support.hpp"

namespace ces {
namespace {

constexpr double kGrainRadius = 1e-3, kGrainDensity = 2500.0;
const ElasticProperties kGrain{1e7, 0.3}, kSteel{2e8, 0.28};

// Material 0: grains; material 1: the plane. Unit sphere shape scaled to kGrainRadius.
std::shared_ptr<Model> dem_model(double restitution, double step, double friction = 0.3) {
  auto m = std::make_shared<Model>();
  m->step = step;
  m->contact_model = ContactModel::DEM;
  m->materials = MaterialTable(
      {{"grain", kGrainDensity, friction, restitution}, {"steel", 7800.0, friction, restitution}},
      {});
  m->dem.materials = {kGrain, kSteel};
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  return m;
}

double e_star(const ElasticProperties& a, const ElasticProperties& b) {
  return 1.0 / ((1 - a.poisson_ratio * a.poisson_ratio) / a.youngs_modulus +
                (1 - b.poisson_ratio * b.poisson_ratio) / b.youngs_modulus);
}

// Two equal spheres, head on at 1 m/s, no gravity; step 2e-7 s (about 1/800
// of the contact time). Tolerance: 2 % of e.
TEST(Dem, HeadOnCollisionReproducesRestitution) {
  for (const double e : {0.3, 0.6, 0.9}) {
    auto m = dem_model(e, 2e-7);
    m->gravity.setZero();
    World w(m);
    const double v0 = 0.5;
    w.add_particle(0, kGrainRadius, 0, Vec3(-kGrainRadius - 1e-6, 0, 0), Quat::Identity(),
                   Vec3(v0, 0, 0));
    w.add_particle(0, kGrainRadius, 0, Vec3(kGrainRadius + 1e-6, 0, 0), Quat::Identity(),
                   Vec3(-v0, 0, 0));
    for (int i = 0; i < 5000; ++i) w.step();
    const auto& p = w.particles();
    ASSERT_GT((p.position[1] - p.position[0]).norm(), 2 * kGrainRadius) << "still in contact";
    const double rebound = (p.velocity[1] - p.velocity[0]).x() / (2 * v0);
    EXPECT_NEAR(rebound, e, 0.02 * e) << "e = " << e;
  }
}

// The calibrated damping is needed: LIGGGHTS' linear-spring beta(e) misses
// the Hertz restitution (documented in dem.hpp). Tolerance on the
// calibration: 1e-4 absolute.
TEST(Dem, DampingCalibrationInvertsRestitution) {
  for (const double e : {0.05, 0.3, 0.6, 0.9, 1.0})
    EXPECT_NEAR(hertz_restitution(hertz_damping_for_restitution(e)), e, 1e-4);
}

// A grain on a steel plane settles at delta = (3 m g / (4 E* sqrt(R)))^(2/3),
// R* = R, E* from both materials. Tolerance: 2 % of delta.
TEST(Dem, SphereOnPlaneSettlesAtHertzOverlap) {
  auto m = dem_model(0.3, 1e-6);
  m->bodies.push_back(test::ground_plane(Vec3::UnitY(), 1));
  World w(m);
  w.add_particle(0, kGrainRadius, 0, Vec3(0, kGrainRadius, 0));
  for (int i = 0; i < 30000; ++i) w.step();
  const double mass = w.particles().mass[0];
  const double expected =
      std::pow(3 * mass * 9.81 / (4 * e_star(kGrain, kSteel) * std::sqrt(kGrainRadius)), 2.0 / 3.0);
  const double delta = kGrainRadius - w.particles().position[0].y();
  EXPECT_NEAR(delta, expected, 0.02 * expected);
  EXPECT_LT(w.particles().velocity[0].norm(), 1e-6);
}

// Rayleigh time pi R sqrt(rho / G) / (0.1631 nu + 0.8766) of a 1 mm grain is
// 86.5 us (tolerance 1e-12 relative): 1e-5 s is below 20 % of it, 1e-4 s above.
TEST(Dem, StepAboveRayleighLimitWarns) {
  const double shear = kGrain.youngs_modulus / (2 * (1 + kGrain.poisson_ratio));
  const double rayleigh = M_PI * kGrainRadius * std::sqrt(kGrainDensity / shear) /
                          (0.1631 * kGrain.poisson_ratio + 0.8766);
  for (const double step : {1e-5, 1e-4}) {
    auto m = dem_model(0.5, step);
    m->bodies.push_back(test::ground_plane(Vec3::UnitY(), 1));
    World w(m);
    w.add_particle(0, kGrainRadius, 0, Vec3(0, kGrainRadius, 0));
    const StepStats& s = w.step();
    EXPECT_NEAR(s.rayleigh_time, rayleigh, 1e-12 * rayleigh);
    EXPECT_EQ(s.step_above_rayleigh_limit, step > 0.2 * rayleigh) << step;
  }
  auto dvi = std::make_shared<Model>();
  EXPECT_FALSE(World(dvi).step().step_above_rayleigh_limit);
}

// A pile of 343 touching grains dropped on a plane, 400 steps: the state
// with 1 and 2 threads is bitwise identical (the parallel loops engage above
// 256 items).
TEST(Dem, OneAndTwoThreadsBitwiseIdentical) {
  std::vector<Vec3> result[2];
  for (int t = 0; t < 2; ++t) {
    auto m = dem_model(0.5, 1e-5, 0.5);
    m->threads = t + 1;
    m->bodies.push_back(test::ground_plane(Vec3::UnitY(), 1));
    World w(m);
    for (int i = 0; i < 7; ++i)
      for (int j = 0; j < 7; ++j)
        for (int k = 0; k < 7; ++k) {
          const Vec3 x(1.98 * kGrainRadius * i + 1e-5 * j, kGrainRadius * (1.02 + 1.98 * j),
                       1.98 * kGrainRadius * k + 1e-5 * i);
          w.add_particle(0, kGrainRadius, 0, x, Quat::Identity(), Vec3(0.01 * (k - 3), 0, 0));
        }
    for (int s = 0; s < 400; ++s) w.step();
    EXPECT_GT(w.last_step().contacts, 256u);
    result[t] = w.particles().position;
    for (const Vec3& v : w.particles().angular_velocity) result[t].push_back(v);
  }
  ASSERT_EQ(result[0].size(), result[1].size());
  EXPECT_EQ(std::memcmp(result[0].data(), result[1].data(), result[0].size() * sizeof(Vec3)), 0);
}

}  // namespace
}  // namespace ces
