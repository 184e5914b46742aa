// Yielding surfaces (Material::compliance): a contact with one is a
// spring-dashpot in the contact problem, stepped by backward Euler. Checked
// against the spring's statics (a weight W on a spring of stiffness k
// sinks W / k; two in series, W (1/k1 + 1/k2)) and the linear
// spring-dashpot's restitution, with every solver.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "feed/shapes.hpp"
#include "nip.hpp"
#include "sim/world.hpp"
#include "support.hpp"

namespace ces {
namespace {

constexpr double kRadius = 0.001, kDensity = 2500.0;

double sphere_mass() { return kDensity * 4.0 / 3.0 * kPi * std::pow(kRadius, 3); }

struct Bench {
  double plane_stiffness = 1.0;                                       // N/m
  double sphere_stiffness = std::numeric_limits<double>::infinity();  // N/m
  double restitution = 0.0;
  double gravity = 9.81;  // m/s^2, along -y
  double step = 1e-3;
  SolverMethod method = SolverMethod::APGD;
  double ceiling = std::numeric_limits<double>::infinity();  // m: a rigid plane facing down
};

// A sphere of 1 mm on a plane of material "bristles", the plane the
// yielding one; the sphere too when its stiffness is finite.
std::unique_ptr<World> sphere_on_plane(const Bench& s, const Vec3& position, const Vec3& velocity) {
  auto m = std::make_shared<Model>();
  m->step = s.step;
  m->gravity = Vec3(0, -s.gravity, 0);
  const double sphere_compliance = std::isinf(s.sphere_stiffness) ? 0.0 : 1.0 / s.sphere_stiffness;
  m->materials = MaterialTable({{"grain", kDensity, 0.5, s.restitution, sphere_compliance},
                                {"bristles", 1000.0, 0.5, s.restitution, 1.0 / s.plane_stiffness}},
                               {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  m->bodies.push_back(test::ground_plane(Vec3::UnitY(), 1));
  if (std::isfinite(s.ceiling)) {
    m->bodies.push_back(test::ground_plane(-Vec3::UnitY(), 0));
    m->bodies.back().pose.position = Vec3(0, s.ceiling, 0);
  }
  m->solver.method = s.method;
  m->solver.max_iterations = 100000;
  m->solver.tolerance = 1e-10;
  auto w = std::make_unique<World>(m);
  w->add_particle(0, kRadius, 0, position);
  w->particles().velocity[0] = velocity;
  return w;
}

struct Rest {
  double sink = 0.0;       // m, the sphere's overlap with the plane at the end
  double worst_yield = 0;  // m, StepStats::max_yield over the run
  double worst_overlap = 0;
};

Rest settle(const Bench& s) {
  auto w = sphere_on_plane(s, Vec3(0, kRadius, 0), Vec3::Zero());
  Rest r;
  for (int i = 0; i < 400; ++i) {
    const StepStats& st = w->step();
    r.worst_yield = std::max(r.worst_yield, st.max_yield);
    r.worst_overlap = std::max(r.worst_overlap, st.max_penetration_relative);
  }
  r.sink = kRadius - w->particles().position[0].y();
  return r;
}

// Statics: 400 steps of 1 ms are 20 periods of the critically damped
// spring (2 pi sqrt(m/k) = 20 ms), so it has come to rest to far below the
// 1e-6 relative tolerance, which is then the solve's and rounding's. What
// the plane gives is reported as its yield, not as an overlap.
TEST(Yielding, WeightSinksASpringByWeightOverStiffness) {
  const double weight = sphere_mass() * 9.81;
  for (const SolverMethod method : {SolverMethod::APGD, SolverMethod::SPG, SolverMethod::PGS}) {
    Bench s;
    s.method = method;
    const Rest one = settle(s);
    EXPECT_NEAR(one.sink, weight / 1.0, 1e-6 * weight) << int(method);
    EXPECT_NEAR(one.worst_yield, one.sink, 0.05 * one.sink);
    EXPECT_EQ(one.worst_overlap, 0.0);
    s.plane_stiffness = 4.0;
    s.sphere_stiffness = 2.0;
    const Rest series = settle(s);
    EXPECT_NEAR(series.sink, weight * (1.0 / 4.0 + 1.0 / 2.0), 1e-6 * weight) << int(method);
  }
}

// The rebound speed of a sphere thrown at the plane at 0.2 m/s without
// gravity, over the speed it came in at: the spring-dashpot whose force
// never pulls gives restitution e exactly in continuous time (Schwager,
// Poeschel, Granular Matter 9(6), 2007); backward Euler damps by
// about h omega (0.03 at 0.1 ms and omega = 310 rad/s), so within 10 %.
// Below exp(-2) (e = 0 here) the damping is critical, and the rebound
// exp(-2) = 0.135.
double rebound(double e, SolverMethod method) {
  Bench s;
  s.restitution = e;
  s.gravity = 0.0;
  s.step = 1e-4;
  s.method = method;
  const double v0 = 0.2;
  auto w = sphere_on_plane(s, Vec3(0, kRadius + 0.5 * v0 * s.step, 0), Vec3(0, -v0, 0));
  for (int i = 0; i < 1000; ++i) w->step();  // five periods
  return w->particles().velocity[0].y() / v0;
}

TEST(Yielding, DampingGivesThePairsRestitution) {
  for (const SolverMethod method : {SolverMethod::APGD, SolverMethod::PGS}) {
    for (const double e : {0.3, 0.7}) EXPECT_NEAR(rebound(e, method), e, 0.1 * e) << e;
    EXPECT_NEAR(rebound(0.0, method), std::exp(-2.0), 0.1 * std::exp(-2.0));
  }
}

// A sphere pressed 0.8 radii into stiff bristles (1000 N/m), without
// gravity, under a rigid ceiling 0.3 radii above it: farther than its
// envelope at rest (a quarter of its radius), so the ceiling is not among
// the first step's contacts. The bristles throw it at their depth over
// h + c/k (the soft row's bias; c/k = 0.2 ms here), 0.66 mm in the step,
// which would take it 0.36 radii into the ceiling. It stops at the
// ceiling's surface (dynamics/unlisted_walls.hpp), within the overlap aim,
// and stays there, pressed on it by the bristles.
TEST(Yielding, ThrownAtAWallPastItsEnvelopeStopsAtItsSurface) {
  Bench s;
  s.plane_stiffness = 1000.0;
  s.gravity = 0.0;
  const double depth = 0.8 * kRadius;
  s.ceiling = 2.0 * kRadius - depth + 0.3 * kRadius;
  auto w = sphere_on_plane(s, Vec3(0, kRadius - depth, 0), Vec3::Zero());
  const StepStats& first = w->step();
  EXPECT_EQ(first.unlisted_wall_stops, 1u);
  double worst = 0.0;
  for (int i = 0; i < 100; ++i) worst = std::max(worst, w->step().max_wall_penetration_relative);
  const double aim = w->model().solver.overlap_aim();
  EXPECT_LE(worst, aim * (1.0 + 1e-6));
  EXPECT_NEAR(w->particles().position[0].y(), s.ceiling - kRadius, aim * kRadius);
  EXPECT_LT(w->particles().velocity[0].norm(), 1e-3);
}

// The reference machine's nip: grains carried up between the drum and a
// brush that touches it (zero gap, surfaces moving opposite at the nip),
// at the reference scene's 0.25 ms and 25 iterations: spheres of 0.5 mm
// riding the drum up into the nip at its surface speed, and flakes (19
// spheres, 1.2 mm wide) falling on edge into the wedge above it. Grains
// roll in place there, squeezed by the two surfaces.
struct Nip {
  double wall = 0.0;   // radii: the worst a grain went into a rigid surface
  double yield = 0.0;  // m: the most the brush gave
  std::size_t corrections = 0;  // wall rows the wall guard had to finish
};

Nip grains_in_the_nip(double brush_compliance) {
  auto m = std::make_shared<Model>();
  m->step = 0.25e-3;
  m->gravity = Vec3(0, -9.81, 0);
  m->materials = MaterialTable({{"grain", kDensity, 0.5, 0.0, 0.0},
                                {"steel", 7800.0, 0.5, 0.0, 0.0},
                                {"bristles", 1000.0, 0.9, 0.0, brush_compliance}},
                               {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  const feed::SphereList flake = feed::flake_spheres(0.2);
  m->shapes.push_back(make_particle_shape(flake.centers, flake.radii));
  m->solver.max_iterations = 25;
  m->solver.tolerance = 1e-6;
  const double omega = 70.0 * 2.0 * kPi / 60.0;
  test::add_drum_and_brush(*m, omega, 1, 2);
  World w(m);
  test::add_nip_grains(w, 1, omega);
  Nip nip;
  for (int i = 0; i < 800; ++i) {
    const StepStats& st = w.step();
    nip.wall = std::max(nip.wall, st.max_wall_penetration_relative);
    nip.yield = std::max(nip.yield, st.max_yield);
    nip.corrections += st.wall_corrections;
  }
  return nip;
}

// Rigid, the pair leaves no room: a solve cut at 25 iterations leaves
// grains inside a surface, and only the wall guard's sweeps hold them to
// the penetration tolerance, a tenth of a radius (at a large step it
// bounds them by half a radius:
// Engine.GrainsStayOutOfAZeroGapNipAtALargeStep). The reference brush's
// bristles yield (1.6 N/m): the grains part them, and the solve alone
// keeps them out of the steel to a tenth of a radius, the bound of the
// reference scene's targets, while the brush gives no more than the
// widest grain (1.2 mm).
TEST(Yielding, GrainsPartABrushThatTouchesTheDrum) {
  const Nip rigid = grains_in_the_nip(0.0);
  EXPECT_GT(rigid.corrections, 100u) << "the rigid nip no longer pinches: the test shows nothing";
  EXPECT_LE(rigid.wall, 0.1 + 1e-9) << "radii into a surface, with the guard";
  EXPECT_EQ(rigid.yield, 0.0);
  const Nip yielding = grains_in_the_nip(1.0 / 1.6);
  EXPECT_EQ(yielding.corrections, 0u) << "the yielding nip needed the wall guard";
  EXPECT_LE(yielding.wall, 0.1) << "radii into the drum";
  EXPECT_GT(yielding.yield, 0.0);
  EXPECT_LE(yielding.yield, 1.2e-3);
}

}  // namespace
}  // namespace ces
