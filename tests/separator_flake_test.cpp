// The separator's force stages in the World (fields/stages.hpp) on flat
// flakes (face area and tilt, image force, saturation charge, pinned and
// carried), the electrostatics spec's errors, and bitwise determinism of a
// charged drum across thread counts. Each test states its tolerance and
// assumptions.
//
// Frame: drum axis = z through the origin, gravity −y. The drum turns
// clockwise seen from +z, so its top moves toward +x, where the electrode
// is (docs/physics.md §2); θ is measured from the top in the direction of rotation.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "feed/shapes.hpp"
#include "fields/drag.hpp"
#include "fields/electrostatics.hpp"
#include "separator_support.hpp"
#include "sim/world.hpp"

namespace ces::fields {
namespace {

// The separator tests' shared machine, materials and closed forms.
using namespace test;

// ----------------------------------------------------------- flat flakes --

// The built-in flake of aspect 0.2 (fed as `shape: flake`): 19 spheres of
// radius 0.1 on a hexagonal lattice of spacing 0.2, so neighbours just
// touch and its face is exactly 19 discs: A = 19 π 0.1² (scale 1).
ParticleShape unit_flake() {
  const feed::SphereList f = feed::flake_spheres(0.2);
  return make_particle_shape(f.centers, f.radii);
}
constexpr double kFlakeFace = 19.0 * kPi * 0.01;

// The centre of the shape's lowest sphere (least y) turned by `turn`,
// relative to its centre of mass at scale 1 (the centre of mass itself if
// no sphere is below it): a flake of scale s stood on its rim with that
// sphere's centre at p has its own centre at p - s lowest_sphere(...).
Vec3 lowest_sphere(const ParticleShape& shape, const Quat& turn) {
  Vec3 lowest = Vec3::Zero();
  for (const Vec3& c : shape.centers)
    if ((turn * c).y() < lowest.y()) lowest = turn * c;
  return lowest;
}

// An FR-4 flake's model for the electrics checks: no gravity, 1 ms steps,
// the unit flake as its last shape (a drum to be added).
std::shared_ptr<Model> flake_model(std::vector<MaterialSpec>& mats) {
  mats = {{kFr4, 0.5, ElectricalMaterial::insulator(kFr4Permittivity)}};
  auto m = make_model(1e-3, mats);
  m->gravity.setZero();
  m->shapes.push_back(unit_flake());
  return m;
}

// Flat shapes take the face laws, compact ones the sphere's. Areas by the
// stage's grid count within 0.2 % of the exact union of discs.
TEST(FlakeElectrics, FaceAreaAndTilt) {
  const ParticleShape flake = unit_flake();
  const ShapeElectrics e = shape_electrics(flake);
  EXPECT_NEAR(e.face_area, kFlakeFace, 0.002 * kFlakeFace);
  // The face is across the principal axis with the largest inertia.
  int thin = 0;
  for (int k = 1; k < 3; ++k)
    if (flake.unit_inertia[k] > flake.unit_inertia[thin]) thin = k;
  EXPECT_NEAR(std::abs(e.face_normal[thin]), 1.0, 1e-12);
  // Flat within the tilt at which the rim lifts by the thickness: 0.2 over
  // the width across flats, 0.2 + 0.4 √3.
  // (1e-6: the principal frame of overlapping spheres comes from a volume
  // integration, so the face is level to about that.)
  EXPECT_NEAR(e.flat_cos, std::cos(std::asin(0.2 / (0.2 + 0.4 * std::sqrt(3.0)))), 1e-6);
  // A 4 x 4 square of touching spheres of radius 1: A = 16π, 8 wide, 2 thick.
  std::vector<Vec3> centers;
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 4; ++k) centers.emplace_back(2.0 * i, 2.0 * k, 0.0);
  const ShapeElectrics square =
      shape_electrics(make_particle_shape(centers, std::vector<double>(16, 1.0)));
  EXPECT_NEAR(square.face_area, 16.0 * kPi, 0.002 * 16.0 * kPi);
  // The bridged face law: κ Q²/(2 ε0 εr A) on the drum (κ = 1 for a uniform
  // charge, 9/8 by default), a point charge and its image 2g apart far off
  // it (1 %), falling in between: at g = 0.1 √A to 1/(1 + 0.08 π κ).
  const double q = 1e-10, area = 1e-6;
  for (const double kappa : {1.0, kThinFlakeImageFactor}) {
    const double contact = kappa * q * q / (2.0 * kEps0 * kEpsAir * area);
    EXPECT_NEAR(flat_image_force(q, area, kEpsAir, 0.0, kappa), contact, 1e-12 * contact);
    const double far = 0.1;  // 100 √A
    EXPECT_NEAR(flat_image_force(q, area, kEpsAir, far, kappa), image_pull(q, far),
                0.01 * image_pull(q, far));
    EXPECT_NEAR(flat_image_force(q, area, kEpsAir, 1e-4, kappa) / contact,
                1.0 / (1.0 + 0.08 * kPi * kappa), 1e-12);
  }
  EXPECT_NEAR(flat_image_force(q, area, kEpsAir), 9.0 / 8.0 * q * q / (2.0 * kEps0 * kEpsAir * area),
              1e-12 * flat_image_force(q, area, kEpsAir));
  EXPECT_EQ(flat_image_force(q, area, kEpsAir, 0.0, 0.0), 0.0);
  // A sphere, a pair and the default rod are compact: sphere law.
  const feed::SphereList rod = feed::rod_spheres(0.25);
  for (const ParticleShape& compact :
       {make_particle_shape({Vec3::Zero()}, {1.0}),
        make_particle_shape({Vec3(-1, 0, 0), Vec3(1, 0, 0)}, {1.0, 1.0}),
        make_particle_shape(rod.centers, rod.radii)}) {
    EXPECT_EQ(shape_electrics(compact).face_area, 0.0);
  }
}

// A charged FR-4 flake (scale 2 mm: 2 mm across, 0.4 mm thick) touching a
// still drum on its top, in no field and without gravity: lying flat it is
// pulled by κ Q² / (2 ε0 εr A) along −n (docs/physics.md §5.5, written out
// here with A = 19 π (0.1 s)², t = V/A and κ of its thinness); stood on its
// rim it is pulled by the sphere law of its equal-volume sphere. Tolerance
// 0.2 % (the stage's area count).
TEST(FlakeElectrics, ImageForceOfAFlakeIsTheFaceLawLyingFlat) {
  std::vector<MaterialSpec> mats;
  auto m = flake_model(mats);
  const int flake = int(m->shapes.size()) - 1;
  m->bodies.push_back(drum(0.0));
  const ShapeElectrics e = shape_electrics(m->shapes.back());
  World w(m);
  const double s = 2e-3, q = -3e-11, r = 0.1 * s;
  // Face normal along the drum normal (+y at the top), and across it.
  const Vec3 n_body = e.face_normal;
  const Quat flat = Quat::FromTwoVectors(n_body, Vec3::UnitY());
  const Quat edge = Quat::FromTwoVectors(n_body, Vec3::UnitX());
  w.add_particle(flake, s, 1, Vec3(0, kDrumRadius + r, 0), flat);
  // On its rim, the outermost sphere on the drum (at 0.4 s from the centre
  // along some in-plane direction): put the centre above it.
  const Quat stood = edge;
  w.add_particle(flake, s, 1,
                 Vec3(0.0, kDrumRadius + r, 0.05) - s * lowest_sphere(m->shapes.back(), stood),
                 stood);
  for (double& c : w.particles().charge) c = q;
  w.set_electrostatics(electrostatics(no_field(), mats));
  ForceProbe probe;
  w.step(&probe);
  const double area = kFlakeFace * s * s;
  const double volume = m->shapes.back().volume * s * s * s;
  const double kappa = flake_image_factor({area, volume / area}, kFr4Permittivity);
  const double face_law = kappa * q * q / (2.0 * kEps0 * kEpsAir * area);
  EXPECT_NEAR(probe.force[0].y(), -face_law, 0.002 * face_law);
  EXPECT_NEAR(probe.force[0].x(), 0.0, 1e-9 * face_law);
  const double r_eq = std::cbrt(3.0 * volume / (4.0 * kPi));
  const double sphere_law = image_pull(q, r_eq);
  const Vec3 n1 = Vec3(probe.position[1].x(), probe.position[1].y(), 0.0).normalized();
  EXPECT_LT((probe.force[1] + sphere_law * n1).norm(), 0.01 * sphere_law);
  // At equal charge the stage's pull lying flat is κ 8π r_eq² / A times
  // its pull on the rim (the two laws' ratio), within the two tolerances.
  const double ratio = -probe.force[0].y() / probe.force[1].dot(-n1);
  EXPECT_NEAR(ratio, kappa * 8.0 * kPi * r_eq * r_eq / area, 0.012 * ratio);
}

// Corona charge of a flake lying flat on the drum: the saturation charge
// of a flat flake of its face area and thickness V/A (docs/physics.md
// §5.3), more than twice the sphere's. Held flat a gap δ over the drum,
// beyond any contact the step lists, the face's charge divided by
// 1 + εr δ/t (the flake and the air gap in series) while that exceeds the
// sphere's, and the sphere's farther off; stood on its rim just as near,
// the sphere's. 1e-5 relative given the area: the flake's spheres touch,
// so its centre of mass comes from a numerical integration of their
// union, which leaves a flake placed on the drum a fraction of a
// nanometre off it.
TEST(FlakeElectrics, FlakeChargesByTheGapUnderIt) {
  std::vector<MaterialSpec> mats;
  auto m = flake_model(mats);
  m->bodies.push_back(drum(0.0));
  const ParticleShape& shape = m->shapes.back();
  const ShapeElectrics e = shape_electrics(shape);
  World w(m);
  const double s = 2e-3, r = 0.1 * s, near = 0.07e-3, far = 3e-3;
  const Quat flat = Quat::FromTwoVectors(e.face_normal, Vec3::UnitY());
  const Quat stood = Quat::FromTwoVectors(e.face_normal, Vec3::UnitX());
  const int flake = int(m->shapes.size()) - 1;
  w.add_particle(flake, s, 1, Vec3(0, kDrumRadius + r, 0), flat);
  w.add_particle(flake, s, 1, Vec3(0, kDrumRadius + r + near, 0.02), flat);
  w.add_particle(flake, s, 1, Vec3(0, kDrumRadius + r + far, 0.04), flat);
  w.add_particle(flake, s, 1,
                 Vec3(0, kDrumRadius + r + near, 0.06) - s * lowest_sphere(shape, stood), stood);
  ElectrostaticsSpec spec = electrostatics(reference_field(), mats);
  spec.corona = {saturation_zone()};
  w.set_electrostatics(spec);
  w.step();
  const double a = e.face_area * s * s;
  const FlatFlake face{a, shape.volume * s * s * s / a};
  const double field = 4.13e5;
  const double lying = flake_saturation_charge(face, kFr4Permittivity, field);
  const double sphere = pauthenier_saturation_charge(
      std::cbrt(3.0 * shape.volume / (4.0 * kPi)) * s, kFr4Permittivity, field);
  const double hovering = lying / (1.0 + kFr4Permittivity * near / face.thickness);
  ASSERT_GT(lying, 2.0 * sphere);
  ASSERT_GT(hovering, 1.2 * sphere);  // the near flake is in the face's range
  ASSERT_LT(lying / (1.0 + kFr4Permittivity * far / face.thickness), sphere);
  const std::vector<double>& q = w.particles().charge;
  EXPECT_NEAR(q[0], -lying, 1e-5 * lying);
  EXPECT_NEAR(q[1], -hovering, 1e-5 * hovering);
  EXPECT_NEAR(q[2], -sphere, 1e-5 * sphere);
  EXPECT_NEAR(q[3], -sphere, 1e-5 * sphere);
  // The drum's contacts: only the flake lying on it has any.
  for (std::size_t k = 0; k < w.contacts().size(); ++k) EXPECT_EQ(w.contacts().body_b[k], 0);
}

// A charged FR-4 flake (d = 1.8 mm, its corona saturation charge at
// 4.13 kV/cm) lands flat on the drum turning at 44.8 rpm, 80° above the
// horizontal, 0.2 m/s faster than the drum's surface, as flakes from the
// feed belt do. Lying flat it is pinned by several m g, so friction (0.5)
// must take its slip away within ~15 ms and carry it past the bottom of
// the drum (0.6 s, 160° of turn). This needs the stage to see a SLIDING
// contact as touching: the relaxed cone complementarity lifts it by μ |v_t|
// h per step (50 µm here), far above the 1 % of r a resting contact shows.
// The seed's step (0.5 ms) and iteration cap (APGD, 50).
TEST(FlakeElectrics, SlidingFlakeIsPinnedAndCarried) {
  const SingleThread one_thread;
  const std::vector<MaterialSpec> mats = {
      {kFr4, 0.5, ElectricalMaterial::insulator(kFr4Permittivity)}};
  auto m = make_model(0.5e-3, mats);
  m->solver.max_iterations = 50;
  m->solver.tolerance = 1e-6;
  m->shapes.push_back(unit_flake());
  const double omega = rpm(44.8);
  m->bodies.push_back(drum(omega));
  const ShapeElectrics e = shape_electrics(m->shapes.back());
  World w(m);
  const double unit_radius = std::cbrt(3.0 * m->shapes.back().volume / (4.0 * kPi));
  const double s = 1.8e-3 / (2.0 * unit_radius), r = 0.1 * s;
  const double theta = 10.0 * kDeg;  // from the top: 80° above the horizontal
  const Vec3 x0 = on_drum(kDrumRadius + r, theta), n0 = x0.normalized();
  const Vec3 t0 = Vec3(0, 0, -1).cross(n0);  // the drum surface's direction of motion
  w.add_particle(int(m->shapes.size()) - 1, s, 1, x0,
                 Quat::FromTwoVectors(e.face_normal, n0), carried_velocity(omega, x0) + 0.2 * t0);
  const double area = e.face_area * s * s;
  w.particles().charge[0] = -flake_saturation_charge(
      {area, m->shapes.back().volume * s * s * s / area}, kFr4Permittivity, 4.13e5);
  w.set_electrostatics(electrostatics(reference_field(), mats));
  const auto slip = [&] {
    const Vec3& x = w.particles().position[0];
    return (w.particles().velocity[0] - carried_velocity(omega, x)).norm();
  };
  for (int i = 0; i < 40; ++i) w.step();  // 20 ms
  EXPECT_LT(slip(), 0.01);
  double worst_gap = 0.0;
  for (int i = 0; i < 1160; ++i) {
    w.step();
    worst_gap = std::max(worst_gap, w.particles().position[0].head<2>().norm() - kDrumRadius - r);
  }
  EXPECT_LT(worst_gap, 1e-4);
  EXPECT_GT(theta_of(w.particles().position[0]), 165.0 * kDeg);  // past the bottom, still on
  EXPECT_LT(slip(), 0.01);
}

// Spec errors name what is wrong.
TEST(Electrostatics, RejectsSpecsThatDoNotFitTheModel) {
  const std::vector<MaterialSpec> mats = {
      {kFr4, 0.5, ElectricalMaterial::insulator(kFr4Permittivity)}};
  auto m = make_model(1e-3, mats);
  m->bodies.push_back(drum(0.0));
  World w(m);
  const auto rejects = [&](const std::function<void(ElectrostaticsSpec&)>& edit, const char* what) {
    ElectrostaticsSpec spec = electrostatics(reference_field(), mats);
    edit(spec);
    try {
      w.set_electrostatics(spec);
      ADD_FAILURE() << "accepted: " << what;
    } catch (const std::invalid_argument& err) {
      EXPECT_NE(std::string(err.what()).find(what), std::string::npos) << err.what();
    }
  };
  rejects([](ElectrostaticsSpec& s) { s.drum_body = 1; }, "drum_body 1");
  rejects([](ElectrostaticsSpec& s) { s.brush_body = 0; }, "brush cannot be the drum");
  rejects([](ElectrostaticsSpec& s) { s.materials.pop_back(); },
          "1 electrical materials given for 2");
  rejects([](ElectrostaticsSpec& s) { s.materials[1].metal_fraction = 1.5; }, "material 1: metal");
  rejects([](ElectrostaticsSpec& s) { s.corona = {CoronaZone{}}; }, "corona zone 0");
  rejects([](ElectrostaticsSpec& s) { s.field = std::shared_ptr<const GridField>(); },
          "grid field");
}

// ------------------------------------------------------------ determinism --

// 300 particles (copper, FR-4 and mixed, d 0.8–1.2 mm) packed on the top of
// the reference drum (neighbours touch: ~400 contacts) at 44.8 rpm, with a
// corona zone over the packing, FR-4 decay and Schiller–Naumann drag. Every
// 7th particle is removed half-way (the mixed particles' charges are carried
// by id). 100 steps of 1 ms with 1 and with 2 threads: positions,
// velocities, spins, charges and forces bitwise identical (the stages'
// loops go parallel above 256 particles).
std::vector<double> charged_drum_state(int threads, bool dumbbells = false) {
  const std::vector<MaterialSpec> mats = {
      {kCopper, 0.5, ElectricalMaterial::conductor()},
      {kFr4, 0.5, ElectricalMaterial::insulator(kFr4Permittivity, 39.0)},
      {kFr4, 0.5, ElectricalMaterial::mixed(0.3, kFr4Permittivity, 39.0)}};
  auto m = make_model(1e-3, mats);
  m->threads = threads;
  m->solver.max_iterations = 20;  // bitwise equality needs no convergence; fewer barriers
  m->bodies.push_back(drum(rpm(44.8)));
  World w(m);
  // Dumbbells lie along the drum axis, two spheres of radius r each.
  const Quat along_z(Eigen::AngleAxisd(0.5 * kPi, Vec3::UnitY()));
  for (int i = 0; i < 300; ++i) {
    const double r = 0.4e-3 + 0.1e-3 * (i % 5);
    const double theta = (-5.0 + 0.45 * (i % 20)) * kDeg;
    const double z = dumbbells ? -0.03 + 4e-3 * (i / 20) : -0.01 + 1.25e-3 * (i / 20);
    const Vec3 x = on_drum(kDrumRadius + r + 1e-4, theta, z);
    w.add_particle(dumbbells ? kPair : kSphere, r, 1 + i % 3, x,
                   dumbbells ? along_z : Quat::Identity(), carried_velocity(rpm(44.8), x));
  }
  ElectrostaticsSpec spec = electrostatics(reference_field(), mats);
  CoronaZone zone;
  zone.angle_begin = 80.0 * kDeg;
  zone.angle_end = 95.0 * kDeg;
  zone.depth = 0.02;
  zone.current_density = 1e-4;  // A/m², any: the test is of the threads
  spec.corona = {zone};
  w.set_electrostatics(spec);
  w.set_drag({Air{}, DragLaw::SchillerNaumann});
  for (int s = 0; s < 100; ++s) {
    if (s == 50)
      for (std::size_t i = w.particles().size(); i-- > 0;)
        if (i % 7 == 0) w.remove_particle(i);
    w.step();
  }
  std::vector<double> state;
  const Particles& p = w.particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    for (const Vec3* v : {&p.position[i], &p.velocity[i], &p.angular_velocity[i], &p.force[i]})
      state.insert(state.end(), v->data(), v->data() + 3);
    state.push_back(p.charge[i]);
  }
  omp_set_num_threads(omp_get_num_procs());
  return state;
}

// The same with two-sphere clusters, so that a particle has several drum
// contacts, whose runs the electric stage's touches and the spin cap of
// clumps read in parallel chunks.
TEST(Determinism, ChargedDumbbellsAreBitwiseIdenticalForOneAndTwoThreads) {
  const auto one = charged_drum_state(1, true), two = charged_drum_state(2, true);
  ASSERT_EQ(one.size(), two.size());
  EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(double)));
}

TEST(Determinism, ChargedDrumIsBitwiseIdenticalForOneAndTwoThreads) {
  const auto one = charged_drum_state(1), two = charged_drum_state(2);
  ASSERT_EQ(one.size(), two.size());
  EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(double)));
  std::size_t charged = 0;  // the charge is the 13th value per particle
  for (std::size_t k = 12; k < one.size(); k += 13) charged += one[k] != 0.0;
  EXPECT_GT(charged, one.size() / 13 / 2);
}

}  // namespace
}  // namespace ces::fields
