// The energy ledger of summary.json (output/energy.hpp) against closed forms.
#include <gtest/gtest.h>

#include <memory>

#include "sim/world.hpp"
#include "output/energy.hpp"
#include "support.hpp"

namespace ces {
namespace {

constexpr double kRadius = 1e-3, kDensity = 2500.0;

std::shared_ptr<Model> sphere_model(Vec3 gravity) {
  auto m = std::make_shared<Model>();
  m->step = 1e-3;
  m->gravity = gravity;
  m->materials = MaterialTable({{"grain", kDensity, 0.0, 0.0}}, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  return m;
}

// The ledger observing a World's stages as the runner's does (no feeds or
// collectors).
struct Ledger : StepObserver {
  output::EnergyLedger ledger;
  Ledger(const Simulation& sim, const World& w) : ledger(sim, w.state()) {}
  void after(Stage stage, const World& w) override { ledger.after(stage, w.state()); }
};

output::EnergyBalance run_ledger(const std::shared_ptr<Model>& m, World& w, int steps) {
  Simulation sim;
  sim.model = m;
  Ledger observer(sim, w);
  for (int i = 0; i < steps; ++i) w.step(&observer);
  return observer.ledger.balance();
}

// Semi-implicit Euler loses exactly m g^2 h^2 / 2 per step in free fall
// (v' = v + g h, x' = x + h v'): never a gain. Tolerance 1e-9 relative.
TEST(Energy, FreeFallLosesHalfMGSquaredHSquaredPerStep) {
  const Vec3 g(0, -9.81, 0);
  auto m = sphere_model(g);
  World w(m);
  w.add_particle(0, kRadius, 0, Vec3(0, 1, 0), Quat::Identity(), Vec3(0.3, 0, 0),
                 Vec3(0, 0, 50));
  const int n = 200;
  const output::EnergyBalance e = run_ledger(m, w, n);
  const double mass = w.particles().mass[0], h = m->step;
  const double expected = n * 0.5 * mass * g.squaredNorm() * h * h;
  EXPECT_NEAR(e.dissipated, expected, 1e-9 * expected);
  EXPECT_EQ(e.max_gain, 0.0);
  EXPECT_EQ(e.fed, 0.0);
  // Spin is kept: 2/5 m r^2 w^2 / 2 in the kinetic energy.
  const double spin = 0.5 * 0.4 * mass * kRadius * kRadius * 50.0 * 50.0;
  EXPECT_NEAR(e.peak_kinetic, 0.5 * mass * (0.09 + g.squaredNorm() * (n * h) * (n * h)) + spin,
              1e-9 * e.peak_kinetic);
}

// A grain placed 20 % of its radius into the ground, without gravity: the
// stabilisation pushes it out and it leaves with kinetic energy nothing
// supplied. The ledger must see all of it as a gain (1e-12 relative).
TEST(Energy, StabilisationPushingOutAnOverlapIsAGain) {
  auto m = sphere_model(Vec3::Zero());
  m->bodies.push_back(test::ground_plane());
  World w(m);
  w.add_particle(0, kRadius, 0, Vec3(0, 0.4 * kRadius, 0));
  const output::EnergyBalance e = run_ledger(m, w, 50);
  const double kinetic = 0.5 * w.particles().mass[0] * w.particles().velocity[0].squaredNorm();
  EXPECT_GT(kinetic, 0.0);
  EXPECT_NEAR(e.max_gain, kinetic, 1e-12 * kinetic);
  EXPECT_NEAR(e.max_gain_relative(), 1.0, 1e-12);
}

TEST(Energy, MovingBodiesElectricForcesAndMotorsAreSources) {
  Simulation sim;
  sim.model = sphere_model(Vec3::Zero());
  sim.model->bodies.push_back(test::ground_plane());
  EXPECT_EQ(output::why_not_passive(sim), "");
  sim.model->bodies[0].kind = BodyKind::Kinematic;  // kinematic but still: passive
  EXPECT_EQ(output::why_not_passive(sim), "");
  sim.model->bodies[0].motion.angular_speed = 1.0;
  EXPECT_NE(output::why_not_passive(sim).find("'ground' moves"), std::string::npos);
  sim.model->bodies[0].motion.angular_speed = 0.0;
  sim.model->motors.push_back({});
  EXPECT_EQ(output::why_not_passive(sim), "motors do work");
}

}  // namespace
}  // namespace ces
