// Engine checks against closed forms. Each test states its tolerance.
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>
#include <omp.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <thread>

#include "common/parallel.hpp"
#include "dynamics/adjacency.hpp"
#include "dynamics/ccp.hpp"
#include "sim/world.hpp"
#include "feed/shapes.hpp"
#include "nip.hpp"
#include "support.hpp"

namespace ces {
namespace {

constexpr double g0 = 9.81;

// "m0", "m1", ...: appended, not "m" + std::to_string(i), on which GCC 12
// warns falsely (-Wrestrict, GCC bug 105329).
std::string material_name(std::size_t i) {
  std::string name = "m";
  name += std::to_string(i);
  return name;
}

// A model with one material per entry of `frictions`, a unit sphere shape,
// and the given solver settings.
std::shared_ptr<Model> base_model(std::vector<double> frictions = {0.5}, double step = 1e-3) {
  auto m = std::make_shared<Model>();
  m->step = step;
  std::vector<Material> mats;
  for (std::size_t i = 0; i < frictions.size(); ++i)
    mats.push_back({material_name(i), 2500.0, frictions[i], 0.0});
  m->materials = MaterialTable(mats, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  m->solver.max_iterations = 500;
  m->solver.tolerance = 1e-10;
  return m;
}

// Uniform numbers in [-1, 1) from a 64-bit LCG: the same on every platform.
struct Uniform {
  std::uint64_t state;
  double operator()() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(state >> 11) * 0x1.0p-53 * 2.0 - 1.0;
  }
};

// ---------------------------------------------------------------- free flight

// Semi-implicit Euler: v_n = v0 + n h g, x_n = x0 + n h v0 + h^2 g n(n+1)/2.
// Tolerance: 1e-12 relative (rounding only).
TEST(Engine, FreeFallAndProjectileMatchDiscreteSolution) {
  auto m = base_model();
  World w(m);
  const Vec3 x0(0.1, 2.0, -0.3), v0(3.0, 4.0, 0.5);
  w.add_particle(0, 0.01, 0, x0, Quat::Identity(), v0);
  const int n = 1000;
  for (int i = 0; i < n; ++i) w.step();
  const double h = m->step;
  const Vec3 v = v0 + n * h * m->gravity;
  const Vec3 x = x0 + n * h * v0 + h * h * m->gravity * (n * (n + 1) / 2.0);
  EXPECT_LT((w.particles().velocity[0] - v).norm(), 1e-12 * v.norm());
  EXPECT_LT((w.particles().position[0] - x).norm(), 1e-12 * x.norm());
}

// ---------------------------------------------------------------- resting

// 10,000 steps of 1 ms: drift below 1e-6 m, penetration below 1 % of r.
TEST(Engine, SphereRestsOnPlaneWithoutDrift) {
  auto m = base_model();
  m->bodies.push_back(test::ground_plane());
  World w(m);
  const double r = 0.005;
  const Vec3 x0(0, r, 0);
  w.add_particle(0, r, 0, x0);
  double worst_pen = 0.0;
  for (int i = 0; i < 10000; ++i) worst_pen = std::max(worst_pen, w.step().max_penetration);
  EXPECT_LT((w.particles().position[0] - x0).norm(), 1e-6);
  EXPECT_LT(worst_pen, 0.01 * r);
}

// ---------------------------------------------------------------- friction

// Four equal spheres in a square, as one rigid raft, on a plane tilted by
// theta about z. Sticks for tan(theta) <= mu - 0.02 (displacement < 1e-6 m
// in 1 s); slides with a = g (sin - mu cos) within 2 % for tan >= mu + 0.02.
double raft_acceleration(double theta, double mu, double* displacement) {
  auto m = base_model({mu});
  const Vec3 n(-std::sin(theta), std::cos(theta), 0.0);
  m->bodies.push_back(test::ground_plane(n));
  const double r = 0.005;
  m->shapes.push_back(make_particle_shape(
      {Vec3(-1, 0, -1), Vec3(1, 0, -1), Vec3(-1, 0, 1), Vec3(1, 0, 1)}, {1, 1, 1, 1}));
  World w(m);
  // Raft lying flat on the incline: its local y along the incline normal.
  // The principal frame of the square has its flat axes first; orient so the
  // sphere centres are at height r above the plane.
  const Quat tilt(Eigen::AngleAxisd(theta, Vec3::UnitZ()));
  const ParticleShape& s = m->shapes[1];
  // Find the principal axis normal to the raft (largest moment).
  Eigen::Index normal_axis;
  s.unit_inertia.maxCoeff(&normal_axis);
  const Quat align = Quat::FromTwoVectors(Vec3::Unit(normal_axis), Vec3::UnitY());
  w.add_particle(1, r, 0, n * r, tilt * align);
  const Vec3 down_slope(-std::cos(theta), -std::sin(theta), 0.0);
  double v1 = 0.0, v2 = 0.0;
  const int steps = 1000;
  for (int i = 1; i <= steps; ++i) {
    w.step();
    if (i == 200) v1 = w.particles().velocity[0].dot(down_slope);
    if (i == steps) v2 = w.particles().velocity[0].dot(down_slope);
  }
  if (displacement) *displacement = (w.particles().position[0] - n * r).norm();
  return (v2 - v1) / (0.8);
}

TEST(Engine, RaftOnInclineSticksBelowFrictionAngle) {
  const double mu = 0.5;
  double displacement = 0.0;
  raft_acceleration(std::atan(mu - 0.02), mu, &displacement);
  EXPECT_LT(displacement, 1e-6);
}

TEST(Engine, RaftOnInclineSlidesWithCoulombAcceleration) {
  const double mu = 0.5;
  for (double tan_theta : {mu + 0.02, 0.8, 1.2}) {
    const double theta = std::atan(tan_theta);
    const double expected = g0 * (std::sin(theta) - mu * std::cos(theta));
    const double a = raft_acceleration(theta, mu, nullptr);
    EXPECT_NEAR(a, expected, 0.02 * expected) << "tan theta " << tan_theta;
  }
}

// Manifold reduction: a 5 x 5 raft of touching spheres lying on a surface
// touches it with 25 spheres; its four corners and the deepest contact are
// kept and hold it level. In the corner of an L-shaped mesh the wall's contacts,
// with another normal, are reduced on their own. 500 steps of 1 ms: the raft
// stays level within 1e-3 rad and sinks less than 1 % of r.
std::unique_ptr<World> raft_on(std::shared_ptr<Model> m, double r) {
  std::vector<Vec3> centres;
  for (int i = -2; i <= 2; ++i)
    for (int k = -2; k <= 2; ++k) centres.emplace_back(2.0 * i, 0.0, 2.0 * k);
  m->shapes.push_back(make_particle_shape(centres, std::vector<double>(centres.size(), 1.0)));
  auto w = std::make_unique<World>(m);
  Eigen::Index normal_axis;
  m->shapes[1].unit_inertia.maxCoeff(&normal_axis);
  w->add_particle(1, r, 0, Vec3(0, r, 0), Quat::FromTwoVectors(Vec3::Unit(normal_axis), Vec3::UnitY()));
  return w;
}

TEST(Engine, FlatRaftKeepsFourContactsAndStaysLevel) {
  const double r = 0.001;
  auto m = base_model({0.5});
  m->bodies.push_back(test::ground_plane());
  auto w = raft_on(m, r);
  w->step();
  const Contacts& c = w->contacts();
  ASSERT_GE(c.size(), 4u);
  ASSERT_LE(c.size(), 5u);
  int corners = 0;  // at (±4r, ±4r)
  for (std::size_t k = 0; k < c.size(); ++k)
    corners += std::abs(std::abs(c.point[k].x()) - 4 * r) < 1e-9 &&
               std::abs(std::abs(c.point[k].z()) - 4 * r) < 1e-9;
  EXPECT_EQ(corners, 4);
  for (int i = 0; i < 500; ++i) w->step();
  const Particles& p = w->particles();
  const Vec3 up = p.orientation[0] * Vec3::Unit(0);  // any in-plane axis stays horizontal
  EXPECT_LT(std::abs(up.y()), 1e-3);
  EXPECT_LT(r - p.position[0].y(), 0.01 * r);
}

TEST(Engine, RaftInMeshCornerKeepsContactsOnBothFaces) {
  const double r = 0.001;
  auto m = base_model({0.5});
  // Floor y = 0 for x > -5r and a wall x = -5r (normal +x), one mesh.
  const double x0 = -5 * r, big = 0.05;
  RigidBody corner;
  corner.name = "corner";
  corner.shape = std::make_shared<const geo::TriMesh>(
      std::vector<Vec3>{Vec3(x0, 0, -big), Vec3(big, 0, -big), Vec3(big, 0, big), Vec3(x0, 0, big),
                        Vec3(x0, big, -big), Vec3(x0, big, big)},
      std::vector<std::array<std::uint32_t, 3>>{{0, 2, 1}, {0, 3, 2}, {0, 4, 5}, {0, 5, 3}});
  m->bodies.push_back(corner);
  auto w = raft_on(m, r);
  w->step();
  std::size_t floor = 0, wall = 0;
  for (std::size_t k = 0; k < w->contacts().size(); ++k) {
    const Vec3& n = w->contacts().normal[k];
    if (std::abs(n.y()) > 0.99) ++floor;
    if (std::abs(n.x()) > 0.99) ++wall;
  }
  EXPECT_GE(floor, 4u);  // 25 reduced to the corners and the deepest
  EXPECT_LE(floor, 5u);
  EXPECT_EQ(wall, 5u);  // the five spheres of the edge row, at most five: all kept
  for (int i = 0; i < 500; ++i) w->step();
  EXPECT_LT(r - w->particles().position[0].y(), 0.01 * r);
  EXPECT_GT(w->particles().position[0].x(), -0.01 * r);
}

// A sphere launched sliding without spin ends rolling at 5/7 of its speed
// (angular momentum about the contact point is conserved). Tolerance 1 %.
// A sphere landing softly (0.02 m/s) on a plane while slipping at 0.75 m/s
// (a grain dropped on the turning drum) should stay on the plane: with
// restitution 0 nothing throws it up, and it slides under Coulomb friction
// until it rolls. The cone complementarity relaxation (Anitescu-Tasora)
// gives a sliding contact the normal velocity mu |v_t|: without the
// sliding release (dynamics/safeguards.cpp) the sphere hops at 0.19 m/s
// and rises 1.86 mm (1.9 radii) at the CES scenes' 0.5 ms step (the same
// at 1 ms).
// Tolerances: 1 % of r off the plane; rolling within two steps of the
// closed form.
TEST(Engine, SphereLandingWithSlipStaysOnPlane) {
  auto m = base_model({0.5}, 0.5e-3);
  m->bodies.push_back(test::ground_plane());
  World w(m);
  const double r = 0.001, mu = 0.5, g = 9.81, v0 = 0.75, vy = 0.02;
  w.add_particle(0, r, 0, Vec3(0, r, 0), Quat::Identity(), Vec3(v0, -vy, 0));
  double top = 0.0, rolling_at = -1.0;
  std::size_t releases = 0;
  for (int i = 1; i <= 800; ++i) {
    releases += w.step().sliding_releases;
    const Particles& p = w.particles();
    top = std::max(top, p.position[0].y() - r);
    const double slip = p.velocity[0].x() + p.angular_velocity[0].z() * r;
    if (rolling_at < 0.0 && slip < 1e-6) rolling_at = i * m->step;  // float frames: ~1e-8 left
  }
  EXPECT_LT(top, 0.01 * r);
  EXPECT_GT(releases, 0u);  // the release, not the solver, kept it down
  // Coulomb sliding: the landing impulse m vy takes (7/2) mu vy of slip at
  // once, then slip falls at (7/2) mu g until the sphere rolls.
  const double expected = (v0 - 3.5 * mu * vy) / (3.5 * mu * g);
  EXPECT_NEAR(rolling_at, expected, 2 * m->step) << "rolling from " << rolling_at << " s";
}

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
// spheres' rows are linear in the step's motion, so uncapped a sphere ended
// 0.66 radii inside the plane; capped (at a quarter radius of drift) 0.03.
// Bound: a quarter radius.
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

TEST(Engine, SlidingSphereEndsRollingAtFiveSevenths) {
  auto m = base_model({0.3});
  m->bodies.push_back(test::ground_plane());
  World w(m);
  const double r = 0.01, v0 = 1.0;
  w.add_particle(0, r, 0, Vec3(0, r, 0), Quat::Identity(), Vec3(v0, 0, 0));
  for (int i = 0; i < 500; ++i) w.step();  // slip ends at 2 v0 / (7 mu g) = 0.097 s
  const Particles& p = w.particles();
  EXPECT_NEAR(p.velocity[0].x(), 5.0 / 7.0 * v0, 0.01 * 5.0 / 7.0 * v0);
  EXPECT_NEAR(-p.angular_velocity[0].z() * r, p.velocity[0].x(), 1e-3 * v0);  // rolling
}

// ---------------------------------------------------------------- curved surface

// A frictionless sphere from the top of a fixed horizontal cylinder leaves
// it where cos(theta) = 2/3 + v0^2 / (3 g (R + r)). Tolerance 0.5 degree.
double release_angle(double v0) {
  auto m = base_model({0.0}, 1e-4);
  RigidBody drum;
  drum.shape = geo::Cylinder{0.1, 0.2, 0.0};
  m->bodies.push_back(drum);
  World w(m);
  const double R = 0.1, r = 0.005;
  w.add_particle(0, r, 0, Vec3(0, R + r, 0), Quat::Identity(), Vec3(v0, 0, 0));
  for (int i = 0; i < 200000; ++i) {
    w.step();
    const Vec3& x = w.particles().position[0];
    const double theta = std::atan2(x.x(), x.y());
    // Detached once the contact carries no load.
    double load = 0.0;
    for (std::size_t k = 0; k < w.contacts().size(); ++k) load += w.impulses()[std::ptrdiff_t(3 * k)];
    if (theta > 0.1 && load <= 0.0) return theta;
  }
  return -1.0;
}

TEST(Engine, FrictionlessSphereLeavesCylinderAtClosedFormAngle) {
  const double R = 0.1, r = 0.005;
  for (double v0 : {0.01, 0.3}) {
    const double expected = std::acos(2.0 / 3.0 + v0 * v0 / (3 * g0 * (R + r)));
    EXPECT_NEAR(release_angle(v0), expected, 0.5 * kPi / 180.0) << "v0 " << v0;
  }
}

// ---------------------------------------------------------------- impacts

// Head-on impact of unequal spheres, no gravity. Momentum to 1e-12
// relative; post-impact velocities within 1e-9 m/s of the textbook values.
void head_on(double e) {
  auto m = base_model({0.0});
  m->gravity.setZero();
  m->materials = MaterialTable({{"m", 1000.0, 0.0, e}}, {});
  m->contact.restitution_threshold = 1e-6;
  World w(m);
  const double r = 0.01;
  w.add_particle(0, r, 0, Vec3(0, 0, 0), Quat::Identity(), Vec3(1.0, 0, 0));
  w.add_particle(0, 2 * r, 0, Vec3(3.0005 * r, 0, 0), Quat::Identity(), Vec3(-0.5, 0, 0));
  const Particles& p = w.particles();
  const double m1 = p.mass[0], m2 = p.mass[1], u1 = 1.0, u2 = -0.5;
  const double momentum = m1 * u1 + m2 * u2;
  for (int i = 0; i < 20; ++i) w.step();
  const double v1 = p.velocity[0].x(), v2 = p.velocity[1].x();
  EXPECT_NEAR(m1 * v1 + m2 * v2, momentum, 1e-12 * std::abs(m1 * u1) + 1e-12 * std::abs(m2 * u2));
  const double cm = momentum / (m1 + m2);
  EXPECT_NEAR(v1, cm - e * m2 * (u1 - u2) / (m1 + m2), 1e-9);
  EXPECT_NEAR(v2, cm + e * m1 * (u1 - u2) / (m1 + m2), 1e-9);
}

TEST(Engine, HeadOnPlasticImpact) { head_on(0.0); }
TEST(Engine, HeadOnElasticImpact) { head_on(1.0); }

// ---------------------------------------------------------------- piles

// Three spheres touching on the ground, a fourth on top (a regular
// tetrahedron). Ground mu 0.5; between spheres the threshold is
// tan(phi/2) = 0.318 with sin(phi) = 1/sqrt(3): mu 0.4 holds (apex drops
// < 1 % of r in 1 s), mu 0.2 collapses (apex drops > 50 % of r).
double apex_drop(double mu_spheres) {
  auto m = base_model({0.5, 0.5});
  m->materials = MaterialTable({{"ground", 2500, 0.5, 0}, {"sphere", 2500, 0.5, 0}},
                               {{1, 1, mu_spheres, std::nullopt}});
  m->bodies.push_back(test::ground_plane());
  World w(m);
  const double r = 0.005;
  const double s = 2 * r / std::sqrt(3.0);  // circumradius of the base triangle
  for (int k = 0; k < 3; ++k) {
    const double a = 2 * kPi * k / 3;
    w.add_particle(0, r, 1, Vec3(s * std::cos(a), r, s * std::sin(a)));
  }
  const double top = r + 2 * r * std::sqrt(2.0 / 3.0);
  w.add_particle(0, r, 1, Vec3(0, top, 0));
  for (int i = 0; i < 1000; ++i) w.step();
  return top - w.particles().position[3].y();
}

TEST(Engine, TetrahedralPileHoldsWithEnoughFriction) { EXPECT_LT(apex_drop(0.4), 0.01 * 0.005); }
TEST(Engine, TetrahedralPileCollapsesWithLittleFriction) { EXPECT_GT(apex_drop(0.2), 0.5 * 0.005); }

// A sphere 1000 times heavier on a 5 x 5 layer of light spheres: penetration
// stays below 5 % of the radius with 100 APGD iterations per step.
TEST(Engine, HeavySphereOnLightLayerStaysOnTop) {
  auto m = base_model({0.5, 0.5});
  m->materials = MaterialTable({{"light", 1000, 0.5, 0}, {"heavy", 1e6, 0.5, 0}}, {});
  m->bodies.push_back(test::ground_plane());
  m->solver.max_iterations = 100;
  m->solver.tolerance = 1e-8;
  World w(m);
  const double r = 0.005;
  for (int i = -2; i <= 2; ++i)
    for (int k = -2; k <= 2; ++k) w.add_particle(0, r, 0, Vec3(2 * r * i, r, 2 * r * k));
  w.add_particle(0, r, 1, Vec3(r, r + std::sqrt(2.0) * r, r));  // in a pocket of four
  double worst = 0.0;
  for (int i = 0; i < 1000; ++i) worst = std::max(worst, w.step().max_penetration_relative);
  EXPECT_LT(worst, 0.05);
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

// ---------------------------------------------------------------- solvers

// Moreau's decomposition: x = Π_K(x) + Π_K°(x) with the two parts
// orthogonal, for the friction cone K and its polar K° = {mu |t| <= -n}.
// 1e5 random points over all four cases. Tolerance 1e-12 relative.
TEST(Engine, ConeProjectionIsMoreauDecomposition) {
  Uniform uniform{7};
  for (int i = 0; i < 100000; ++i) {
    const double mu = i % 10 == 0 ? 0.0 : 1.5 * (uniform() + 1.0) / 2.0;
    const Vec3 x(uniform(), uniform(), uniform());
    Vec3 p = x;
    project_cone(mu, p[0], p[1], p[2]);
    const Vec3 d = x - p;
    const double tol = 1e-12 * x.norm();
    ASSERT_LE(std::hypot(p[1], p[2]), mu * p[0] + tol) << "outside the cone";
    ASSERT_LE(mu * std::hypot(d[1], d[2]), -d[0] + tol) << "remainder outside the polar cone";
    ASSERT_NEAR(p.dot(d), 0.0, tol * x.norm()) << "parts not orthogonal";
  }
}


// The APGD kernel (CcpProblem::apgd_step, apgd_gradient: four contacts to a
// SIMD vector, the last block padded, on world rows) against the plain row
// operations in contact frames, through to_local and to_world, on a random
// problem: 4 bodies (one a wall), 13 contacts at random points and normals
// (lever arms off the normal, so every term of the Jacobian counts; two
// normals along -z and +z, where a tangent basis is most easily wrong),
// friction 0 on some, two yielding, and one bilateral row. The normals are stored in
// float, so the frame is orthonormal to about 1e-7: the tolerance is 1e-6
// of each quantity's scale. A wrong sign, term or case is of order 1.
TEST(Engine, ApgdKernelMatchesPlainOperations) {
  Uniform uniform{11};
  auto vec = [&] { return Vec3(uniform(), uniform(), uniform()); };
  SolverBodies B;
  B.resize(4);
  for (std::size_t i = 0; i < 4; ++i) {
    B.x[i] = 0.01 * vec();
    B.v[i] = B.v_free[i] = vec();
    B.w[i] = B.w_free[i] = 10.0 * vec();
    B.inv_mass[i] = i == 3 ? 0.0 : 1e3 * (1.5 + uniform());
    const Vec3 d = 1e7 * (Vec3::Constant(1.5) + 0.5 * vec());
    B.inv_inertia[i] = i == 3 ? Mat3::Zero() : Mat3(d.asDiagonal());
  }
  Contacts c;
  for (int k = 0; k < 13; ++k) {
    const int a = k % 3, b = k % 4 == 3 ? 3 : (a + 1 + k % 2) % 3;
    const Vec3 n = k == 11   ? Vec3(0, 0, -1)
                   : k == 12 ? Vec3(1e-5, 0, 1).normalized()
                             : vec().normalized();
    // Contacts 1 and 6 yield (their blocks of four take the spring's
    // term), the blocks from 8 on are rigid.
    const double compliance = k == 1 || k == 6 ? 1e-3 : 0.0;
    c.push(a, b, n, 0.01 * vec(), 1e-4 * uniform(), 0.001,
           {k % 5 == 0 ? 0.0 : 0.5 + 0.4 * uniform(), 0.0, compliance}, ContactKey{});
  }
  BilateralRow row;
  row.a = 0;
  row.lin_a = vec();
  row.ang_a = 0.01 * vec();
  row.bias = 0.1;
  CcpProblem p;
  p.assemble(c, B, {row}, 1e-3, ContactSettings{});
  const std::size_t m = p.row_count();
  ASSERT_EQ(m, 40u);
  // World rows, each with a spare past its end (RowBuffer::take).
  auto rows = [&] { return std::vector<double>(m + 1); };
  std::vector<double> x = rows(), x_old = rows(), x1 = rows(), gx = rows(), g_old = rows(),
                      g1 = rows(), y = rows(), gy = rows();
  for (std::size_t i = 0; i < m; ++i) {
    x[i] = uniform();
    x_old[i] = uniform();
    gx[i] = uniform();
    g_old[i] = uniform();
  }
  auto span = [&](std::vector<double>& v) { return Span(v.data(), m); };
  auto cspan = [&](const std::vector<double>& v) { return ConstSpan(v.data(), m); };
  auto scale_of = [&](const std::vector<double>& v) {
    double s = 0.0;
    for (std::size_t i = 0; i < m; ++i) s = std::max(s, std::abs(v[i]));
    return s;
  };
  // The reference: Π(y - step W gy) row by row in contact frames, in world
  // rows (a contact's weight is the same on its three rows, so W commutes
  // with the change of frame).
  auto plain_step = [&](const std::vector<double>& yw, const std::vector<double>& gw, double step) {
    std::vector<double> yl(m), gl(m), out(m), world = rows(), wg = rows();
    for (std::size_t i = 0; i < m; ++i) wg[i] = p.metric_weight(i) * gw[i];
    p.to_local(cspan(yw), yl);
    p.to_local(cspan(wg), gl);
    p.projected_step(yl, gl, step, out);
    p.to_world(out, span(world));
    return world;
  };
  auto expect_rows_near = [&](const std::vector<double>& got, const std::vector<double>& want) {
    const double tol = 1e-6 * std::max(scale_of(want), 1e-300);
    for (std::size_t i = 0; i < m; ++i) ASSERT_NEAR(got[i], want[i], tol) << i;
  };
  const double step = 0.3, ca = 1.7, cb = 0.7;
  for (std::size_t i = 0; i < m; ++i) {
    y[i] = ca * x[i] - cb * x_old[i];
    gy[i] = ca * gx[i] - cb * g_old[i];
  }
  const CcpProblem::Momentum momentum{ca, cb};
  CcpProblem::TrialSums t = p.apgd_step(x, x_old, span(x1), gx, g_old, momentum, step);
  expect_rows_near(x1, plain_step(y, gy, step));
  const CcpProblem::TrialSums t_trial = t;
  p.apgd_gradient(x1, span(g1), x, x_old, momentum, t, {});
  // The next trial made in the gradient's pass (solve_apgd's guess that x1
  // is accepted) is apgd_step's from x1, x, g1, gx to the bit, with and
  // without momentum, and the pass's own sums do not change.
  for (const CcpProblem::Momentum next : {CcpProblem::Momentum{1.4, 0.4}, CcpProblem::Momentum{}}) {
    std::vector<double> x2 = rows(), x2_step = rows(), g1_again = rows();
    CcpProblem::TrialSums t_again = t_trial;
    const CcpProblem::TrialSums ahead = p.apgd_gradient(
        x1, span(g1_again), x, x_old, momentum, t_again, {span(x2), cspan(gx), next, 0.2});
    const CcpProblem::TrialSums alone = p.apgd_step(x1, x, span(x2_step), g1, gx, next, 0.2);
    EXPECT_EQ(x2, x2_step);
    EXPECT_EQ(g1_again, g1);
    EXPECT_EQ(ahead.dd, alone.dd);
    EXPECT_EQ(ahead.dnd, alone.dnd);
    EXPECT_EQ(ahead.uphill, alone.uphill);
    EXPECT_EQ(t_again.dnd, t.dnd);
    EXPECT_EQ(t_again.res_sum, t.res_sum);
    EXPECT_GT(ahead.dd, 0.0);
  }
  // The gradient at x1 by the plain scatter and gather, in world rows.
  std::vector<double> x1_local(m), g_local(m), g = rows();
  p.to_local(cspan(x1), x1_local);
  p.gradient(x1_local, g_local);
  p.to_world(g_local, span(g));
  expect_rows_near(g1, g);
  // The sums, row by row; the residual from the plain residual(): a
  // contact's residual is a vector, its length the same in any frame.
  double dd = 0, dnd = 0, uphill = 0;
  for (std::size_t i = 0; i < m; ++i) {
    const double d = x1[i] - y[i];
    dd += d * d / p.metric_weight(i);
    dnd += d * (g[i] - gy[i]);
    uphill += gy[i] * (x1[i] - x[i]);
  }
  const double rms = p.residual(x1_local, g_local);
  EXPECT_NEAR(t.dd, dd, 1e-6 * dd);
  EXPECT_NEAR(t.dnd, dnd, 1e-6 * std::abs(dnd));
  EXPECT_NEAR(t.uphill, uphill, 1e-6 * std::abs(uphill));
  EXPECT_NEAR(std::sqrt(t.res_sum / double(m)), rms, 1e-6 * rms);
  EXPECT_GT(dd * std::abs(dnd) * rms, 0.0);  // nothing trivially zero
  // world_gradient: the same gradient at x1, without the kernel.
  std::vector<double> gw = rows();
  p.world_gradient(cspan(x1), span(gw));
  expect_rows_near(gw, g);
  // Without momentum y = x, gy = gx, and x_old, g_old are not read.
  const std::vector<double> nan(m + 1, std::numeric_limits<double>::quiet_NaN());
  t = p.apgd_step(x, cspan(nan), span(x1), gx, cspan(nan), {}, step);
  expect_rows_near(x1, plain_step(x, gx, step));
  p.apgd_gradient(x1, span(g1), x, cspan(nan), {}, t, {});
  EXPECT_TRUE(std::isfinite(t.dd + t.dnd + t.uphill + t.res_sum));
  // Blocks none of whose contacts slides (each sticks, separates or is
  // frictionless) take the projection's short path: a sticking contact
  // keeps its impulse to the bit, a separating one goes to zero.
  std::vector<double> zero = rows(), local(m);
  for (std::size_t k = 0; 3 * k < m - 1; ++k) {
    local[3 * k] = k % 3 == 0 ? -1.0 : 1.0;  // friction >= 0.1: |x_t| <= 0.071 sticks
    local[3 * k + 1] = 0.05 * uniform();
    local[3 * k + 2] = 0.05 * uniform();
  }
  p.to_world(local, span(x));
  t = p.apgd_step(x, cspan(nan), span(x1), zero, cspan(nan), {}, step);
  expect_rows_near(x1, plain_step(x, zero, step));
  int kept = 0, cleared = 0;
  for (std::size_t k = 0; 3 * k < m - 1; ++k) {
    const bool same =
        x1[3 * k] == x[3 * k] && x1[3 * k + 1] == x[3 * k + 1] && x1[3 * k + 2] == x[3 * k + 2];
    const bool none = x1[3 * k] == 0.0 && x1[3 * k + 1] == 0.0 && x1[3 * k + 2] == 0.0;
    kept += same;
    cleared += none;
  }
  EXPECT_GT(kept, 3);
  EXPECT_GT(cleared, 2);  // the separating ones (the frictionless pressing keep only their normal)
}

// A 10-layer stack (3 x 3 spheres per layer) solved from rest without warm
// start: APGD needs fewer iterations than projected Gauss-Seidel to reach the
// same residual tolerance. Counts, not times.
int stack_iterations(SolverMethod method) {
  auto m = base_model({0.3});
  m->bodies.push_back(test::ground_plane());
  m->solver.method = method;
  m->solver.max_iterations = 5000;
  m->solver.tolerance = 1e-5;
  m->solver.warm_start = false;
  World w(m);
  const double r = 0.005;
  for (int layer = 0; layer < 10; ++layer)
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k)
        w.add_particle(0, r, 0, Vec3(2 * r * i, r + 2 * r * layer, 2 * r * k));
  const StepStats& s = w.step();
  EXPECT_TRUE(s.solver.converged);
  return s.solver.iterations;
}

// A contact problem with a NaN in it (the spin of a dynamic box a sphere
// rests on; a NaN on the particle would leave it without contacts, its
// envelope being NaN): every solver reports a NaN residual and no
// convergence, where APGD and SPG used to report 0 for an iterate they
// never measured.
TEST(Engine, SolversReportNonFiniteResidual) {
  for (const SolverMethod method : {SolverMethod::APGD, SolverMethod::SPG, SolverMethod::PGS}) {
    auto m = base_model();
    RigidBody box;
    box.kind = BodyKind::Dynamic;
    box.shape = geo::Box{Vec3(0.05, 0.01, 0.05)};
    box.pose.position = Vec3(0, -0.01, 0);
    box.mass = 1.0;
    m->bodies.push_back(box);
    m->solver.method = method;
    World w(m);
    const double r = 0.005;
    w.add_particle(0, r, 0, Vec3(0, r, 0));
    w.bodies().angular_velocity[0] = Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0);
    const StepStats& s = w.step();
    EXPECT_GE(s.contacts, 1u) << int(method);
    EXPECT_TRUE(std::isnan(s.solver.residual)) << int(method) << ": " << s.solver.residual;
    EXPECT_FALSE(s.solver.converged) << int(method);
  }
}

// APGD's metric (solve_apgd) gives each contact a step scaled to its own
// block of N, so decoupled contacts converge alike whatever their masses:
// 25 spheres at rest on the ground, densities 10 to 1e5 kg/m^3, one step
// from a cold start to 1e-8 m/s: 11 iterations. With one step for all
// (set by the lightest, as before the metric) it had not converged after
// 500.
TEST(Engine, ApgdConvergesAlikeAcrossMassRatios) {
  auto m = base_model();
  std::vector<Material> mats;
  for (int i = 0; i < 5; ++i)
    mats.push_back({material_name(i), std::pow(10.0, 1 + i), 0.5, 0.0});
  m->materials = MaterialTable(mats, {});
  m->bodies.push_back(test::ground_plane());
  m->solver.warm_start = false;
  m->solver.tolerance = 1e-8;
  World w(m);
  const double r = 0.002;
  for (int i = 0; i < 25; ++i) w.add_particle(0, r, i % 5, Vec3(3 * r * i, r, 0));
  const StepStats& s = w.step();
  ASSERT_EQ(s.contacts, 25u);
  EXPECT_TRUE(s.solver.converged);
  EXPECT_LE(s.solver.iterations, 40);
  RecordProperty("iterations", s.solver.iterations);
}

// The metric's weight is 1 / (a bound on the largest eigenvalue of the
// contact's 3x3 block of N in world rows, sum over its bodies of
// m^-1 1 + [r]x I^-1 [r]x^T): checked against the block's eigenvalues,
// computed here, for random anisotropic bodies (a bound; float rounding:
// 1e-6), and equal to them for spheres, where the bound is exact.
TEST(Engine, ApgdMetricBoundsEachContactBlock) {
  Uniform uniform{5};
  auto vec = [&] { return Vec3(uniform(), uniform(), uniform()); };
  SolverBodies B;
  B.resize(5);
  for (std::size_t i = 0; i < 5; ++i) {
    B.x[i] = 0.01 * vec();
    B.inv_mass[i] = i == 4 ? 0.0 : 1e3 * (1.5 + uniform());
    const Mat3 R = Quat(uniform(), uniform(), uniform(), uniform()).normalized().toRotationMatrix();
    const Vec3 d = i < 2 ? Vec3(Vec3::Constant(2e7)) : Vec3(1e7 * (Vec3::Constant(1.5) + vec()));
    B.inv_inertia[i] = i == 4 ? Mat3::Zero() : Mat3(R * d.asDiagonal() * R.transpose());
  }
  Contacts c;
  for (int k = 0; k < 20; ++k) {
    const int a = k % 4, b = k % 3 == 0 ? 4 : (a + 1) % 4;
    c.push(a, b, vec().normalized(), 0.01 * vec(), 0.0, 0.001, {0.5, 0.0}, ContactKey{});
  }
  CcpProblem p;
  p.assemble(c, B, {}, 1e-3, ContactSettings{});
  auto part = [&](int body, const Vec3& r) -> Mat3 {
    const auto u = std::size_t(body);
    Mat3 rx;
    rx << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
    return B.inv_mass[u] * Mat3::Identity() + rx * B.inv_inertia[u] * rx.transpose();
  };
  for (std::size_t k = 0; k < c.size(); ++k) {
    const int a = c.body_a[k], b = c.body_b[k];
    const Mat3 block =
        part(a, c.point[k] - B.x[std::size_t(a)]) + part(b, c.point[k] - B.x[std::size_t(b)]);
    const double lambda = Eigen::SelfAdjointEigenSolver<Mat3>(block).eigenvalues().maxCoeff();
    const double bound = 1.0 / p.metric_weight(3 * k);
    EXPECT_LE(lambda, bound * (1.0 + 1e-6)) << k;
    if (a < 2 && (b < 2 || b == 4)) {  // spheres
      EXPECT_NEAR(bound, lambda, 1e-6 * lambda) << k;
    }
    EXPECT_EQ(p.metric_weight(3 * k), p.metric_weight(3 * k + 2));
  }
}

TEST(Engine, ApgdBeatsGaussSeidelOnStack) {
  const int apgd = stack_iterations(SolverMethod::APGD);
  const int pgs = stack_iterations(SolverMethod::PGS);
  const int spg = stack_iterations(SolverMethod::SPG);
  RecordProperty("apgd", apgd);
  RecordProperty("pgs", pgs);
  RecordProperty("spg", spg);
  EXPECT_LT(apgd, pgs);
}

// ---------------------------------------------------------------- determinism

std::vector<double> pile_state(int threads) {
  omp_set_num_threads(threads);
  auto m = base_model({0.4});
  m->solver.max_iterations = 50;
  m->solver.tolerance = 1e-8;
  m->bodies.push_back(test::ground_plane());
  for (const Vec3& n : {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)}) {
    RigidBody wall = test::ground_plane(n);
    wall.shape = geo::Plane{n, -0.03};
    m->bodies.push_back(wall);
  }
  World w(m);
  const double r = 0.002;
  int count = 0;
  for (int layer = 0; count < 500; ++layer)
    for (int i = 0; i < 10 && count < 500; ++i)
      for (int k = 0; k < 10 && count < 500; ++k, ++count)
        w.add_particle(0, r * (1.0 + 0.1 * ((i + k + layer) % 3)), 0,
                       Vec3(-0.025 + 0.0052 * i + 0.0003 * (layer % 2), r + 0.0055 * layer,
                            -0.025 + 0.0052 * k));
  for (int i = 0; i < 1000; ++i) w.step();
  std::vector<double> state;
  const Particles& p = w.particles();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (const Vec3* v : {&p.position[i], &p.velocity[i], &p.angular_velocity[i]})
      state.insert(state.end(), v->data(), v->data() + 3);
  omp_set_num_threads(omp_get_num_procs());
  return state;
}

TEST(Engine, PileIsBitwiseIdenticalAcrossRunsAndThreads) {
  const auto a = pile_state(1), b = pile_state(1), c = pile_state(2);
  ASSERT_EQ(a.size(), c.size());
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(a.data(), c.data(), a.size() * sizeof(double)));
}

// for_each_chunk (common/parallel.hpp), which the solver's passes run on:
// every chunk runs exactly once on 1 to 3 threads, and when one thread is
// slow (it sleeps 1 ms in each of its chunks) the others take over what is
// left of its share. A static schedule leaves it its whole share (500 of
// 1000 chunks at 2 threads): here it keeps a few, and fewer than half
// unless the fast thread is kept off its core for 250 ms.
TEST(Engine, EveryChunkRunsOnceAndASlowThreadsShareIsTakenOver) {
  constexpr std::size_t kChunks = 1000;
  for (const int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    std::vector<std::atomic<int>> runs(kChunks);
    std::atomic<std::size_t> slow_ran{0};
    for_each_chunk(kChunks, true, [&](std::size_t c) {
      runs[c].fetch_add(1);
      if (threads > 1 && omp_get_thread_num() == 1) {
        slow_ran.fetch_add(1);
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
    for (std::size_t c = 0; c < kChunks; ++c) ASSERT_EQ(runs[c].load(), 1) << c << ", " << threads;
    if (threads > 1) {
      EXPECT_LT(slow_ran.load(), kChunks / threads / 2) << threads << " threads";
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

// The helpers the step's formerly serial passes run on (common/parallel.hpp),
// against their serial definitions, on 1 to 3 threads and on sizes that
// are and are not whole blocks.
TEST(Engine, ParallelScanSelectAndRunChunksMatchTheirSerialDefinitions) {
  for (const int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    for (const std::size_t n : {std::size_t(0), std::size_t(5), std::size_t(4096), std::size_t(30001)}) {
      std::vector<std::uint64_t> v(n), expected(n);
      std::uint64_t sum = 0;
      for (std::size_t i = 0; i < n; ++i) {
        v[i] = (i * 7919) % 13;
        expected[i] = sum;
        sum += v[i];
      }
      exclusive_scan(v);
      EXPECT_EQ(v, expected) << n << " items, " << threads << " threads";
      std::vector<std::uint32_t> picked, serial;
      auto keep = [](std::size_t i) { return i % 3 == 0 || i % 7 == 1; };
      for (std::size_t i = 0; i < n; ++i)
        if (keep(i)) serial.push_back(std::uint32_t(i));
      select_in_order(n, keep, picked);
      EXPECT_EQ(picked, serial) << n << " items, " << threads << " threads";
      // Runs of 1 to 9 equal labels: each item once, each run in one chunk.
      std::vector<std::size_t> label(n);
      for (std::size_t i = 1; i < n; ++i) label[i] = label[i - 1] + (i % 9 == (i / 9) % 9);
      std::vector<std::atomic<int>> seen(n);
      std::vector<std::atomic<std::size_t>> chunk_of(n + 1);
      auto same = [&](std::size_t a, std::size_t b) { return label[a] == label[b]; };
      for_each_run_chunk(n, 100, same, [&](std::size_t begin, std::size_t end) {
        for (std::size_t i = begin; i < end; ++i) {
          seen[i].fetch_add(1);
          chunk_of[label[i]].store(begin);
        }
      });
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_EQ(seen[i].load(), 1) << i;
        if (i > 0 && same(i - 1, i)) {
          ASSERT_LE(chunk_of[label[i]].load(), i - 1) << "run cut at " << i;
        }
      }
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

// The body -> contact lists, built by shares of the contacts in parallel,
// are each body's contacts in contact order whatever the thread count;
// bodies not listed (infinite mass) get none.
TEST(Engine, ContactAdjacencyIsEachBodysContactsInOrderOnAnyThreads) {
  const std::size_t bodies = 1000, contacts = 20000;
  std::vector<std::int32_t> a(contacts), b(contacts);
  std::uint64_t state = 12345;
  auto next = [&] { return state = state * 6364136223846793005ULL + 1442695040888963407ULL; };
  for (std::size_t k = 0; k < contacts; ++k) {
    a[k] = std::int32_t(next() >> 33) % std::int32_t(bodies);
    b[k] = std::int32_t(next() >> 33) % std::int32_t(bodies);
  }
  auto listed = [](std::int32_t i) { return i % 10 != 0; };
  std::vector<std::vector<std::uint32_t>> expected(bodies);
  for (std::size_t k = 0; k < contacts; ++k) {
    if (listed(a[k])) expected[std::size_t(a[k])].push_back(std::uint32_t(k << 1));
    if (listed(b[k])) expected[std::size_t(b[k])].push_back(std::uint32_t(k << 1 | 1));
  }
  for (const int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    ContactAdjacency adj;
    for (int round = 0; round < 2; ++round) {  // again on the kept scratch
      adj.build(a, b, bodies, listed);
      ASSERT_EQ(adj.offset.size(), bodies + 1);
      for (std::size_t i = 0; i < bodies; ++i) {
        const std::vector<std::uint32_t> got(adj.entry.begin() + adj.offset[i],
                                             adj.entry.begin() + adj.offset[i + 1]);
        ASSERT_EQ(got, expected[i]) << "body " << i << ", " << threads << " threads";
      }
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

// ---------------------------------------------------------------- spatial order

// Reordering moves every per-particle array together, and the periodic
// Morton sort leaves neighbours adjacent: after it, particles on a line
// spawned in shuffled order come out in order along the line.
TEST(Engine, SpatialReorderMovesWholeParticles) {
  auto m = base_model();
  m->gravity = Vec3::Zero();
  m->reorder_interval = 1;
  m->reorder_min_particles = 0;
  World w(m);
  const int n = 50;
  for (int k = 0; k < n; ++k) {
    const int slot = (k * 17) % n;  // a shuffle of 0..n-1
    w.add_particle(0, 0.001, 0, Vec3(0.01 * slot, 0, 0), Quat::Identity(), Vec3(0, 0, 1e-3 * slot));
  }
  w.step();
  const Particles& p = w.particles();
  for (int j = 0; j < n; ++j) {
    const auto u = std::size_t(j);
    const int slot = int(std::lround(p.position[u].x() / 0.01));
    EXPECT_EQ(slot, j) << "not in order along the line";
    EXPECT_EQ(p.id[u], std::uint64_t((slot * 3) % n)) << "id did not move with its particle";  // 17 * 3 = 1 mod 50
    EXPECT_DOUBLE_EQ(p.velocity[u].z(), 1e-3 * slot);
    EXPECT_DOUBLE_EQ(p.mass[u], p.mass[0]);
  }
}

// The warm start finds last step's impulses by contact key after the
// spatial reorder has made particle-index order (the contacts' order)
// unlike key (id) order: a 4-layer stack added in shuffled order and
// reordered every step needs, once settled, under half the iterations per
// step that the same stack solved cold needs (warm 7, cold 31 on average
// at this tolerance; with the lookup broken, both 31).
TEST(Engine, WarmStartCarriesImpulsesAcrossSpatialReorder) {
  auto iterations = [](bool warm, bool& keys_unsorted) {
    auto m = base_model();
    m->bodies.push_back(test::ground_plane());
    m->solver.tolerance = 1e-6;
    m->solver.warm_start = warm;
    m->reorder_interval = 1;
    m->reorder_min_particles = 0;
    World w(m);
    const double r = 0.005;
    const int n = 36;
    for (int k = 0; k < n; ++k) {
      const int slot = (k * 17) % n, layer = slot / 9, i = slot % 3, j = slot / 3 % 3;
      w.add_particle(0, r, 0, Vec3(2 * r * i, r + 2 * r * layer, 2 * r * j));
    }
    int total = 0;
    for (int step = 0; step < 40; ++step) {
      const StepStats& s = w.step();
      if (step >= 20) total += s.solver.iterations;
    }
    const std::vector<ContactKey>& keys = w.contacts().key;
    keys_unsorted = !std::is_sorted(keys.begin(), keys.end());
    return total;
  };
  bool warm_unsorted = false, cold_unsorted = false;
  const int warm = iterations(true, warm_unsorted), cold = iterations(false, cold_unsorted);
  EXPECT_TRUE(warm_unsorted) << "the keys came in key order: the test misses its case";
  EXPECT_LT(2 * warm, cold) << "warm " << warm << ", cold " << cold << " iterations in 20 steps";
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

}  // namespace
}  // namespace ces
