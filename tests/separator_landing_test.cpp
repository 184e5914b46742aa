// A flat flake landing on the drum: what the rigid contacts do to it at
// any step. Frame and helpers: separator_support.hpp.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "feed/shapes.hpp"
#include "output/energy.hpp"
#include "separator_support.hpp"
#include "sim/world.hpp"

namespace ces::fields {
namespace {

using namespace test;

// Kinetic energy of particle 0 at velocity v, spin w, in orientation q.
double kinetic_energy(const Particles& p, const Vec3& v, const Vec3& w, const Quat& q) {
  return 0.5 * p.mass[0] * v.squaredNorm() +
         output::rotational_energy(q, p.inv_inertia[0].cwiseInverse(), w);
}

// The work the contacts did on particle 0 in each step: its kinetic energy
// after the step's velocities against that of its free motion (the
// velocities before, plus gravity's impulse), both in the step's starting
// orientation, so that the turn of a body with unequal inertias does not
// count.
struct ContactWork : StepObserver {
  Vec3 gravity_impulse = Vec3::Zero();
  Vec3 v = Vec3::Zero(), w = Vec3::Zero();
  Quat q = Quat::Identity();
  double gained = 0.0;  // J: the sum of the steps' positive work
  void after(Stage stage, const World& world) override {
    const Particles& p = world.particles();
    if (stage == Stage::Safeguards) {
      v = p.velocity[0] + gravity_impulse, w = p.angular_velocity[0], q = p.orientation[0];
    } else if (stage == Stage::Integrate) {
      const double work = kinetic_energy(p, p.velocity[0], p.angular_velocity[0], q) -
                          kinetic_energy(p, v, w, q);
      gained += std::max(0.0, work);
    }
  }
};

// An FR-4 flake 3.4 mm across and 0.5 mm thick, of 19 spheres, falls at
// 0.7 m/s (what the feed's 40 mm drop gives) onto the top of a still,
// frictionless drum, tilted by 4° about the drum's axis so that its rim
// strikes first. Plastic impacts without friction on a surface at rest can
// only take energy: at every step, from the reference scene's 0.25 ms to a
// sixteenth of it, the contacts' work summed over the steps where it is
// positive stays under 1e-4 of the impact's kinetic energy (what is left is
// the push-out of overlaps within the penetration tolerance, at the recovery
// speed). What the flake keeps of its energy after landing does depend on
// the step (docs/accuracy.md, section 2): the finer the step, the more of
// its rim's impacts are resolved one after another instead of together.
TEST(FlakeLanding, ContactsOnAStillFrictionlessDrumDoNoPositiveWork) {
  const SingleThread one_thread;
  const std::vector<MaterialSpec> mats = {
      {kFr4, 0.0, ElectricalMaterial::insulator(kFr4Permittivity)}};
  const double width = 3.4e-3, aspect = 0.15, speed = 0.7;
  for (const double h : {0.25e-3, 0.0625e-3, 0.015625e-3}) {
    auto m = make_model(h, mats, 0.0);
    m->gravity = Vec3(0, -kG, 0);
    const feed::SphereList f = feed::flake_spheres(aspect);
    m->shapes.push_back(make_particle_shape(f.centers, f.radii));
    m->bodies.push_back(drum(0.0));
    World w(m);
    const Vec3 x0 = on_drum(kDrumRadius + 0.5 * aspect * width + 0.3e-3, 0.0);
    const Vec3 n0 = x0.normalized();
    const Quat flat = Quat::FromTwoVectors(shape_electrics(m->shapes.back()).face_normal, n0);
    const Quat tilted(Eigen::AngleAxisd(4.0 * kDeg, Vec3::UnitZ()) * flat);
    w.add_particle(int(m->shapes.size()) - 1, width, 1, x0, tilted, -speed * n0);
    const double impact = 0.5 * w.particles().mass[0] * speed * speed;
    ContactWork work;
    work.gravity_impulse = h * m->gravity;
    double load = 0.0;
    for (int i = 0; i * h < 20e-3; ++i) {
      w.step(&work);
      load += drum_load(w, 0);
    }
    EXPECT_GT(load, 0.9 * w.particles().mass[0] * speed) << "h = " << h;  // it did land
    EXPECT_LT(work.gained, 1e-4 * impact) << "h = " << h;
  }
}

}  // namespace
}  // namespace ces::fields
