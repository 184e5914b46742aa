// contact.flake_faces flat: a sphere over a flake's face meets the plate
// the flake's spheres make, with the face's normal and the gap to its
// mid-plane, where sphere on sphere it meets the bumps between them.
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <memory>
#include <optional>

#include "engine_support.hpp"
#include "sim/world.hpp"
#include "support.hpp"

namespace ces {
namespace {

using test::add_raft_shape;
using test::base_model;
using test::g0;

constexpr double r = 0.001;  // the rafts' and the grain's sphere radius

TEST(FlatFace, APlaneOfEqualSpheresIsAPlateAndNothingElseIs) {
  Model m;
  add_raft_shape(m, 2, 2.0);  // 5 x 5 unit spheres 2 apart: a square of side 8
  const ParticleShape& shape = m.shapes.back();
  const FlatFace& raft = shape.face;
  ASSERT_TRUE(raft.flat());
  EXPECT_EQ(raft.hull.size(), 4u);  // the rims' middle spheres are not corners
  const auto covers = [&](const Vec3& x) {
    const Vec3 d = x - raft.origin;
    return raft.covers(d.dot(raft.x_axis), d.dot(raft.y_axis));
  };
  for (const Vec3& c : shape.centers) {
    EXPECT_TRUE(covers(c));  // on the rim too
    const bool rim = c.norm() > 4.0 - 1e-9;  // the inner spheres are within 2 sqrt(2)
    EXPECT_EQ(covers(1.05 * c), !rim) << c.transpose();
  }
  const auto is_flat = [](std::vector<Vec3> c, std::vector<double> radii) {
    return make_particle_shape(c, radii).face.flat();
  };
  EXPECT_FALSE(is_flat({Vec3::Zero()}, {1.0}));
  EXPECT_FALSE(is_flat({Vec3(-1, 0, 0), Vec3(0, 0, 0), Vec3(1, 0, 0)}, {1, 1, 1}));  // a rod
  EXPECT_FALSE(is_flat({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {1, 1, 0.9}));
  EXPECT_FALSE(is_flat({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)}, {1, 1, 1, 1}));
  EXPECT_TRUE(is_flat({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {1, 1, 1}));
}

// covers passes over a point beyond every corner before it tests the
// edges; its margin keeps the billionth of an edge the edges' test admits
// past the rim, also past a very sharp corner, where that billionth
// reaches farthest: a triangle's tip of a hundredth of a degree.
TEST(FlatFace, TheEarlyOutKeepsWhatTheEdgesAdmitPastASharpCorner) {
  const double half = 0.5 * 0.01 * kPi / 180.0;  // half the tip's angle
  const double length = 10.0, width = length * std::tan(half);
  const ParticleShape shape = make_particle_shape(
      {Vec3(length, 0, 0), Vec3(0, width, 0), Vec3(0, -width, 0)}, {1e-4, 1e-4, 1e-4});
  const FlatFace& f = shape.face;
  ASSERT_TRUE(f.flat());
  const auto covers = [&](const Vec3& x) {
    const Vec3 d = x - f.origin;
    return f.covers(d.dot(f.x_axis), d.dot(f.y_axis));
  };
  // Past the tip along its bisector, a point is outside both long edges by
  // its distance times sin(half), and the edges admit a billionth of
  // their length: past the tip that is about 6e-5 of a length.
  const Vec3 tip = shape.centers[0];
  const Vec3 out = (tip - 0.5 * (shape.centers[1] + shape.centers[2])).normalized();
  const double admitted = 1e-9 * (length / std::cos(half)) / std::sin(half);
  EXPECT_TRUE(covers(tip + 0.5 * admitted * out));
  EXPECT_FALSE(covers(tip + 2.0 * admitted * out));
}

// A world of frictionless rafts on a frictionless ground, the solve
// converged, with flat faces or sphere on sphere, reduced to four.
std::shared_ptr<Model> raft_model(bool flat) {
  auto m = base_model({0.0});
  m->bodies.push_back(test::ground_plane());
  m->gravity = Vec3(0, -g0, 0);
  m->contact.manifold = Manifold::Four;
  m->contact.flat_faces = flat;
  return m;
}

// The rafts' contacts with each other, not with the ground (body 2).
std::vector<std::size_t> between_particles(const Contacts& c) {
  std::vector<std::size_t> k;
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c.body_a[i] < 2 && c.body_b[i] < 2) k.push_back(i);
  return k;
}

struct Stack {
  double height = 0.0;  // of the upper raft's centre
  std::size_t touching = 0, on_face = 0;  // contacts, touching or nearly
  bool normals_vertical = true;
};

// A raft dropped on another, offset by half their spacing on both axes, so
// that each of its spheres is over a hollow between four of the lower's.
Stack stacked(bool flat) {
  auto m = raft_model(flat);
  const Quat face_up = add_raft_shape(*m, 2, 2.0);
  World w(m);
  w.add_particle(1, r, 0, Vec3(0, r, 0), face_up);
  w.add_particle(1, r, 0, Vec3(r, 3.2 * r, r), face_up);
  for (int i = 0; i < 300; ++i) w.step();
  Stack s;
  s.height = w.particles().position[1].y();
  for (std::size_t k : between_particles(w.contacts())) {
    // A corner of each, beside the other's face, is listed with the
    // other's rim, a fifth of a radius away or more.
    if (w.contacts().gap[k] > 0.1 * r) continue;
    const ContactKey& key = w.contacts().key[k];
    ++s.touching;
    s.on_face += key.feature_a == kPlateFeature || key.feature_b == kPlateFeature;
    // Where the rims cross, they touch too, along the face's normal.
    s.normals_vertical = s.normals_vertical && std::abs(w.contacts().normal[k].y()) > 1 - 1e-12;
  }
  return s;
}

// A plate's thickness is its spheres' diameter: the upper raft rests 2r
// above the lower's centre. Sphere on sphere it sinks into the hollows, to
// r + sqrt(2) r, and each hollow's four tilted normals make a group of
// their own; over the face every contact has the face's normal, and four
// of them hold the raft.
TEST(FlatFace, FlakesStackAtTheirThicknessOnFourContacts) {
  const Stack flat = stacked(true), spheres = stacked(false);
  EXPECT_NEAR(flat.height, 3 * r, 0.01 * r);
  EXPECT_EQ(flat.on_face, 4u);
  EXPECT_TRUE(flat.normals_vertical);
  EXPECT_NEAR(spheres.height, (1 + std::sqrt(2.0)) * r, 0.01 * r);
  EXPECT_GT(spheres.touching, 4u);
  EXPECT_FALSE(spheres.normals_vertical);
}

// Without friction, a face exerts no force along itself: a raft sliding
// across another keeps its speed and its height, and the lower raft stays
// still (momentum along the face is conserved for each). Sphere on sphere
// the upper raft rides over the bumps: its speed changes.
struct Slide {
  double speed_change = 0.0, lower_speed = 0.0, height_change = 0.0;
};

Slide sliding(bool flat) {
  auto m = raft_model(flat);
  const Quat face_up = add_raft_shape(*m, 2, 2.0);
  World w(m);
  w.add_particle(1, r, 0, Vec3(0, r, 0), face_up);
  w.add_particle(1, r, 0, Vec3(0, 3 * r, 0), face_up);
  for (int i = 0; i < 20; ++i) w.step();  // settle
  const double v = 0.02;
  w.particles().velocity[1].x() = v;
  const double y0 = w.particles().position[1].y();
  Slide s;
  for (int i = 0; i < 150; ++i) {  // 3 mm: 1.5 spacings, still over the lower raft
    w.step();
    const Particles& p = w.particles();
    s.speed_change = std::max(s.speed_change, std::abs(p.velocity[1].x() - v));
    s.lower_speed = std::max(s.lower_speed, std::abs(p.velocity[0].x()));
    s.height_change = std::max(s.height_change, std::abs(p.position[1].y() - y0));
  }
  return s;
}

TEST(FlatFace, AFrictionlessFaceSlidesFreely) {
  const Slide flat = sliding(true), spheres = sliding(false);
  EXPECT_LT(flat.speed_change, 1e-9);
  EXPECT_LT(flat.lower_speed, 1e-9);
  EXPECT_LT(flat.height_change, 0.01 * r);
  EXPECT_GT(spheres.speed_change, 0.1 * 0.02);
}

// The single contact of a grain (a sphere of radius r) placed near a raft
// lying face up, or none.
std::optional<std::size_t> grain_contact(World& w) {
  w.step();
  const auto k = between_particles(w.contacts());
  if (k.empty()) return std::nullopt;
  EXPECT_EQ(k.size(), 1u);
  return k[0];
}

// A grain over a hollow of the face, 0.15 r above the plate's surface,
// meets the face there: one contact, the face's normal, that gap. Sphere on
// sphere it is over half a radius from the nearest spheres, beyond the
// envelope. Beside the raft's rim it meets the rim, the hull's edge swept
// by the spheres' radius: one contact, across the edge. Sphere on sphere it
// meets the two rim spheres nearest, farther.
TEST(FlatFace, AGrainMeetsTheFaceOverItAndTheRimBesideIt) {
  for (bool flat : {true, false}) {
    auto m = raft_model(flat);
    m->gravity = Vec3::Zero();
    const Quat face_up = add_raft_shape(*m, 2, 2.0);
    World w(m);
    w.add_particle(1, r, 0, Vec3(0, r, 0), face_up);
    w.add_particle(0, r, 0, Vec3(r, 3.15 * r, r), Quat::Identity());
    const auto over = grain_contact(w);
    ASSERT_EQ(over.has_value(), flat);
    if (flat) {
      EXPECT_NEAR(std::abs(w.contacts().normal[*over].y()), 1.0, 1e-12);
      EXPECT_NEAR(w.contacts().gap[*over], 0.15 * r, 1e-12);
    }
    // Beside the rim x = 4r, between two of its spheres (z = 0 and 2r).
    Particles& p = w.particles();
    p.position[1] = Vec3(6.05 * r, r, r);
    p.velocity[1] = Vec3::Zero();
    w.step();
    const auto beside = between_particles(w.contacts());
    ASSERT_EQ(beside.size(), flat ? 1u : 2u);
    for (std::size_t k : beside) {
      const double sphere_gap = (std::sqrt(2.05 * 2.05 + 1.0) - 2.0) * r;
      EXPECT_NEAR(w.contacts().gap[k], flat ? 0.05 * r : sphere_gap, 1e-9);
      if (flat) {
        EXPECT_NEAR(w.contacts().normal[k].x(), 1.0, 1e-9);  // from the raft (A) out
      }
    }
  }
}

// Two rafts edge on edge, crossing: one lying face up, the other standing
// beside it across its rim, their edges 0.05 r apart at their middles,
// each beside the other's face and their corners far. Their rims meet
// where the edges cross, as the spheres there do.
TEST(FlatFace, RimsCrossingMeetWhereTheyCross) {
  for (bool flat : {true, false}) {
    auto m = base_model({0.0});
    m->contact.manifold = Manifold::Four;
    m->contact.flat_faces = flat;
    const Quat face_up = add_raft_shape(*m, 2, 2.0);
    World w(m);
    w.add_particle(1, r, 0, Vec3(0, r, 0), face_up);
    const Quat standing = Quat::FromTwoVectors(Vec3::UnitY(), Vec3::UnitZ()) * face_up;
    w.add_particle(1, r, 0, Vec3(10.05 * r, r, 0), standing);
    w.step();
    const auto k = between_particles(w.contacts());
    ASSERT_EQ(k.size(), 1u) << flat;
    EXPECT_NEAR(w.contacts().gap[k[0]], 0.05 * r, 1e-9) << flat;
    EXPECT_NEAR(std::abs(w.contacts().normal[k[0]].x()), 1.0, 1e-9) << flat;
  }
}

}  // namespace
}  // namespace ces
