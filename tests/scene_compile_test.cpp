// Scene files in: what the scenes of scenes/ compile to, YAML/JSON parity
// (twins compile to the same model: bodies, materials, feeds, collectors),
// the resolved scene (reloads to the same simulation, its hash), and the
// compile of only the components that are used.
#include "scene/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <variant>

#include "scene_support.hpp"

namespace ces::scene {
namespace {

using test::kMinimal;
using test::kScenes;
using test::load_errors;
using test::TempDir;

// ------------------------------------------------------------------ scenes/

TEST(SceneLoad, DefaultScene) {
  const Simulation sim = load(kScenes + "default.yaml");
  const Model& m = *sim.model;
  EXPECT_EQ(sim.name, "default");
  EXPECT_EQ(sim.seed, 42u);
  EXPECT_EQ(m.step, 0.001);
  EXPECT_EQ(sim.end_time, 0.5);
  EXPECT_EQ(m.gravity, Vec3(0, -9.81, 0));
  ASSERT_EQ(m.bodies.size(), 1u);
  const RigidBody& drum = m.bodies[0];
  EXPECT_EQ(drum.kind, BodyKind::Kinematic);
  EXPECT_DOUBLE_EQ(drum.motion.angular_speed, 44.8 * 2 * std::numbers::pi / 60);
  EXPECT_EQ(drum.motion.axis, Vec3(0, 0, -1));
  const auto& cylinder = std::get<geo::Cylinder>(drum.shape);
  EXPECT_EQ(cylinder.radius, 0.16);
  EXPECT_EQ(cylinder.half_length, 0.15);
  ASSERT_EQ(sim.feeds.size(), 1u);
  const Feed& feed = sim.feeds[0];
  EXPECT_EQ(feed.count_rate, 1000.0);
  EXPECT_EQ(feed.mass_rate, 0.0);
  EXPECT_EQ(feed.duration, 0.2);
  ASSERT_EQ(feed.mix.size(), 2u);
  EXPECT_EQ(feed.mix[0].mass_fraction, 0.3);
  EXPECT_EQ(feed.mix[0].size.mean_by_number(), 0.001);
  EXPECT_EQ(m.materials.materials()[std::size_t(feed.mix[1].material)].name, "pvc");
  EXPECT_EQ(feed.region.min, Vec3(-0.02, 0.17, -0.05));
  ASSERT_EQ(sim.collectors.size(), 1u);
  EXPECT_EQ(sim.collectors[0].bins, 50);
  ASSERT_EQ(sim.collectors[0].products.size(), 3u);
  EXPECT_EQ(sim.collectors[0].products[1].name, "middling");
  ASSERT_TRUE(sim.domain);
  EXPECT_EQ(sim.output.dir, "out/default");
  EXPECT_TRUE(sim.output.trajectories.vtk && sim.output.trajectories.csv);
  EXPECT_EQ(sim.active_components,
            (std::vector<std::string>{"gravity", "contacts", "kinematic_bodies", "feeds",
                                      "collectors", "domain", "trajectories"}));
  EXPECT_EQ(sim.scene_hash.size(), 16u);
}

TEST(SceneLoad, HopperSceneHasMeshAndClusters) {
  const Simulation sim = load(kScenes + "hopper.json");
  const Model& m = *sim.model;
  const auto& mesh = std::get<std::shared_ptr<const geo::TriMesh>>(m.bodies[0].shape);
  EXPECT_EQ(mesh->triangles().size(), 4u);
  EXPECT_NEAR(mesh->bounds().max.x(), 0.12, 1e-12);    // drawn in mm, scale 0.001
  EXPECT_DOUBLE_EQ(m.materials.pair(2, 0).friction, 0.25);  // glass/steel override
  ASSERT_EQ(m.shapes.size(), 2u);                      // sphere, flake
  const FeedComponent& flake = sim.feeds[0].mix[1];
  EXPECT_EQ(m.shapes[std::size_t(flake.shape)].centers.size(), 3u);
  EXPECT_EQ(flake.shape_size, 2.0);
  for (const char* c : {"meshes", "clusters"})
    EXPECT_NE(std::find(sim.active_components.begin(), sim.active_components.end(), c),
              sim.active_components.end());
}

// ------------------------------------------------------------------ YAML / JSON

void expect_same_shape(const geo::Shape& a, const geo::Shape& b) {
  ASSERT_EQ(a.index(), b.index());
  if (const auto* p = std::get_if<geo::Plane>(&a)) {
    EXPECT_EQ(p->normal, std::get<geo::Plane>(b).normal);
    EXPECT_EQ(p->offset, std::get<geo::Plane>(b).offset);
  } else if (const auto* x = std::get_if<geo::Box>(&a)) {
    EXPECT_EQ(x->half_extents, std::get<geo::Box>(b).half_extents);
  } else if (const auto* c = std::get_if<geo::Cylinder>(&a)) {
    const auto& d = std::get<geo::Cylinder>(b);
    EXPECT_EQ(std::tie(c->radius, c->half_length, c->thickness),
              std::tie(d.radius, d.half_length, d.thickness));
  } else {
    const auto& ma = *std::get<std::shared_ptr<const geo::TriMesh>>(a);
    const auto& mb = *std::get<std::shared_ptr<const geo::TriMesh>>(b);
    EXPECT_EQ(ma.vertices(), mb.vertices());
    EXPECT_EQ(ma.triangles(), mb.triangles());
  }
}

void expect_same_model(const Model& a, const Model& b) {
  EXPECT_EQ(a.step, b.step);
  EXPECT_EQ(a.gravity, b.gravity);
  EXPECT_EQ(a.threads, b.threads);
  EXPECT_EQ(a.solver.method, b.solver.method);
  EXPECT_EQ(a.solver.max_iterations, b.solver.max_iterations);
  EXPECT_EQ(a.solver.tolerance, b.solver.tolerance);
  EXPECT_EQ(a.solver.pgs_relaxation, b.solver.pgs_relaxation);
  EXPECT_EQ(a.solver.warm_start, b.solver.warm_start);
  EXPECT_EQ(a.contact.envelope_fraction, b.contact.envelope_fraction);
  EXPECT_EQ(a.contact.recovery_speed, b.contact.recovery_speed);
  EXPECT_EQ(a.contact.restitution_threshold, b.contact.restitution_threshold);
  const auto& ma = a.materials.materials();
  const auto& mb = b.materials.materials();
  ASSERT_EQ(ma.size(), mb.size());
  for (std::size_t i = 0; i < ma.size(); ++i) {
    EXPECT_EQ(std::tie(ma[i].name, ma[i].density, ma[i].friction, ma[i].restitution),
              std::tie(mb[i].name, mb[i].density, mb[i].friction, mb[i].restitution));
    for (std::size_t j = 0; j < ma.size(); ++j) {
      const SurfacePair pa = a.materials.pair(int(i), int(j));
      const SurfacePair pb = b.materials.pair(int(i), int(j));
      EXPECT_EQ(pa.friction, pb.friction);
      EXPECT_EQ(pa.restitution, pb.restitution);
    }
  }
  ASSERT_EQ(a.shapes.size(), b.shapes.size());
  for (std::size_t i = 0; i < a.shapes.size(); ++i) {
    EXPECT_EQ(a.shapes[i].centers, b.shapes[i].centers);
    EXPECT_EQ(a.shapes[i].radii, b.shapes[i].radii);
    EXPECT_EQ(a.shapes[i].volume, b.shapes[i].volume);
    EXPECT_EQ(a.shapes[i].unit_inertia, b.shapes[i].unit_inertia);
  }
  ASSERT_EQ(a.bodies.size(), b.bodies.size());
  for (std::size_t i = 0; i < a.bodies.size(); ++i) {
    const RigidBody& x = a.bodies[i];
    const RigidBody& y = b.bodies[i];
    EXPECT_EQ(std::tie(x.name, x.kind, x.material, x.mass),
              std::tie(y.name, y.kind, y.material, y.mass));
    expect_same_shape(x.shape, y.shape);
    EXPECT_EQ(x.pose.position, y.pose.position);
    EXPECT_EQ(x.pose.orientation.coeffs(), y.pose.orientation.coeffs());
    EXPECT_EQ(x.motion.axis, y.motion.axis);
    EXPECT_EQ(x.motion.center, y.motion.center);
    EXPECT_EQ(x.motion.angular_speed, y.motion.angular_speed);
    EXPECT_EQ(x.motion.linear_velocity, y.motion.linear_velocity);
    EXPECT_EQ(x.inertia, y.inertia);
    EXPECT_EQ(x.velocity, y.velocity);
    EXPECT_EQ(x.angular_velocity, y.angular_velocity);
  }
  ASSERT_EQ(a.joints.size(), b.joints.size());
  for (std::size_t i = 0; i < a.joints.size(); ++i) {
    EXPECT_EQ(std::tie(a.joints[i].type, a.joints[i].body_a, a.joints[i].body_b),
              std::tie(b.joints[i].type, b.joints[i].body_a, b.joints[i].body_b));
    EXPECT_EQ(a.joints[i].point, b.joints[i].point);
    EXPECT_EQ(a.joints[i].axis, b.joints[i].axis);
  }
  ASSERT_EQ(a.motors.size(), b.motors.size());
  for (std::size_t i = 0; i < a.motors.size(); ++i) {
    const Motor& x = a.motors[i];
    const Motor& y = b.motors[i];
    EXPECT_EQ(std::tie(x.joint, x.mode, x.target, x.max_speed, x.max_force),
              std::tie(y.joint, y.mode, y.target, y.max_speed, y.max_force));
  }
}

// Size laws are compared by their quantiles: equal inputs give equal tables.
void expect_same_size(const feed::SizeDistribution& a, const feed::SizeDistribution& b) {
  for (double q : {0.0, 0.1, 0.5, 0.9, 1.0}) {
    EXPECT_EQ(a.quantile_by_number(q), b.quantile_by_number(q));
    EXPECT_EQ(a.quantile_by_mass(q), b.quantile_by_mass(q));
  }
}

void expect_same_simulation(const Simulation& a, const Simulation& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.end_time, b.end_time);
  expect_same_model(*a.model, *b.model);
  ASSERT_EQ(a.feeds.size(), b.feeds.size());
  for (std::size_t i = 0; i < a.feeds.size(); ++i) {
    const Feed& x = a.feeds[i];
    const Feed& y = b.feeds[i];
    EXPECT_EQ(std::tie(x.name, x.start, x.duration, x.mass_rate, x.count_rate, x.velocity_spread,
                       x.random_orientation, x.max_attempts),
              std::tie(y.name, y.start, y.duration, y.mass_rate, y.count_rate, y.velocity_spread,
                       y.random_orientation, y.max_attempts));
    EXPECT_EQ(x.region.min, y.region.min);
    EXPECT_EQ(x.region.max, y.region.max);
    EXPECT_EQ(x.velocity, y.velocity);
    ASSERT_EQ(x.mix.size(), y.mix.size());
    for (std::size_t k = 0; k < x.mix.size(); ++k) {
      EXPECT_EQ(
          std::tie(x.mix[k].material, x.mix[k].mass_fraction, x.mix[k].shape, x.mix[k].shape_size),
          std::tie(y.mix[k].material, y.mix[k].mass_fraction, y.mix[k].shape, y.mix[k].shape_size));
      expect_same_size(x.mix[k].size, y.mix[k].size);
    }
  }
  ASSERT_EQ(a.collectors.size(), b.collectors.size());
  for (std::size_t i = 0; i < a.collectors.size(); ++i) {
    const Collector& x = a.collectors[i];
    const Collector& y = b.collectors[i];
    EXPECT_EQ(std::tie(x.name, x.from, x.to, x.bins), std::tie(y.name, y.from, y.to, y.bins));
    EXPECT_EQ(x.point, y.point);
    EXPECT_EQ(x.normal, y.normal);
    EXPECT_EQ(x.axis, y.axis);
    ASSERT_EQ(x.products.size(), y.products.size());
    for (std::size_t k = 0; k < x.products.size(); ++k)
      EXPECT_EQ(std::tie(x.products[k].name, x.products[k].from, x.products[k].to),
                std::tie(y.products[k].name, y.products[k].from, y.products[k].to));
  }
  ASSERT_EQ(a.domain.has_value(), b.domain.has_value());
  if (a.domain) {
    EXPECT_EQ(a.domain->min, b.domain->min);
    EXPECT_EQ(a.domain->max, b.domain->max);
  }
  EXPECT_EQ(a.output.dir, b.output.dir);
  EXPECT_EQ(a.output.trajectories.every, b.output.trajectories.every);
  EXPECT_EQ(a.output.trajectories.vtk, b.output.trajectories.vtk);
  EXPECT_EQ(a.output.trajectories.csv, b.output.trajectories.csv);
  EXPECT_EQ(a.output.steps_csv, b.output.steps_csv);
  EXPECT_EQ(a.output.distribution_svg, b.output.distribution_svg);
  EXPECT_EQ(a.active_components, b.active_components);
}

// hopper.yaml spells some values in other units ("2.5 g/cm^3", "1 /ms"):
// exact decimal conversion makes the models bit-identical anyway.
TEST(SceneFormats, YamlAndJsonTwinsCompileToTheSameModel) {
  expect_same_simulation(load(kScenes + "hopper.yaml"), load(kScenes + "hopper.json"));
}

TEST(SceneFormats, JsonIsStrict) {
  TempDir dir;
  const auto errors = load_errors(dir.write("a.json", "{\"ces_sim\": 1, # comment\n}"));
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].line, 1);
  EXPECT_NE(errors[0].message.find("invalid JSON"), std::string::npos);
}

// ------------------------------------------------------------------ resolved scene

// ces_pcb.yaml has a static electrode, whose corona keys the resolved
// scene must not write (they would be refused on loading it again, as
// ces-sim resume does).
TEST(SceneResolved, ReloadsToTheSameSimulation) {
  for (const char* name : {"default.yaml", "hopper.json", "ces_pcb.yaml"}) {
    SCOPED_TRACE(name);
    const Simulation sim = load(kScenes + name);
    // The resolved scene is YAML whatever the input was; its paths are
    // relative to the scene's folder.
    const Simulation again = load_text(sim.resolved_yaml, kScenes + "scene.resolved.yaml");
    expect_same_simulation(sim, again);
    EXPECT_EQ(again.resolved_yaml, sim.resolved_yaml);
    EXPECT_EQ(again.scene_hash, sim.scene_hash);
  }
}

TEST(SceneResolved, HashFollowsTheResolvedText) {
  const Simulation a = load(kScenes + "default.yaml");
  LoadOptions seed;
  seed.overrides = {{"seed", "43"}};
  const Simulation b = load(kScenes + "default.yaml", seed);
  EXPECT_NE(a.scene_hash, b.scene_hash);
  EXPECT_EQ(a.scene_hash, load(kScenes + "default.yaml").scene_hash);
}

// ------------------------------------------------------------------ compile only what is used

TEST(SceneComponents, JointsMotorsAndDynamicBodies) {
  TempDir dir;
  const Simulation sim = load(dir.write(
      "j.yaml",
      std::string(kMinimal) +
          "gravity: [0, -9.81, 0]\n"
          "materials: {steel: {density: 7800}}\n"
          "bodies:\n"
          "  - name: paddle\n"
          "    geometry: {box: {size: [0.2, 0.02, 0.1]}}\n"
          "    pose: {rotation: {axis: [0, 0, 1], angle: 90 deg}}\n"
          "    material: steel\n"
          "    dynamic: {}\n"
          "  - name: slider\n"
          "    geometry: {cylinder: {radius: 0.05, length: 0.1, thickness: 0.01}}\n"
          "    material: steel\n"
          "    dynamic: {mass: 2 kg}\n"
          "joints:\n"
          "  - {name: hinge, type: revolute, body_b: paddle}\n"
          "  - {name: rail, type: prismatic, body_a: ground, body_b: slider, axis: [2, 0, 0]}\n"
          "motors:\n"
          "  - {joint: hinge, speed: 60 rpm, max_force: 3 N m}\n"
          "  - {joint: rail, position: 5 mm, max_speed: 0.1 m/s}\n"));
  const Model& m = *sim.model;
  EXPECT_EQ(
      sim.active_components,
      (std::vector<std::string>{"gravity", "contacts", "dynamic_bodies", "joints", "motors"}));
  EXPECT_TRUE(m.shapes.empty());  // no feed, no particle template
  const RigidBody& paddle = m.bodies[0];
  EXPECT_DOUBLE_EQ(paddle.mass, 7800 * 0.2 * 0.02 * 0.1);
  EXPECT_DOUBLE_EQ(paddle.inertia.z(), paddle.mass * (0.2 * 0.2 + 0.02 * 0.02) / 12);
  EXPECT_TRUE((paddle.pose.orientation * Vec3::UnitX()).isApprox(Vec3::UnitY()));
  const RigidBody& slider = m.bodies[1];
  EXPECT_EQ(slider.mass, 2.0);
  EXPECT_DOUBLE_EQ(slider.inertia.z(), 2.0 * (0.05 * 0.05 + 0.04 * 0.04) / 2);
  ASSERT_EQ(m.joints.size(), 2u);
  EXPECT_EQ(m.joints[1].body_a, -1);
  EXPECT_EQ(m.joints[1].axis, Vec3::UnitX());
  ASSERT_EQ(m.motors.size(), 2u);
  EXPECT_EQ(m.motors[0].mode, Motor::Mode::Speed);
  EXPECT_DOUBLE_EQ(m.motors[0].target, 2 * std::numbers::pi);
  EXPECT_EQ(m.motors[0].max_force, 3.0);
  EXPECT_EQ(m.motors[1].mode, Motor::Mode::Position);
  EXPECT_EQ(m.motors[1].target, 0.005);
  EXPECT_EQ(m.motors[1].max_speed, 0.1);
  EXPECT_TRUE(std::isinf(m.motors[1].max_force));
}

TEST(SceneComponents, UnusedTemplatesAreNotBuilt) {
  TempDir dir;
  const Simulation sim = load(dir.write(
      "f.yaml",
      std::string(kMinimal) +
          "materials: {glass: {density: 2500}}\n"
          "shapes:\n"
          "  rod: {spheres: [[0, 0, 0, 1], [1, 0, 0, 1]]}\n"
          "  unused: {spheres: [[0, 0, 0, 1], [0, 1, 0, 1]]}\n"
          "feeds:\n"
          "  - name: outlet\n"
          "    region: {outlet: {center: [0, 1, 0], size: [0.04, 0.1], normal: [0, -1, 0]}}\n"
          "    rate: 20 g/s\n"
          "    mix:\n"
          "      - material: glass\n"
          "        fraction: 0.5\n"
          "        size: {lognormal: {median: 1 mm, sigma: 0.2}}\n"
          "      - {material: glass, fraction: 0.25, size: {constant: 1 mm}, shape: rod}\n"
          "      - {material: glass, fraction: 0.25, size: {constant: 2 mm}, shape: rod}\n"));
  ASSERT_EQ(sim.model->shapes.size(), 2u);  // sphere and rod, not unused
  EXPECT_EQ(sim.feeds[0].mass_rate, 0.02);
  EXPECT_EQ(sim.feeds[0].mix[1].shape, sim.feeds[0].mix[2].shape);  // compiled once
  // By default the size is the bounding diameter about the centre of mass
  // (overlapping spheres: the centre comes from numerical integration).
  EXPECT_NEAR(sim.feeds[0].mix[1].shape_size, 3.0, 1e-6);
  EXPECT_EQ(sim.feeds[0].region.min, Vec3(-0.02, 1, -0.05));
  EXPECT_EQ(sim.feeds[0].region.max, Vec3(0.02, 1, 0.05));
  EXPECT_EQ(sim.active_components, (std::vector<std::string>{"contacts", "clusters", "feeds"}));
}

}  // namespace
}  // namespace ces::scene
