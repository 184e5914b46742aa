// Engine checks against closed forms on bodies and walls: clumps' spin,
// clusters' mass properties, grains in a zero-gap nip, joints and motors,
// and spheres on boxes, meshes and shells. Each test states its tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "engine_support.hpp"
#include "feed/shapes.hpp"
#include "nip.hpp"
#include "sim/world.hpp"
#include "support.hpp"

namespace ces {
namespace {

using test::base_model;

// ---------------------------------------------------------------- clumps and spin

// World::limit_spin: a clump that touches something turns by at most
// sqrt(2 * 0.1 * r / lever) per step (its spheres drift a tenth of a
// radius off the linearised contact rows); in flight it keeps its spin. A
// dumbbell of two 1 mm spheres 6 mm apart (lever 3 r) spinning at 2000 rad/s
// about the vertical, one lying on a frictionless plane (no torque: only the
// cap changes its spin), one in the air (torque-free about a principal
// axis: exactly kept). Tolerances: 1e-9 relative on the cap, rounding on
// the free spin.
TEST(Engine, ClumpSpinIsCappedOnlyInContact) {
  auto m = base_model({0.0});
  m->shapes.push_back(make_particle_shape({Vec3(-3, 0, 0), Vec3(3, 0, 0)}, {1.0, 1.0}));
  m->bodies.push_back(test::ground_plane());
  World w(m);
  const double r = 1e-3, spin = 2000.0;
  w.add_particle(1, r, 0, Vec3(0, r, 0), Quat::Identity(), Vec3::Zero(), Vec3(0, spin, 0));
  w.add_particle(1, r, 0, Vec3(0, 1.0, 0), Quat::Identity(), Vec3::Zero(), Vec3(0, spin, 0));
  const double cap = std::sqrt(2.0 * 0.1 / 3.0) / m->step;
  EXPECT_EQ(w.step().spin_limited, 1u);
  EXPECT_NEAR(w.particles().angular_velocity[0].norm(), cap, 1e-9 * cap);
  EXPECT_NEAR(w.particles().angular_velocity[1].norm(), spin, 1e-12 * spin);
}

// The cap's purpose: a dumbbell (two 1 mm spheres, centres 6 mm apart)
// tumbling at 450 rad/s onto a plane at a 10 ms step (4.5 rad a step). Its
// spheres' rows are linear in the step's motion, so uncapped a sphere ends
// far past a quarter radius inside the plane; the cap holds each sphere's
// drift in a step to a quarter radius. Bound: a quarter radius.
TEST(Engine, TumblingClumpStaysOutOfThePlane) {
  auto m = base_model({0.5}, 10e-3);
  m->shapes.push_back(make_particle_shape({Vec3(-3, 0, 0), Vec3(3, 0, 0)}, {1.0, 1.0}));
  m->bodies.push_back(test::ground_plane());
  m->solver.max_iterations = 100;
  m->solver.tolerance = 1e-6;
  World w(m);
  const double r = 1e-3;
  w.add_particle(1, r, 0, Vec3(0, 4 * r, 0), Quat::Identity(), Vec3(0.2, -1.0, 0),
                 Vec3(120, 80, 400));
  double worst = 0.0;
  std::size_t capped = 0;
  for (int i = 0; i < 100; ++i) {
    const StepStats& s = w.step();
    worst = std::max(worst, s.max_wall_penetration_relative);
    capped += s.spin_limited;
  }
  EXPECT_GT(capped, 0u);
  EXPECT_LT(worst, 0.25);
}

// ---------------------------------------------------------------- mass properties

// Union of two overlapping spheres (radius 1, centres 1 apart) against the
// closed form: volume of the union = 2 V_sphere - V_lens. Tolerance 1e-4.
TEST(Engine, OverlappingClusterMassPropertiesMatchClosedForm) {
  const double r = 1.0, d = 1.0;
  const ParticleShape s = make_particle_shape({Vec3(0, 0, 0), Vec3(d, 0, 0)}, {r, r});
  const double lens = kPi * (4 * r + d) * (2 * r - d) * (2 * r - d) / 12.0;
  const double volume = 2 * 4.0 / 3.0 * kPi - lens;
  EXPECT_NEAR(s.volume, volume, 1e-4 * volume);
  // Moment about the long axis (x): integral of (y^2 + z^2) over the union,
  // by slices: each slice is a disc of radius a(x), moment pi a^4 / 2.
  auto slice = [&](double x) {
    const double a2 = std::max(r * r - x * x, r * r - (x - d) * (x - d));
    return a2 > 0 ? kPi * a2 * a2 / 2.0 : 0.0;
  };
  double ixx = 0.0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double x = -r + (d + 2 * r) * (i + 0.5) / n;
    ixx += slice(x) * (d + 2 * r) / n;
  }
  // The long axis is the principal axis with the smallest moment.
  EXPECT_NEAR(s.unit_inertia.minCoeff() * s.volume, ixx, 1e-4 * ixx);
  // Separated spheres are exact: two unit spheres 3 apart.
  const ParticleShape t = make_particle_shape({Vec3(0, 0, 0), Vec3(3, 0, 0)}, {1, 1});
  EXPECT_NEAR(t.volume, 8.0 / 3.0 * kPi, 1e-12);
  EXPECT_NEAR(t.unit_inertia.maxCoeff(), 0.4 + 1.5 * 1.5, 1e-12);
}

// A sphere a billionth the size of its neighbour would have the octree
// split the large one's surface into 5e7 cells; the bound on cells coarsens
// them instead. The tiny sphere lies inside: the union is the unit sphere,
// to the accuracy of the coarser cells (1e-3).
TEST(Engine, ClusterOfVeryDifferentSpheresStaysAccurate) {
  const ParticleShape s = make_particle_shape({Vec3(0, 0, 0), Vec3(0.5, 0, 0)}, {1.0, 1e-9});
  const double volume = 4.0 / 3.0 * kPi;
  EXPECT_NEAR(s.volume, volume, 1e-3 * volume);
  EXPECT_NEAR(s.unit_inertia.x(), 0.4, 1e-3 * 0.4);
}

// Clusters are integrated once per process and remembered by their
// spheres' bits: a cluster apart from a remembered one is its own, and
// threads asking for clusters at once get what one thread gets alone.
TEST(Engine, RememberedClustersAreEachClustersOwn) {
  const auto volume = [](double r) {
    return make_particle_shape({Vec3(0, 0, 0), Vec3(1, 0, 0)}, {1.0, r}).volume;
  };
  const double first = volume(1.0);
  EXPECT_EQ(volume(1.0), first);
  EXPECT_NE(volume(1.0 + 1e-6), first);
  std::vector<double> together(4);
#pragma omp parallel for schedule(static, 1)
  for (std::size_t k = 0; k < together.size(); ++k) together[k] = volume(0.6 + 0.1 * double(k % 2));
  EXPECT_EQ(together[2], together[0]);
  EXPECT_EQ(together[3], together[1]);
  EXPECT_EQ(volume(0.6), together[0]);
  EXPECT_NE(together[1], together[0]);
}

// ---------------------------------------------------------------- nip

// The nip of two rigid cylinders that touch (zero gap), both kinematic and
// turning the same way, so that at the nip their surfaces move opposite:
// the reference machine's drum (r 0.16 m, surface 0.75 m/s up at the nip)
// and brush (r 0.053 m, 0.25 m/s down), at 20 times the machine's step
// (10 ms, APGD 50 iterations). Flakes (19 spheres, 1.2 mm wide) fall
// into the wedge above the nip at 1 m/s, standing in it on edge as the
// scene's did; spheres ride the drum up into the wedge below it. Every
// grain must stay out of both cylinders (docs/accuracy.md, section 4):
// bound half a radius. It takes the wall guard's sweeps, finished body by
// body (dynamics/safeguards.cpp), with the guards after the spin cap
// leaving clumps' spin alone: without them a sphere goes radii into a
// cylinder here.
TEST(Engine, GrainsStayOutOfAZeroGapNipAtALargeStep) {
  auto m = base_model({0.5}, 10e-3);
  m->solver.max_iterations = 50;
  m->solver.tolerance = 1e-6;
  const feed::SphereList flake = feed::flake_spheres(0.2);
  m->shapes.push_back(make_particle_shape(flake.centers, flake.radii));
  const double omega = 44.8 * 2.0 * kPi / 60.0;
  test::add_drum_and_brush(*m, omega, 0, 0);
  World w(m);
  test::add_nip_grains(w, 1, omega);
  double worst = 0.0;
  for (int i = 0; i < 40; ++i) worst = std::max(worst, w.step().max_wall_penetration_relative);
  EXPECT_EQ(w.particles().size(), 12u);
  EXPECT_LE(worst, 0.5) << "radii into a cylinder";
}

// ---------------------------------------------------------------- joints

// A drum on a revolute joint driven by a speed motor: turns at the commanded
// speed (error < 1e-6 rad/s) with joint drift < 1e-6 m, under gravity.
TEST(Engine, MotorDrivesDrumAtCommandedSpeed) {
  auto m = base_model();
  RigidBody drum;
  drum.name = "drum";
  drum.kind = BodyKind::Dynamic;
  drum.shape = geo::Cylinder{0.16, 0.15, 0.0};
  drum.mass = 50.0;
  drum.inertia = Vec3(0.5 * 50 * 0.16 * 0.16, 0.5 * 50 * 0.16 * 0.16, 0.5 * 50 * 0.16 * 0.16);
  drum.pose.position = Vec3(0.0, 0.3, 0.0);
  m->bodies.push_back(drum);
  m->joints.push_back({JointType::Revolute, -1, 0, Vec3(0.0, 0.3, 0.0), Vec3::UnitZ()});
  const double speed = 44.8 * 2 * kPi / 60;
  m->motors.push_back({0, Motor::Mode::Speed, speed});
  World w(m);
  double drift = 0.0;
  for (int i = 0; i < 1000; ++i) drift = std::max(drift, w.step().joint_drift);
  EXPECT_NEAR(w.bodies().angular_velocity[0].z(), speed, 1e-6);
  EXPECT_LT(w.bodies().angular_velocity[0].head<2>().norm(), 1e-6);
  EXPECT_LT(drift, 1e-6);
  EXPECT_LT((w.bodies().pose[0].position - Vec3(0, 0.3, 0)).norm(), 1e-6);
}

// A prismatic joint with a position motor slides a plate to its target.
TEST(Engine, PrismaticPositionMotorReachesTarget) {
  auto m = base_model();
  m->gravity.setZero();
  RigidBody plate;
  plate.kind = BodyKind::Dynamic;
  plate.shape = geo::Box{Vec3(0.01, 0.05, 0.1)};
  plate.mass = 1.0;
  plate.inertia = Vec3(1e-3, 1e-3, 1e-3);
  m->bodies.push_back(plate);
  m->joints.push_back({JointType::Prismatic, -1, 0, Vec3::Zero(), Vec3::UnitX()});
  m->motors.push_back({0, Motor::Mode::Position, 0.05, 0.1, 100.0});
  World w(m);
  for (int i = 0; i < 1000; ++i) w.step();  // 0.05 m at 0.1 m/s: 0.5 s
  EXPECT_NEAR(w.bodies().pose[0].position.x(), 0.05, 1e-9);
  EXPECT_LT(w.bodies().pose[0].position.tail<2>().norm(), 1e-9);
}

// A heavy plate falling at 1 m/s strikes a grain and drives it into the
// grain below, 0.6 radii away: beyond the lower grain's envelope, and
// beyond the upper one's before the blow. The collision must find that pair
// in the step of the blow, or the upper grain ends the step 0.4 radii in
// the lower. Tolerance: the solver's penetration_tolerance.
TEST(Engine, PlateDrivesAGrainIntoTheOneBelow) {
  auto m = base_model({0.0}, 1e-3);
  m->gravity.setZero();
  m->solver.tolerance = 1e-3;
  const double r = 1e-3;
  RigidBody plate;
  plate.kind = BodyKind::Dynamic;
  plate.shape = geo::Box{Vec3(0.005, 0.001, 0.005)};
  plate.mass = 1.0;
  plate.inertia = Vec3(1e-5, 1e-5, 1e-5);
  plate.pose.position = Vec3(0, r + 0.1e-3 + 0.001, 0);
  plate.velocity = Vec3(0, -1.0, 0);
  m->bodies.push_back(plate);
  World w(m);
  w.add_particle(0, r, 0, Vec3::Zero(), Quat::Identity(), Vec3::Zero());
  w.add_particle(0, r, 0, Vec3(0, -2.6 * r, 0), Quat::Identity(), Vec3::Zero());
  double worst = 0.0;
  for (int i = 0; i < 3; ++i) worst = std::max(worst, w.step().max_penetration_relative);
  EXPECT_LT(w.particles().velocity[1].y(), -0.5) << "the blow reached the lower grain";
  EXPECT_LE(worst, m->solver.penetration_tolerance + 1e-9);
}

// A fixed joint holds a heavy plate to the ground against gravity: drift
// below 1e-6 m and rotation below 1e-6 rad after 1 s.
TEST(Engine, FixedJointHoldsBodyAgainstGravity) {
  auto m = base_model();
  RigidBody plate;
  plate.kind = BodyKind::Dynamic;
  plate.shape = geo::Box{Vec3(0.1, 0.01, 0.1)};
  plate.mass = 5.0;
  plate.inertia = Vec3(0.02, 0.03, 0.02);
  plate.pose.position = Vec3(0.2, 0.5, 0.0);
  m->bodies.push_back(plate);
  // Anchor off the centre of mass, so gravity also makes a torque.
  m->joints.push_back({JointType::Fixed, -1, 0, Vec3(0.0, 0.5, 0.0), Vec3::UnitZ()});
  World w(m);
  double drift = 0.0;
  for (int i = 0; i < 1000; ++i) drift = std::max(drift, w.step().joint_drift);
  EXPECT_LT(drift, 1e-6);
  EXPECT_LT((w.bodies().pose[0].position - Vec3(0.2, 0.5, 0.0)).norm(), 1e-6);
  EXPECT_LT(w.bodies().pose[0].orientation.angularDistance(Quat::Identity()), 1e-6);
}

// ---------------------------------------------------------------- machine surfaces

// A sphere rests on a box, on a triangulated mesh floor, and inside a hollow
// drum shell at the bottom: drift below 1e-6 m over 2 s, penetration below
// 1 % of the radius. The mesh floor's shared edges and vertices must not
// create extra contacts (exactly one contact while resting on a vertex).
double rest_on(const geo::Shape& shape, const Vec3& start, std::size_t* contacts) {
  auto m = base_model();
  RigidBody floor;
  floor.shape = shape;
  m->bodies.push_back(floor);
  World w(m);
  w.add_particle(0, 0.005, 0, start);
  double pen = 0.0;
  for (int i = 0; i < 2000; ++i) pen = std::max(pen, w.step().max_penetration);
  if (contacts) *contacts = w.contacts().size();
  EXPECT_LT(pen, 0.01 * 0.005);
  return (w.particles().position[0] - start).norm();
}

TEST(Engine, SphereRestsOnBoxMeshAndShell) {
  const double r = 0.005;
  EXPECT_LT(rest_on(geo::Box{Vec3(0.1, 0.02, 0.1)}, Vec3(0.01, 0.02 + r, 0.0), nullptr), 1e-6);
  // Mesh floor: 4 x 4 squares of two triangles each, at y = 0.
  std::vector<Vec3> v;
  std::vector<std::array<std::uint32_t, 3>> t;
  for (int i = 0; i <= 4; ++i)
    for (int k = 0; k <= 4; ++k) v.emplace_back(-0.1 + 0.05 * i, 0.0, -0.1 + 0.05 * k);
  for (std::uint32_t i = 0; i < 4; ++i)
    for (std::uint32_t k = 0; k < 4; ++k) {
      const std::uint32_t a = i * 5 + k, b = a + 5;
      t.push_back({a, a + 1, b});
      t.push_back({b, a + 1, b + 1});
    }
  auto mesh = std::make_shared<const geo::TriMesh>(v, t);
  std::size_t contacts = 0;
  EXPECT_LT(rest_on(mesh, Vec3(0.0, r, 0.0), &contacts), 1e-6);  // on a shared vertex
  EXPECT_EQ(contacts, 1u);
  // Inside a drum shell (R 0.16 m, wall 5 mm) resting at the bottom.
  EXPECT_LT(rest_on(geo::Cylinder{0.16, 0.15, 0.005}, Vec3(0.0, -0.155 + r, 0.0), nullptr), 1e-6);
}

// A frictionless sphere slides across a triangulated floor at constant speed:
// the shared edges are not bumps (speed kept within 1e-9 m/s, height within
// 1e-6 m).
TEST(Engine, SphereSlidesAcrossMeshEdgesWithoutBumps) {
  auto m = base_model({0.0});
  std::vector<Vec3> v;
  std::vector<std::array<std::uint32_t, 3>> t;
  for (int i = 0; i <= 10; ++i)
    for (int k = 0; k <= 2; ++k) v.emplace_back(-0.05 + 0.02 * i, 0.0, -0.02 + 0.02 * k);
  for (std::uint32_t i = 0; i < 10; ++i)
    for (std::uint32_t k = 0; k < 2; ++k) {
      const std::uint32_t a = i * 3 + k, b = a + 3;
      t.push_back({a, a + 1, b});
      t.push_back({b, a + 1, b + 1});
    }
  RigidBody floor;
  floor.shape = std::make_shared<const geo::TriMesh>(v, t);
  m->bodies.push_back(floor);
  World w(m);
  const double r = 0.002;
  w.add_particle(0, r, 0, Vec3(-0.04, r, 0.0013), Quat::Identity(), Vec3(0.5, 0, 0.02));
  for (int i = 0; i < 300; ++i) {
    w.step();
    EXPECT_NEAR(w.particles().velocity[0].head<1>()(0), 0.5, 1e-9);
    EXPECT_NEAR(w.particles().position[0].y(), r, 1e-6);
  }
}

}  // namespace
}  // namespace ces
