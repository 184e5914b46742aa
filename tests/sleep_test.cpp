// Sleep (dynamics/sleep.hpp): particles at rest on a turning body ride it
// out of the solve, and wake where the awake physics would move them.
// Frame and helpers: separator_support.hpp.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "feed/shapes.hpp"
#include "separator_support.hpp"
#include "sim/world.hpp"

namespace ces::fields {
namespace {

using namespace test;

constexpr double kFriction = 0.5;
constexpr double kWidth = 3.4e-3, kAspect = 0.15;  // an FR-4 flake of 19 spheres
constexpr double kOmega = 1.0;                      // rad/s: a slow drum
const SleepSettings kSleep{true, 5e-3, 20e-3};

// A world with the turning drum and one flake lying flat on its top,
// carried with it; gravity only.
std::shared_ptr<Model> flake_model(double h, bool sleep) {
  auto m = make_model(h, {{kFr4, kFriction, ElectricalMaterial::insulator(kFr4Permittivity)}},
                      kFriction);
  m->gravity = Vec3(0, -kG, 0);
  const feed::SphereList f = feed::flake_spheres(kAspect);
  m->shapes.push_back(make_particle_shape(f.centers, f.radii));
  m->bodies.push_back(drum(kOmega));
  if (sleep) m->sleep = kSleep;
  return m;
}

void add_flat_flake(World& w, double theta) {
  const Model& m = w.model();
  const Vec3 x = on_drum(kDrumRadius + 0.5 * kAspect * kWidth + 1e-6, theta);
  const Quat flat =
      Quat::FromTwoVectors(shape_electrics(m.shapes.back()).face_normal, x.normalized());
  w.add_particle(int(m.shapes.size()) - 1, kWidth, 1, x, flat, carried_velocity(kOmega, x),
                 carried_spin(kOmega));
}

// Speed of particle 0 relative to the drum's surface under it.
double slip(const World& w) {
  const Particles& p = w.particles();
  return (p.velocity[0] - carried_velocity(kOmega, p.position[0])).norm();
}

// Where a carried particle can no longer be held with half the friction to
// spare (sleep's reserve) and with all of it (where it slides): the angle
// from the top at which its weight's pull along the drum, m g sin θ, is
// that share of the normal force m (g cos θ - ω² ρ). Bisection.
double release_angle(double share, double rho) {
  double lo = 0.0, hi = kPi / 2;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    const double normal = kG * std::cos(mid) - kOmega * kOmega * rho;
    const bool held = kG * std::sin(mid) <= share * kFriction * normal;
    (held ? lo : hi) = mid;
  }
  return lo;
}

// Where a flake released at θ_s has slid up to speed v on the drum: its
// slip grows at g sin θ - μ (g cos θ - ω² ρ) while the drum turns it on at
// ω (the Coriolis term, 2 ω v, is a thousandth of it). Integrated in 1e-6 s
// steps.
double slid_angle(double theta_s, double v, double rho) {
  const double dt = 1e-6;
  double theta = theta_s, speed = 0.0;
  while (speed < v) {
    speed += dt * (kG * std::sin(theta) -
                   kFriction * (kG * std::cos(theta) - kOmega * kOmega * rho));
    theta += kOmega * dt;
  }
  return theta;
}

struct Ride {
  double asleep_at = -1.0, woke_at = -1.0, slid_at = -1.0;  // θ, or -1: never
  double radius_drift = 0.0, turn_error = 0.0;              // while asleep
};

// Steps a flake from the top of the slow drum until it slides, and
// records where it fell asleep, woke and, once settled (slower than
// 0.1 mm/s on the drum), started to slide (faster than 1 mm/s).
Ride ride(bool sleep, double h) {
  const SingleThread one_thread;
  World w(flake_model(h, sleep));
  add_flat_flake(w, 0.0);
  Ride r;
  double rho = 0.0, theta = 0.0;
  bool settled = false;
  for (int i = 0; i * h < 1.0 && r.slid_at < 0.0; ++i) {
    const bool was_asleep = w.particles().asleep(0);
    w.step();
    const Vec3& x = w.particles().position[0];
    const bool asleep = w.particles().asleep(0);
    if (asleep && !was_asleep) r.asleep_at = theta_of(x), rho = x.norm();
    if (asleep && was_asleep) {
      r.radius_drift = std::max(r.radius_drift, std::abs(x.norm() - rho));
      r.turn_error = std::max(r.turn_error, std::abs(theta_of(x) - theta - kOmega * h));
    }
    if (!asleep && was_asleep) r.woke_at = theta_of(x);
    settled = settled || slip(w) < 1e-4;
    if (settled && !asleep && slip(w) > 1e-3) r.slid_at = theta_of(x);
    theta = theta_of(x);
  }
  return r;
}

// A flake lying on the slow drum's top, held by its weight and friction:
// it falls asleep within the sleep time of settling, rides the drum
// exactly (its distance from the axis to 1e-12 m, each step's turn ω h to
// 1e-12 rad), wakes within one step's turn of where its weight would take
// half the friction, and, awake, slides where the run that never sleeps
// does, both within 0.2° of where a block released where its weight takes
// all the friction (26.2° at μ = 0.5 and this drum) has slid up to 1 mm/s.
TEST(Sleep, FlakeOnATurningDrumSleepsAndWakesBeforeItWouldSlide) {
  const double h = 0.5e-3;
  const double rho = kDrumRadius + 0.5 * kAspect * kWidth;
  const Ride awake = ride(false, h), asleep = ride(true, h);
  EXPECT_LT(awake.asleep_at, 0.0);
  ASSERT_GE(asleep.asleep_at, 0.0);
  EXPECT_LT(asleep.asleep_at, kOmega * (kSleep.time + 0.05));
  EXPECT_LT(asleep.radius_drift, 1e-12);
  EXPECT_LT(asleep.turn_error, 1e-12);
  const double wake = release_angle(0.5, rho);
  EXPECT_GE(asleep.woke_at, wake);
  EXPECT_LE(asleep.woke_at, wake + kOmega * h + 1e-9);
  const double slide = slid_angle(release_angle(1.0, rho), 1e-3, rho);
  ASSERT_GT(awake.slid_at, 0.0);
  EXPECT_NEAR(asleep.slid_at, awake.slid_at, 0.2 * kDeg);
  EXPECT_NEAR(awake.slid_at, slide, 0.2 * kDeg);
}

// A grain (one sphere) on the drum has no face to bear a torque: once the
// drum has turned it off the very top, its weight rolls it, however much
// friction there is. Set on the top, where it is at rest for the sleep
// time and more, it never sleeps, and its run is the same to the bit as
// the one without sleep.
TEST(Sleep, AGrainRollsAndNeverSleeps) {
  const SingleThread one_thread;
  const double h = 0.5e-3, r = 0.5e-3;
  std::vector<Vec3> path[2];
  for (const bool sleep : {false, true}) {
    World w(flake_model(h, sleep));
    const Vec3 x = on_drum(kDrumRadius + r, 0.0);
    w.add_particle(kSphere, r, 1, x, Quat::Identity(), carried_velocity(kOmega, x),
                   carried_spin(kOmega));
    for (int i = 0; i * h < 0.2; ++i) {
      w.step();
      EXPECT_FALSE(w.particles().asleep(0));
      path[sleep].push_back(w.particles().position[0]);
    }
  }
  EXPECT_EQ(path[0], path[1]);
}

// A plate fixed half a flake's thickness above the drum, ahead of a
// sleeping flake, in its way: the flake wakes before the plate can touch
// it, and the plate's contacts with it are listed as for any awake
// particle.
TEST(Sleep, ASleeperWakesBeforeItReachesAnotherBody) {
  const SingleThread one_thread;
  const double h = 0.5e-3;
  auto m = flake_model(h, true);
  RigidBody plate;
  plate.name = "plate";
  plate.shape = geo::Box{Vec3(1e-3, 0.5e-3, 10e-3)};
  const double at = 6.0 * kDeg;
  plate.pose.position = on_drum(kDrumRadius + 0.5 * kAspect * kWidth + 0.5e-3, at);
  plate.pose.orientation = Quat(Eigen::AngleAxisd(-at, Vec3::UnitZ()));
  m->bodies.push_back(plate);
  World w(m);
  add_flat_flake(w, 0.0);
  bool slept = false, touched = false;
  const int plate_index = 2;  // the solver's index: after the one particle and the drum
  for (int i = 0; i * h < 0.2 && !touched; ++i) {
    w.step();
    slept = slept || w.particles().asleep(0);
    const Contacts& c = w.contacts();
    for (std::size_t k = 0; k < c.size(); ++k) touched = touched || c.body_a[k] == plate_index;
    if (touched) {
      EXPECT_FALSE(w.particles().asleep(0));
    }
  }
  EXPECT_TRUE(slept);
  EXPECT_TRUE(touched);
}

// A copper flake asleep on the top of the slow drum, in a uniform field of
// 200 kV/m along +y: it touches the grounded drum, so its charge is the
// one the field normal to the drum induces on a flake lying flat, which
// changes as the drum turns it. After 10° its charge is the awake run's
// (to 1e-6 of it); a charge frozen when it fell asleep would be off by
// 1.5 %.
TEST(Sleep, ASleepingCopperFlakeKeepsTheChargeItsTouchInduces) {
  const SingleThread one_thread;
  const std::vector<MaterialSpec> mats = {{kCopper, kFriction, ElectricalMaterial::conductor()}};
  const double h = 0.5e-3;
  const GridField::Axis axis{-1.0, 2.0, 2};
  const ElectricField uniform = std::make_shared<const GridField>(
      std::array{axis, axis, axis}, std::vector<Vec3>(8, Vec3(0, 2e5, 0)));
  double charge[2] = {0.0, 0.0};
  bool slept = false;
  for (const bool sleep : {false, true}) {
    auto m = make_model(h, mats, kFriction);
    m->gravity = Vec3(0, -kG, 0);
    const feed::SphereList f = feed::flake_spheres(kAspect);
    m->shapes.push_back(make_particle_shape(f.centers, f.radii));
    m->bodies.push_back(drum(kOmega));
    if (sleep) m->sleep = kSleep;
    World w(m);
    add_flat_flake(w, 0.0);
    w.set_electrostatics(electrostatics(uniform, mats));
    while (theta_of(w.particles().position[0]) < 10.0 * kDeg) {
      w.step();
      slept = slept || w.particles().asleep(0);
    }
    if (sleep) {
      EXPECT_TRUE(w.particles().asleep(0));
    }
    charge[sleep] = w.particles().charge[0];
  }
  EXPECT_TRUE(slept);
  EXPECT_NE(charge[0], 0.0);
  EXPECT_NEAR(charge[1], charge[0], 1e-6 * std::abs(charge[0]));
}

// The index of the particle with this id (the spatial order moves them).
std::size_t index_of(const World& w, std::uint64_t id) {
  const auto& ids = w.particles().id;
  return std::size_t(std::find(ids.begin(), ids.end(), id) - ids.begin());
}

// A bead three times the flake's mass strikes a sleeping flake at 0.5 m/s,
// 45° from the drum's normal: the blow along the drum is more than half
// the friction can hold, and wakes the flake. (Its weight resting on the
// flake does not: the drum bears it.)
TEST(Sleep, ANeighboursBlowWakesASleeper) {
  const SingleThread one_thread;
  const double h = 0.5e-3;
  auto m = flake_model(h, true);
  World w(m);
  add_flat_flake(w, 0.0);
  for (int i = 0; i * h < 0.05; ++i) w.step();
  ASSERT_TRUE(w.particles().asleep(0));
  const Vec3 x = w.particles().position[0];
  const double bead = 1.5e-3;
  const Vec3 above = x + x.normalized() * (bead + 0.5 * kAspect * kWidth + 0.2e-3);
  const Vec3 n = x.normalized(), along = Vec3::UnitZ().cross(n);
  const Vec3 blow = 0.5 * std::sqrt(0.5) * (along - n);
  const std::uint64_t id = w.add_particle(kSphere, bead, 1, above, Quat::Identity(),
                                          carried_velocity(kOmega, above) + blow);
  const Particles& p = w.particles();
  EXPECT_GT(p.mass[index_of(w, id)], 2.5 * p.mass[index_of(w, 0)]);
  bool woke = false;
  for (int i = 0; i * h < 0.01 && !woke; ++i) {
    w.step();
    woke = !p.asleep(index_of(w, 0));
  }
  EXPECT_TRUE(woke);
}

// The state of 240 flakes laid in two layers on the top of a drum turning
// at 3 rad/s, after 0.1 s on `threads` threads; how many slept at most,
// and how many woke.
struct RainedFlakes {
  std::vector<double> state;
  std::size_t most_asleep = 0, woke = 0;
};

RainedFlakes rained_flakes(int threads, bool flat_faces = false) {
  omp_set_num_threads(threads);
  const double h = 0.5e-3, omega = 3.0, width = 2e-3;
  auto m = make_model(h, {{kFr4, kFriction, ElectricalMaterial::insulator(kFr4Permittivity)}},
                      kFriction);
  m->gravity = Vec3(0, -kG, 0);
  m->solver.max_iterations = 50;
  const feed::SphereList f = feed::flake_spheres(0.25);
  m->shapes.push_back(make_particle_shape(f.centers, f.radii));
  m->bodies.push_back(drum(omega));
  m->sleep = kSleep;
  m->contact.flat_faces = flat_faces;
  World w(m);
  const Quat flat = Quat::FromTwoVectors(shape_electrics(m->shapes.back()).face_normal,
                                         Vec3::UnitY());
  for (int layer = 0; layer < 2; ++layer)
    for (int i = 0; i < 10; ++i)
      for (int k = 0; k < 12; ++k) {
        const double theta = ((i - 4.5) * 1.1 + 0.3 * layer) * width / kDrumRadius;
        const Vec3 x = on_drum(kDrumRadius + (0.125 + 0.26 * layer) * width + 1e-5, theta,
                               (k - 5.5) * 1.1 * width);
        const Quat q(Eigen::AngleAxisd(-theta, Vec3::UnitZ()) * flat);
        w.add_particle(int(m->shapes.size()) - 1, width, 1, x, q, carried_velocity(omega, x),
                       carried_spin(omega));
      }
  RainedFlakes out;
  std::vector<std::uint8_t> slept(240, 0);
  for (int step = 0; step * h < 0.1; ++step) {
    w.step();
    const Particles& p = w.particles();
    out.most_asleep = std::max(out.most_asleep, w.last_step().asleep);
    for (std::size_t i = 0; i < p.size(); ++i) {
      std::uint8_t& s = slept[p.id[i]];
      if (s == 1 && !p.asleep(i)) ++out.woke, s = 2;
      if (s == 0 && p.asleep(i)) s = 1;
    }
  }
  const Particles& p = w.particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    for (const Vec3* v : {&p.position[i], &p.velocity[i], &p.angular_velocity[i]})
      out.state.insert(out.state.end(), v->data(), v->data() + 3);
    out.state.push_back(p.at_rest[i] + p.carrier[i]);
  }
  omp_set_num_threads(omp_get_num_procs());
  return out;
}

// Flakes on the drum and on each other fall asleep and wake (pushed, or
// turned past where they are held) to the same bits on one thread and two.
TEST(Sleep, FlakesOnTheDrumSleepAndWakeToTheSameBitsOnAnyThreads) {
  const RainedFlakes one = rained_flakes(1), two = rained_flakes(2);
  EXPECT_GT(one.most_asleep, 60u);
  EXPECT_GT(one.woke, 30u);
  EXPECT_EQ(one.most_asleep, two.most_asleep);
  ASSERT_EQ(one.state.size(), two.state.size());
  EXPECT_EQ(0, std::memcmp(one.state.data(), two.state.data(), one.state.size() * sizeof(double)));
}

// The same with the flakes as plates (contact.flake_faces flat), which
// meet each other face on face and rim on rim.
TEST(Sleep, FlatFacedFlakesGiveTheSameBitsOnAnyThreads) {
  const RainedFlakes one = rained_flakes(1, true), two = rained_flakes(2, true);
  EXPECT_GT(one.most_asleep, 60u);
  EXPECT_EQ(one.most_asleep, two.most_asleep);
  ASSERT_EQ(one.state.size(), two.state.size());
  EXPECT_EQ(0, std::memcmp(one.state.data(), two.state.data(), one.state.size() * sizeof(double)));
  EXPECT_NE(one.state, rained_flakes(1).state);  // the plates are what met
}

}  // namespace
}  // namespace ces::fields
