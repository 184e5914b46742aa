// The separator's force stages in the World (fields/stages.hpp) against the
// closed forms of docs/physics.md §4–§5: corona charging, charge decay,
// pinning by the image force, the brush, and the forces acting in the step
// they are computed with charges frozen in flight. Each test states its
// tolerance and assumptions.
//
// Frame: drum axis = z through the origin, gravity −y. The drum turns
// clockwise seen from +z, so its top moves toward +x, where the electrode
// is (docs/physics.md §2); θ is measured from the top in the direction of rotation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "fields/electrostatics.hpp"
#include "separator_support.hpp"
#include "sim/world.hpp"

namespace ces::fields {
namespace {

// The separator tests' shared machine, materials and closed forms.
using namespace test;

// --------------------------------------------------------------- charging --

// FR-4 spheres (d = 1 mm) resting on a still drum under the reference field.
// Friction 0.5 holds them up to 26° from the top; the field and image force
// only press them harder onto the drum.
constexpr double kFr4Radius = 0.5e-3;

struct RestingFr4 {
  std::shared_ptr<Model> model;
  std::vector<MaterialSpec> materials;
};

RestingFr4 resting_fr4(const std::vector<double>& decay_times) {
  std::vector<MaterialSpec> mats;
  for (double tau : decay_times)
    mats.push_back({kFr4, 0.5, ElectricalMaterial::insulator(kFr4Permittivity, tau)});
  auto m = make_model(1e-3, mats);
  m->bodies.push_back(drum(0.0));
  return {m, mats};
}

void add_on_drum(World& w, int material, double theta) {
  w.add_particle(kSphere, kFr4Radius, material, on_drum(kDrumRadius + kFr4Radius, theta));
}

// Pauthenier's law in a corona zone over the drum top, with the field model's
// |E| at the particle (0.68 kV/cm: τ_c = 24 ms at J = 1e-4 A/m²), sampled
// every 10 ms for 0.1 s against Q_s t/(t + τ_c) from docs/physics.md §5 written out.
// A particle 20° from the top, outside the zone, stays neutral. Tolerance
// 1 % of Q(t) (the stage's update is exact for a constant field; the
// particle moves by less than 1 µm, so E does not change measurably).
TEST(Corona, PauthenierGrowthInZone) {
  auto [m, mats] = resting_fr4({kNoDecay});
  World w(m);
  add_on_drum(w, 1, 0.0);
  add_on_drum(w, 1, 20.0 * kDeg);
  ElectrostaticsSpec spec = electrostatics(reference_field(), mats);
  CoronaZone zone;
  zone.angle_begin = 80.0 * kDeg;
  zone.angle_end = 100.0 * kDeg;
  zone.depth = 5e-3;
  zone.current_density = 1e-4;
  spec.corona = {zone};
  w.set_electrostatics(spec);
  const double e = field_at(reference_field(), w.particles().position[0]).norm();
  const double p = 3.0 * kFr4Permittivity / (kFr4Permittivity + 2.0);
  const double saturation = -4.0 * kPi * kEps0 * kFr4Radius * kFr4Radius * p * e;  // negative ions
  const double tau_c = 4.0 * kEps0 * e / 1e-4;
  for (int i = 1; i <= 100; ++i) {
    w.step();
    if (i % 10 != 0) continue;
    const double t = i * m->step;
    const double expected = saturation * t / (t + tau_c);
    EXPECT_NEAR(w.particles().charge[0], expected, 0.01 * std::abs(expected)) << "t = " << t;
  }
  EXPECT_EQ(w.particles().charge[1], 0.0);
}

// The seed's instant charging: Q_s of the zone's field after one step, and
// no further change. Tolerance 1e-12 relative.
TEST(Corona, SaturationModeChargesOnEntry) {
  auto [m, mats] = resting_fr4({kNoDecay});
  World w(m);
  add_on_drum(w, 1, 0.0);
  ElectrostaticsSpec spec = electrostatics(reference_field(), mats);
  CoronaZone zone = saturation_zone();
  zone.ion_sign = 1.0;
  spec.corona = {zone};
  w.set_electrostatics(spec);
  const double p = 3.0 * kFr4Permittivity / (kFr4Permittivity + 2.0);
  const double saturation = 4.0 * kPi * kEps0 * kFr4Radius * kFr4Radius * p * 4.13e5;
  w.step();
  EXPECT_NEAR(w.particles().charge[0], saturation, 1e-12 * saturation);
  for (int i = 0; i < 10; ++i) w.step();
  EXPECT_NEAR(w.particles().charge[0], saturation, 1e-12 * saturation);
}

// Charge relaxation Q0 exp(−t/τ) with τ = 50 ms, every 10 ms for 0.2 s;
// τ = 0 and τ = ∞ both mean no decay. Tolerance 1 % (the update is exact;
// rounding only).
TEST(Decay, ChargedInsulatorRelaxesExponentially) {
  const double tau = 0.05, q0 = -2e-11;
  auto [m, mats] = resting_fr4({tau, 0.0, kNoDecay});
  World w(m);
  add_on_drum(w, 1, 0.0);
  add_on_drum(w, 2, 10.0 * kDeg);
  add_on_drum(w, 3, -10.0 * kDeg);
  for (double& q : w.particles().charge) q = q0;
  w.set_electrostatics(electrostatics(reference_field(), mats));
  for (int i = 1; i <= 200; ++i) {
    w.step();
    if (i % 10 != 0) continue;
    const double expected = q0 * std::exp(-i * m->step / tau);
    EXPECT_NEAR(w.particles().charge[0], expected, 0.01 * std::abs(expected))
        << "t = " << i * m->step;
  }
  EXPECT_EQ(w.particles().charge[1], q0);
  EXPECT_EQ(w.particles().charge[2], q0);
}

// ----------------------------------------------------------------- pinning --

// An FR-4 sphere (d = 1 mm) at the bottom of the drum turning at 44.8 rpm,
// carried at drum speed. There the net outward force is largest over the
// whole turn, m (ω² ρ + g), ρ = R + r; the image force needs
// Q* = √(m (ω² ρ + g) 4π ε0 εr (2r)²) to hold it. At 1.05 Q* (image force
// 10 % above the threshold) it stays within 10 µm of the drum for a whole
// turn and is still carried at the end (single steps may carry no load
// while the start settles); at 0.95 Q* it is 1 mm off within 50 ms.
// Assumptions: no electric field (the test isolates the image force), no
// rolling (infinite inertia, as a flake), friction 5 (no slip needed here).
struct PinRun {
  double max_gap;  // largest centre distance beyond R + r, m
  bool carried_at_end;
};

PinRun pin_run(double charge_over_threshold, double duration) {
  const double omega = rpm(44.8), rho = kDrumRadius + kFr4Radius;
  const std::vector<MaterialSpec> mats = {
      {kFr4, 5.0, ElectricalMaterial::insulator(kFr4Permittivity)}};
  auto m = make_model(1e-3, mats, 5.0);
  m->bodies.push_back(drum(omega));
  World w(m);
  const Vec3 x0 = on_drum(rho, kPi);
  w.add_particle(kSphere, kFr4Radius, 1, x0, Quat::Identity(), carried_velocity(omega, x0),
                 carried_spin(omega));
  w.particles().inv_inertia[0].setZero();
  const double outward = w.particles().mass[0] * (omega * omega * rho + kG);
  const double threshold =
      std::sqrt(outward * 4.0 * kPi * kEps0 * kEpsAir * 4.0 * kFr4Radius * kFr4Radius);
  w.particles().charge[0] = charge_over_threshold * threshold;
  w.set_electrostatics(electrostatics(no_field(), mats));
  PinRun run{0.0, false};
  for (int i = 0; i * m->step < duration; ++i) {
    w.step();
    run.max_gap = std::max(run.max_gap, w.particles().position[0].head<2>().norm() - rho);
  }
  run.carried_at_end = drum_load(w, 0) > 0.0;
  return run;
}

TEST(Pinning, Fr4StaysPinnedAboveImageForceThresholdAndFliesBelow) {
  const PinRun pinned = pin_run(1.05, 2.0 * kPi / rpm(44.8));
  EXPECT_LT(pinned.max_gap, 1e-5);
  EXPECT_TRUE(pinned.carried_at_end);
  EXPECT_GT(pin_run(0.95, 0.05).max_gap, 1e-3);
}

// ------------------------------------------------------------------- brush --

// The brush of docs/physics.md §2 (radius 53 mm, at 9 o'clock touching the drum),
// still. A charged FR-4 sphere dropped onto it loses its charge at the first
// touch; one dropped onto the drum keeps it (no decay). No field, so only
// gravity moves them. Exact.
TEST(Brush, TouchRemovesInsulatorCharge) {
  const std::vector<MaterialSpec> mats = {
      {kFr4, 0.5, ElectricalMaterial::insulator(kFr4Permittivity)}};
  auto m = make_model(1e-3, mats);
  m->bodies.push_back(drum(0.0));
  RigidBody brush;
  brush.name = "brush";
  brush.shape = geo::Cylinder{0.053, kHalfWidth, 0.0};
  brush.pose.position = Vec3(-(kDrumRadius + 0.053), 0.0, 0.0);
  m->bodies.push_back(brush);
  World w(m);
  const double drop = 2e-3, q0 = -2e-11;
  w.add_particle(kSphere, kFr4Radius, 1,
                 brush.pose.position + Vec3(0, 0.053 + kFr4Radius + drop, 0));
  w.add_particle(kSphere, kFr4Radius, 1, Vec3(0, kDrumRadius + kFr4Radius + drop, 0));
  for (double& q : w.particles().charge) q = q0;
  ElectrostaticsSpec spec = electrostatics(no_field(), mats);
  spec.brush_body = 1;
  w.set_electrostatics(spec);
  const double fall_time = std::sqrt(2.0 * drop / kG);  // 20 ms
  for (int i = 0; i < int(0.5 * fall_time / m->step); ++i) w.step();
  EXPECT_EQ(w.particles().charge[0], q0);  // still falling
  for (int i = 0; i < int(fall_time / m->step); ++i) w.step();
  EXPECT_EQ(w.particles().charge[0], 0.0);
  EXPECT_EQ(w.particles().charge[1], q0);
}

// ---------------------------------------------------- forces in the step --

// Forces in the step they are computed, from that step's contacts, against
// docs/physics.md §5 written out; then the frozen charges in flight. Gravity off,
// reference field, still drum. Tolerance 1e-12 relative.
//  0 copper touching the drum at 60° from the top (polar 30°, under the
//    electrode): charge Q_c(E·n) and lift force 0.832 Q_c (E·n) n at once;
//  1 FR-4 with charge q touching there: q E − F_im(q) n;
//  2 mixed (w = 0.4, εr 4.4) with insulating charge q touching there:
//    w 0.832 Q_c E·n n + (1 − w)(q E − F_im(q) n);
//  3 charged FR-4 beyond the drum's width (z = 0.2 m): no force;
//  4 copper and 5 mixed at 60° but 0.1 mm off the drum, charged q: off the
//    drum, copper feels q E and the mixed particle (1 − w)(q E − F_im n)
//    with the image force of its charge r + 0.1 mm from the drum (the induced
//    charge only while touching);
//  6 FR-4 charged q 3 mm off the drum, far outside the collision envelope:
//    q E − F_im(r + 3 mm) n (the image force acts at the distance of the
//    nearest drum surface, listed contact or not);
//  7 FR-4 charged q more than a drum radius off the drum: q E alone.
// After one step particles 0 and 2 leave the drum at 1 m/s; in the next
// step copper feels Q_c E and the mixed one (w Q_c + (1 − w) q) E, Q_c
// being the charge from step 1 (frozen), E at the new position, minus
// (1 − w) F_im at its new gap.
TEST(Forces, ActInTheStepTheyAreComputedAndChargesFreeze) {
  const double w_metal = 0.4, r = 0.5e-3, q = -1e-11;
  const std::vector<MaterialSpec> mats = {
      {kCopper, 0.5, ElectricalMaterial::conductor()},
      {kFr4, 0.5, ElectricalMaterial::insulator(kFr4Permittivity)},
      {kFr4, 0.5, ElectricalMaterial::mixed(w_metal, kFr4Permittivity)}};
  auto m = make_model(1e-3, mats);
  m->gravity.setZero();
  m->bodies.push_back(drum(0.0));
  World w(m);
  const double theta = 60.0 * kDeg;
  const Vec3 n = on_drum(1.0, theta);
  const Vec3 touching = on_drum(kDrumRadius + r, theta);
  const Vec3 off = on_drum(kDrumRadius + r + 1e-4, theta);
  const Vec3 away = 1.0 * n;  // m/s
  w.add_particle(kSphere, r, 1, touching, Quat::Identity(), away);
  w.add_particle(kSphere, r, 2, touching - 0.01 * Vec3::UnitZ());
  w.add_particle(kSphere, r, 3, touching + 0.01 * Vec3::UnitZ(), Quat::Identity(), away);
  w.add_particle(kSphere, r, 2, Vec3(0.0, 0.3, 0.2));
  w.add_particle(kSphere, r, 1, off - 0.02 * Vec3::UnitZ());
  w.add_particle(kSphere, r, 3, off + 0.02 * Vec3::UnitZ());
  const Vec3 hop = on_drum(kDrumRadius + r + 3e-3, theta) + 0.04 * Vec3::UnitZ();
  const Vec3 far = on_drum(2.0 * kDrumRadius + r + 1e-3, theta) - 0.04 * Vec3::UnitZ();
  w.add_particle(kSphere, r, 2, hop);
  w.add_particle(kSphere, r, 2, far);
  Particles& p = w.particles();
  for (std::size_t i = 1; i < p.size(); ++i) p.charge[i] = q;
  w.set_electrostatics(electrostatics(reference_field(), mats));
  ForceProbe probe;
  const ElectricField field = reference_field();

  w.step(&probe);
  const Vec3 e = field_at(field, touching);
  const double en = e.dot(n), qc = induced_charge(r, en);
  const Vec3 lift = lift_force(r, en) * n;
  const Vec3 insulating = q * e - image_pull(q, r) * n;
  const auto expect_force = [&](std::size_t i, const Vec3& expected) {
    EXPECT_LT((probe.force[i] - expected).norm(), 1e-12 * expected.norm()) << "particle " << i;
  };
  EXPECT_NEAR(p.charge[0], qc, 1e-12 * std::abs(qc));
  expect_force(0, lift);
  expect_force(1, insulating);
  expect_force(2, w_metal * lift + (1.0 - w_metal) * insulating);
  EXPECT_EQ(probe.force[3], Vec3::Zero());
  expect_force(4, q * field_at(field, probe.position[4]));
  const auto listed_gap = [&](std::size_t i) {  // of particle i's drum contact, or -1
    const Contacts& c = w.contacts();
    for (std::size_t k = 0; k < c.size(); ++k)
      if (c.body_a[k] == int(p.size()) && c.body_b[k] == int(i)) return c.gap[k];
    return -1.0;
  };
  const auto radial = [](const Vec3& x) { return Vec3(x.x(), x.y(), 0.0).normalized(); };
  ASSERT_NEAR(listed_gap(5), 1e-4, 1e-12);
  expect_force(5, (1.0 - w_metal) * (q * field_at(field, probe.position[5]) -
                                     image_pull(q, r + 1e-4) * radial(probe.position[5])));
  ASSERT_EQ(listed_gap(6), -1.0);
  expect_force(6, q * field_at(field, hop) - image_pull(q, r + 3e-3) * n);
  expect_force(7, q * field_at(field, far));

  const double frozen = p.charge[0];
  w.step(&probe);
  for (std::size_t i : {0, 2})
    ASSERT_GT(probe.position[i].head<2>().norm() - kDrumRadius - r, 5e-4) << "still on the drum";
  EXPECT_EQ(p.charge[0], frozen);
  expect_force(0, qc * field_at(field, probe.position[0]));
  const double gap2 = probe.position[2].head<2>().norm() - kDrumRadius - r;
  const Vec3 image2 = image_pull(q, r + gap2) * radial(probe.position[2]);
  expect_force(2, (w_metal * qc + (1.0 - w_metal) * q) * field_at(field, probe.position[2]) -
                      (1.0 - w_metal) * image2);
}

}  // namespace
}  // namespace ces::fields
