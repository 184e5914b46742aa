// Scene files in: units, includes, overrides, YAML/JSON parity,
// the resolved scene, active components, and the bad-scene suite.
#include "scene/scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <variant>

#include "scene/units.hpp"

namespace ces::scene {
namespace {

namespace fs = std::filesystem;

const std::string kScenes = std::string(CES_SOURCE_DIR) + "/scenes/";
const std::string kBadSceneDir = std::string(CES_TEST_DIR) + "/bad_scenes/";

// A fresh folder per test, removed at the end.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("ces_scene_" + std::string(info->test_suite_name()) + "_" + info->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = path_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
    return p.string();
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// The diagnostics a load throws; fails the test if it does not throw.
std::vector<Diagnostic> load_errors(const std::string& path, const LoadOptions& options = {}) {
  try {
    load(path, options);
  } catch (const SceneError& e) {
    return e.diagnostics();
  }
  ADD_FAILURE() << path << " loaded without errors";
  return {};
}

std::string all(const std::vector<Diagnostic>& list) {
  std::string s;
  for (const Diagnostic& d : list) s += d.str() + "\n";
  return s;
}

constexpr const char* kMinimal = "ces_sim: 1\ntime: {step: 1 ms, end: 0.1 s}\n";

// ------------------------------------------------------------------ units

struct UnitCase {
  const char* text;
  double si;
  const char* kind;
};

TEST(SceneUnits, ParsesToSiWithDimension) {
  const double pi = std::numbers::pi;
  const UnitCase cases[] = {
      {"0.8 mm", 0.0008, "length"},
      {"1.5e-3 km", 1.5, "length"},
      {"5 um", 5e-6, "length"},
      {"5 \u00b5m", 5e-6, "length"},
      {"12", 12.0, nullptr},
      {"1 ms", 0.001, "time"},
      {"2 min", 120.0, "time"},
      {"44.8 rpm", 44.8 * 2.0 * pi / 60.0, "angular_speed"},
      {"30 deg", 30.0 * pi / 180.0, "angle"},
      {"-35 kV", -35000.0, "voltage"},
      {"20 g/s", 0.02, "mass_rate"},
      {"3.6 t/h", 1.0, "mass_rate"},
      {"2000 /s", 2000.0, "count_rate"},
      {"2000 1/s", 2000.0, "count_rate"},
      {"50 Hz", 50.0, "count_rate"},
      {"8960 kg/m^3", 8960.0, "density"},
      {"8.96 g/cm^3", 8960.0, "density"},
      {"9.81 m/s^2", 9.81, "acceleration"},
      {"0.5 m/s", 0.5, "speed"},
      {"0.02 kg m^2", 0.02, "inertia"},
      {"2 N m", 2.0, "torque"},
      {"10 N", 10.0, "force"},
      {"1e12 ohm m", 1e12, "resistivity"},
      {"+2 kg", 2.0, "mass"},
  };
  for (const UnitCase& c : cases) {
    SCOPED_TRACE(c.text);
    const auto parsed = units::parse(c.text);
    ASSERT_TRUE(std::holds_alternative<units::Quantity>(parsed)) << std::get<std::string>(parsed);
    const auto& q = std::get<units::Quantity>(parsed);
    EXPECT_DOUBLE_EQ(q.value, c.si);
    if (c.kind)
      EXPECT_EQ(q.dimension, units::find_kind(c.kind)->dimension);
    else
      EXPECT_EQ(q.dimension, units::Dimension{});
  }
}

// Powers of ten are applied to the decimal exponent, so a value written with
// a prefix is the same double as the SI value written out.
TEST(SceneUnits, DecimalPrefixesAreExact) {
  const std::pair<const char*, double> cases[] = {
      {"0.8 mm", 0.0008}, {"0.1 mm", 1e-4},       {"1.2 mm", 0.0012},
      {"0.3 ms", 3e-4},   {"2.5 g/cm^3", 2500.0},
  };
  for (const auto& [text, si] : cases)
    EXPECT_EQ(std::get<units::Quantity>(units::parse(text)).value, si) << text;
}

TEST(SceneUnits, RejectsWhatIsNotAQuantity) {
  for (const char* text : {"mm", "5 parsecs", "5 m/", "5 ^2", "", "1 m^x"}) {
    EXPECT_TRUE(std::holds_alternative<std::string>(units::parse(text))) << text;
  }
  EXPECT_EQ(std::get<std::string>(units::parse("5 parsecs")), "unknown unit 'parsecs'");
}

// Out of a double's range, or past the bounds on powers: refused, never
// read as another number (the exponent used to be dropped: 4e99999 s = 4 s).
TEST(SceneUnits, RefusesNumbersOutOfRange) {
  for (const char* text : {"4e99999999999 s", "4e-99999999999 s", "1e309 m", "1e-320 s", "1e-400",
                           "2e308", "1e-300 mm^3", "1e303 km^2"}) {
    const auto parsed = units::parse(text);
    ASSERT_TRUE(std::holds_alternative<std::string>(parsed)) << text;
    EXPECT_NE(std::get<std::string>(parsed).find("number out of range"), std::string::npos)
        << text << ": " << std::get<std::string>(parsed);
  }
  for (const char* text : {"4 s^99999999999", "1 km^1000000000", "1 m^17", "1 m^-17", "1 m^8 m^9",
                           "1 kg/g kg/g", "1 s^-99999999999999999999"}) {
    const auto parsed = units::parse(text);
    if (std::string(text) == "1 kg/g kg/g") {  // 1e6, dimensionless: within every bound
      EXPECT_EQ(std::get<units::Quantity>(parsed).value, 1e6);
      continue;
    }
    ASSERT_TRUE(std::holds_alternative<std::string>(parsed)) << text;
    EXPECT_NE(std::get<std::string>(parsed).find("a unit power beyond 16"), std::string::npos)
        << text << ": " << std::get<std::string>(parsed);
  }
  // Zero is zero however written; the largest and smallest normal doubles pass.
  EXPECT_EQ(std::get<units::Quantity>(units::parse("0e-99999 s")).value, 0.0);
  EXPECT_EQ(std::get<units::Quantity>(units::parse("1.7976931348623157e308")).value,
            1.7976931348623157e308);
  EXPECT_EQ(std::get<units::Quantity>(units::parse("2.2250738585072014e-305 mm")).value,
            2.2250738585072014e-308);
  EXPECT_EQ(std::get<units::Quantity>(units::parse("1 m^16")).dimension.exponent[1], 16);
}

// A thousand factors cancel to a plain number: bounded all the way.
TEST(SceneUnits, LongExpressionsStayBounded) {
  std::string text = "1";
  for (int i = 0; i < 1000; ++i) text += " kg/g";
  EXPECT_NE(std::get<std::string>(units::parse(text)).find("a unit power beyond 16"),
            std::string::npos);
  text = "1";
  for (int i = 0; i < 17; ++i) text += " m";
  EXPECT_TRUE(std::holds_alternative<std::string>(units::parse(text)));
}

TEST(SceneUnits, DescribesDimensions) {
  EXPECT_EQ(units::describe(units::find_kind("mass_rate")->dimension), "a mass rate (kg/s)");
  EXPECT_EQ(units::describe(std::get<units::Quantity>(units::parse("3 kg m/s")).dimension),
            "kg m/s");
}

// ------------------------------------------------------------------ schema

// Every x-unit of the schema must name a kind the units module knows.
void check_units(const nlohmann::json& s, std::set<std::string>& seen) {
  if (s.is_object()) {
    if (auto it = s.find("x-unit"); it != s.end()) {
      for (const auto& name : it->is_array() ? *it : nlohmann::json::array({*it})) {
        EXPECT_NE(units::find_kind(name.get<std::string>()), nullptr) << name;
        seen.insert(name.get<std::string>());
      }
    }
  }
  if (s.is_structured())
    for (const auto& child : s) check_units(child, seen);
}

TEST(SceneSchema, IsDraft7JsonWithKnownUnits) {
  const nlohmann::json schema = nlohmann::json::parse(schema_text());
  EXPECT_EQ(schema["$schema"], "http://json-schema.org/draft-07/schema#");
  std::set<std::string> seen;
  check_units(schema, seen);
  EXPECT_TRUE(seen.count("length") && seen.count("mass_rate") && seen.count("angular_speed"));
}

TEST(SceneSchema, MinimalSceneGetsDefaults) {
  TempDir dir;
  const Simulation sim = load(dir.write("tiny.yaml", kMinimal));
  EXPECT_EQ(sim.name, "tiny");
  EXPECT_EQ(sim.seed, 0u);
  EXPECT_EQ(sim.model->solver.method, SolverMethod::APGD);
  EXPECT_EQ(sim.model->solver.max_iterations, 100);
  EXPECT_DOUBLE_EQ(sim.model->contact.envelope_fraction, 0.25);
  EXPECT_EQ(sim.model->gravity, Vec3::Zero());
  EXPECT_EQ(sim.output.dir, "out");
  EXPECT_TRUE(sim.active_components.empty());
  EXPECT_NE(sim.resolved_yaml.find("warm_start: true"), std::string::npos);
}

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
  EXPECT_DOUBLE_EQ(m.materials.friction(2, 0), 0.25);  // glass/steel override
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
      EXPECT_EQ(a.materials.friction(int(i), int(j)), b.materials.friction(int(i), int(j)));
      EXPECT_EQ(a.materials.restitution(int(i), int(j)), b.materials.restitution(int(i), int(j)));
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

TEST(SceneResolved, ReloadsToTheSameSimulation) {
  for (const char* name : {"default.yaml", "hopper.json"}) {
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

// ------------------------------------------------------------------ includes

TEST(SceneIncludes, MergeRelativeToTheIncludingFile) {
  TempDir dir;
  dir.write("lib/materials.yaml",
            "materials:\n  steel: {friction: 0.3}\n  copper: {density: 8960, friction: 0.3, "
            "restitution: 0.2}\n");
  dir.write("machines/meshes/plate.stl",
            "solid p\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
            "vertex 0 1 0\nendloop\nendfacet\nendsolid p\n");
  dir.write("machines/drum.yaml",
            "include: ../lib/materials.yaml\n"
            "bodies:\n"
            "  - {name: drum, geometry: {cylinder: {radius: 0.16, length: 0.3}}, material: steel}\n"
            "  - {name: plate, geometry: {mesh: {file: meshes/plate.stl}}, material: steel}\n");
  const std::string scene = dir.write(
      "scenes/main.yaml",
      "ces_sim: 1\n"
      "include: [../machines/drum.yaml]\n"
      "time: {step: 1 ms, end: 0.1 s}\n"
      "materials:\n  copper: {friction: 0.5}\n"  // overrides one key
      "bodies:\n  - {name: wall, geometry: {box: {size: [1, 1, 1]}}, material: copper}\n");
  LoadOptions options;  // machines/ and lib/ are beside the scene's folder
  options.include_paths = {dir.path().string()};
  const Simulation sim = load(scene, options);
  const auto& materials = sim.model->materials.materials();
  ASSERT_EQ(materials.size(), 2u);
  EXPECT_EQ(materials[1].name, "copper");
  EXPECT_EQ(materials[1].friction, 0.5);     // the including file wins
  EXPECT_EQ(materials[1].restitution, 0.2);  // the rest of the library's entry stays
  ASSERT_EQ(sim.model->bodies.size(), 3u);   // lists concatenate, included first
  EXPECT_EQ(sim.model->bodies[0].name, "drum");
  EXPECT_EQ(sim.model->bodies[2].name, "wall");
  // The mesh path was relative to machines/; the resolved scene says it
  // relative to scenes/.
  EXPECT_NE(sim.resolved_yaml.find("\"../machines/meshes/plate.stl\""), std::string::npos);
  EXPECT_EQ(sim.resolved_yaml.find("include"), std::string::npos);
}

TEST(SceneIncludes, LaterIncludesWin) {
  TempDir dir;
  dir.write("a.yaml", "solver: {max_iterations: 10, tolerance: 1e-3}\n");
  dir.write("b.yaml", "solver: {max_iterations: 20}\n");
  const Simulation sim =
      load(dir.write("main.yaml", std::string(kMinimal) + "include: [a.yaml, b.yaml]\n"));
  EXPECT_EQ(sim.model->solver.max_iterations, 20);
  EXPECT_EQ(sim.model->solver.tolerance, 1e-3);
}

TEST(SceneIncludes, CycleIsReportedWithTheChain) {
  TempDir dir;
  dir.write("b.yaml", "include: c.yaml\n");
  dir.write("c.yaml", "include: b.yaml\n");
  const auto errors = load_errors(dir.write("a.yaml", std::string(kMinimal) + "include: b.yaml\n"));
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  EXPECT_TRUE(errors[0].file.ends_with("c.yaml"));
  EXPECT_EQ(errors[0].line, 1);
  EXPECT_NE(errors[0].message.find("include cycle: "), std::string::npos);
  EXPECT_NE(errors[0].message.find("b.yaml -> "), std::string::npos);
}

TEST(SceneIncludes, SelfIncludeIsACycle) {
  TempDir dir;
  const auto errors = load_errors(dir.write("a.yaml", std::string(kMinimal) + "include: a.yaml\n"));
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  EXPECT_EQ(errors[0].line, 3);
  EXPECT_NE(errors[0].message.find("include cycle"), std::string::npos);
}

// ------------------------------------------------------------------ --set

LoadOptions sets(std::vector<std::pair<std::string, std::string>> overrides) {
  LoadOptions o;
  o.overrides = std::move(overrides);
  return o;
}

TEST(SceneOverrides, ReplaceAndCreateKeys) {
  const Simulation sim =
      load(kScenes + "default.yaml", sets({
                                         {"solver.max_iterations", "7"},
                                         {"time.end", "20 ms"},
                                         {"bodies.drum.material", "copper"},
                                         {"bodies[0].pose.position", "[0, 1 mm, 0]"},
                                         {"feeds.0.velocity_spread", "0"},
                                         {"contact.envelope", "0.5"},
                                     }));
  EXPECT_EQ(sim.model->solver.max_iterations, 7);
  EXPECT_EQ(sim.end_time, 0.02);
  EXPECT_EQ(sim.model->materials.materials()[std::size_t(sim.model->bodies[0].material)].name,
            "copper");
  EXPECT_EQ(sim.model->bodies[0].pose.position, Vec3(0, 0.001, 0));
  EXPECT_EQ(sim.feeds[0].velocity_spread, 0.0);
  EXPECT_EQ(sim.model->contact.envelope_fraction, 0.5);
  EXPECT_NE(sim.resolved_yaml.find("max_iterations: 7"), std::string::npos);
}

TEST(SceneOverrides, CreateNestedSection) {
  TempDir dir;
  const Simulation sim =
      load(dir.write("s.yaml", kMinimal),
           sets({{"output.trajectories.every", "5 ms"}, {"gravity", "[0, -9.81, 0]"}}));
  EXPECT_EQ(sim.output.trajectories.every, 0.005);
  EXPECT_TRUE(sim.output.trajectories.vtk);  // the default format
  EXPECT_EQ(sim.model->gravity, Vec3(0, -9.81, 0));
}

// The reference separator, a newcomer's first run, writes frames to open in
// ParaView: VTK, at least ten over the run, and coarse (no more than one
// per 100 steps).
TEST(SceneOverrides, ReferenceSeparatorWritesCoarseVtkFrames) {
  const Simulation sim = load(kScenes + "ces_pcb.yaml");
  const double every = sim.output.trajectories.every;
  EXPECT_TRUE(sim.output.trajectories.vtk);
  EXPECT_GE(sim.end_time / every, 10.0);
  EXPECT_GE(every / sim.model->step, 100.0);
}

// A scene's trajectories switched off from the command line.
TEST(SceneOverrides, TrajectoriesFormatNoneWritesNoFrames) {
  TempDir dir;
  const std::string path = dir.write(
      "s.yaml", std::string(kMinimal) + "output: {trajectories: {every: 5 ms, format: both}}\n");
  const Simulation on = load(path);
  EXPECT_TRUE(on.output.trajectories.every > 0.0 && on.output.trajectories.csv);
  const Simulation off = load(path, sets({{"output.trajectories.format", "none"}}));
  EXPECT_EQ(off.output.trajectories.every, 0.0);
  EXPECT_FALSE(off.output.trajectories.vtk || off.output.trajectories.csv);
  EXPECT_EQ(std::count(off.active_components.begin(), off.active_components.end(), "trajectories"),
            0);
}

// The contact model and its elastic constants, as `study --vary
// contact.model=dvi,dem` sets them: global constants, a material's own wins.
TEST(SceneOverrides, ContactModelAndDemConstants) {
  TempDir dir;
  const std::string path = dir.write("s.yaml", std::string(kMinimal) + R"(
materials:
  soft: {density: 1000, youngs_modulus: 5 MPa}
  hard: {density: 1000, poisson_ratio: 0.2}
)");
  EXPECT_EQ(load(path).model->contact_model, ContactModel::DVI);
  const Simulation sim = load(path, sets({{"contact.model", "dem"},
                                          {"contact.dem.youngs_modulus", "20 MPa"},
                                          {"contact.dem.min_restitution", "0.1"}}));
  const DemSettings& dem = sim.model->dem;
  EXPECT_EQ(sim.model->contact_model, ContactModel::DEM);
  EXPECT_EQ(dem.min_restitution, 0.1);
  EXPECT_EQ(dem.elastic(0).youngs_modulus, 5e6);   // soft: its own
  EXPECT_EQ(dem.elastic(0).poisson_ratio, 0.3);    // the default
  EXPECT_EQ(dem.elastic(1).youngs_modulus, 20e6);  // hard: the scene's
  EXPECT_EQ(dem.elastic(1).poisson_ratio, 0.2);
}

TEST(SceneOverrides, SeedAndThreadsOptions) {
  LoadOptions o;
  o.seed = 1234;
  o.threads = 2;
  const Simulation sim = load(kScenes + "default.yaml", o);
  EXPECT_EQ(sim.seed, 1234u);
  EXPECT_EQ(sim.model->threads, 2);
  EXPECT_NE(sim.resolved_yaml.find("seed: 1234"), std::string::npos);
}

TEST(SceneOverrides, InvalidPathsAreReported) {
  const auto errors = load_errors(kScenes + "default.yaml", sets({
                                                                {"solver.max_iterations", "5"},
                                                                {"bodies.nope.material", "copper"},
                                                                {"time.step.unit", "ms"},
                                                                {"solver..method", "apgd"},
                                                            }));
  ASSERT_EQ(errors.size(), 3u) << all(errors);
  EXPECT_EQ(errors[0].str(),
            "--set:2:1: bodies.nope.material: invalid override path: 'bodies' has no item 'nope', "
            "expected an index "
            "below 1 or the name of an item");
  EXPECT_EQ(errors[1].line, 3);
  EXPECT_NE(errors[1].message.find("'time.step' is '1 ms', not a mapping or a list"),
            std::string::npos);
  EXPECT_EQ(errors[2].line, 4);
  EXPECT_NE(errors[2].message.find("invalid override path"), std::string::npos);
}

TEST(SceneOverrides, BadValuesPointAtTheOverride) {
  const auto errors = load_errors(kScenes + "default.yaml",
                                  sets({{"solver.method", "fast"}, {"time.step", "2 kg"}}));
  ASSERT_EQ(errors.size(), 2u) << all(errors);
  EXPECT_EQ(errors[0].str(),
            "--set:1:1: solver.method: got 'fast', expected one of apgd, spg, psor or pgs");
  EXPECT_EQ(errors[1].str(),
            "--set:2:1: time.step: '2 kg' is a mass (kg), expected a time (s), e.g. \"1 ms\"");
}

// ------------------------------------------------------------------ set:

// A machine fragment made wider by the scene that includes it: the merge
// cannot change an item of its bodies list, set can; --set still wins.
TEST(SceneSet, ChangesAnIncludedListItemBeforeTheCommandLine) {
  TempDir dir;
  dir.write("machine.yaml",
            "materials: {steel: {friction: 0.5}}\n"
            "bodies:\n"
            "  - {name: drum, geometry: {cylinder: {radius: 0.16, length: 0.3}}, material: steel}\n"
            "domain: {box: {min: [-1, -1, -0.2], max: [1, 1, 0.2]}}\n");
  const std::string scene =
      dir.write("wide.yaml", std::string(kMinimal) +
                                 "include: machine.yaml\n"
                                 "set:\n"
                                 "  bodies.drum.geometry.cylinder.length: 1 m\n"
                                 "  domain.box.min: [-1, -1, -0.6]\n"
                                 "  solver.max_iterations: 9\n");
  const Simulation sim = load(scene);
  const auto& drum = std::get<geo::Cylinder>(sim.model->bodies.at(0).shape);
  EXPECT_EQ(2.0 * drum.half_length, 1.0);
  EXPECT_EQ(sim.domain->min, Vec3(-1, -1, -0.6));  // replaced, not concatenated
  EXPECT_EQ(sim.model->solver.max_iterations, 9);
  EXPECT_EQ(sim.resolved_yaml.find("set:"), std::string::npos);
  EXPECT_EQ(load(scene, sets({{"solver.max_iterations", "4"}})).model->solver.max_iterations, 4);
}

TEST(SceneSet, BadPathsNameTheFileAndLine) {
  TempDir dir;
  const std::string scene = dir.write(
      "s.yaml", std::string(kMinimal) +
                    "set:\n"
                    "  bodies.nope.material: copper\n"
                    "  time.step.unit: ms\n"
                    "  include: a.yaml\n"
                    "materials: {steel: {}}\n"
                    "bodies: [{name: wall, geometry: {box: {size: [1, 1, 1]}}, material: steel}]\n");
  const auto errors = load_errors(scene);
  ASSERT_EQ(errors.size(), 3u) << all(errors);
  EXPECT_EQ(errors[0].line, 4);
  EXPECT_EQ(errors[0].path, "set.bodies.nope.material");
  EXPECT_NE(errors[0].message.find("invalid override path"), std::string::npos);
  EXPECT_EQ(errors[1].line, 5);
  EXPECT_NE(errors[1].message.find("'time.step' is '1 ms', not a mapping or a list"),
            std::string::npos);
  EXPECT_EQ(errors[2].line, 6);
  EXPECT_NE(errors[2].message.find("'include' cannot be overridden"), std::string::npos);
  const auto list = load_errors(dir.write("l.yaml", std::string(kMinimal) + "set: [1, 2]\n"));
  ASSERT_EQ(list.size(), 1u) << all(list);
  EXPECT_NE(list[0].message.find("expected a mapping of key paths to values"), std::string::npos);
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

// ------------------------------------------------------------------ bad scenes

struct Expected {
  const char* file;   // in tests/bad_scenes/
  const char* where;  // the file the diagnostic names (may be a fragment)
  int line;
  const char* message;  // a substring of "key.path: message"
};

const Expected kExpectations[] = {
    {"aspect_on_sphere.yaml", "aspect_on_sphere.yaml", 13,
     "feeds[0].mix[0].aspect: 'sphere' has no aspect, expected aspect only with flake or rod"},
    {"bad_enum.yaml", "bad_enum.yaml", 3,
     "solver.method: got 'apdg', expected one of apgd, spg, psor or pgs (did you mean 'apgd'?)"},
    {"bins_count_zero.yaml", "bins_count_zero.yaml", 6,
     "collectors[0].bins.count: 0 is out of range, expected >= 1"},
    {"bins_reversed.yaml", "bins_reversed.yaml", 6,
     "collectors[0].bins.to: to 0.1 m is not above from 0.4 m"},
    {"corrupt_mesh.yaml", "corrupt_mesh.yaml", 9, "bodies[0].geometry.mesh.file: cannot load mesh"},
    {"dem_modulus_not_a_pressure.yaml", "dem_modulus_not_a_pressure.yaml", 5,
     "contact.dem.youngs_modulus: '10 mm' is a length (m), expected a pressure (Pa)"},
    {"dem_poisson_out_of_range.yaml", "dem_poisson_out_of_range.yaml", 8,
     "materials.rubber.poisson_ratio: 0.5 is out of range, expected < 0.5"},
    {"dem_unknown_model.yaml", "dem_unknown_model.yaml", 3,
     "contact.model: got 'dme', expected one of dvi or dem (did you mean 'dem'?)"},
    {"duplicate_body.yaml", "duplicate_body.yaml", 10,
     "duplicate body name 'drum', first given at line 7"},
    {"duplicate_key.json", "duplicate_key.json", 6,
     "materials.copper: duplicate key 'copper', first given at line 5"},
    {"duplicate_key.yaml", "duplicate_key.yaml", 7,
     "materials.copper.density: duplicate key 'density', first given at line 5"},
    {"dynamic_mesh.yaml", "dynamic_mesh.yaml", 10,
     "a mesh has no volume to take a mass from, expected mass and inertia"},
    {"es_bipolar_two_electrodes.yaml", "es_bipolar_two_electrodes.yaml", 20,
     "electrostatics.field.model: bipolar is the field of exactly one electrode, the scene lists "
     "2"},
    {"es_conduction_unknown.yaml", "es_conduction_unknown.yaml", 5,
     "materials.copper: material 'copper' is fed into the separator but does not say how it "
     "conducts"},
    {"es_corona_below_onset.yaml", "es_corona_below_onset.yaml", 22,
     "electrostatics.electrodes[0].voltage: at 5 kV the wire is below its corona onset of 8.91 kV "
     "(Peek's 126 kV/cm at its surface), expected a voltage above onset"},
    {"es_corona_bipolar.yaml", "es_corona_bipolar.yaml", 22,
     "electrostatics.electrodes[0].type: a corona electrode needs the field of every electrode at "
     "the wire, expected field.model: line_charges"},
    {"es_corona_reversed.yaml", "es_corona_reversed.yaml", 23,
     "electrostatics.corona[0].to: the sector from 75 deg to 30 deg is empty or reversed"},
    {"es_corona_thick_wire.yaml", "es_corona_thick_wire.yaml", 22,
     "electrostatics.electrodes[0].radius: a corona wire of radius 5 mm does not ionise, expected "
     "a radius of at most 1 mm"},
    {"es_electrode_in_drum.yaml", "es_electrode_in_drum.yaml", 21,
     "electrostatics.electrodes[0].polar: electrode 'hv' reaches 0.131 m from the drum axis, "
     "inside the drum (radius 0.16 m)"},
    {"es_electrodes_overlap.yaml", "es_electrodes_overlap.yaml", 23,
     "electrostatics.electrodes[1]: overlaps electrode 'hv'"},
    {"es_grid_bad_row.yaml", "es_grid_bad_row.yaml", 20,
     "fields/bad_row.csv:3: z is not a finite number: 'zero'"},
    {"es_grid_missing.yaml", "es_grid_missing.yaml", 20,
     "fields/nowhere.csv: cannot open the field file"},
    {"es_insulator_without_permittivity.yaml", "es_insulator_without_permittivity.yaml", 6,
     "materials.fr4: material 'fr4' is (partly) an insulator, whose corona charge needs its "
     "relative_permittivity"},
    {"es_unknown_brush.yaml", "es_unknown_brush.yaml", 20,
     "electrostatics.brush: unknown body 'brsh'"},
    {"es_unknown_drum.yaml", "es_unknown_drum.yaml", 19,
     "electrostatics.drum: unknown body 'drun' (did you mean 'drum'?)"},
    {"feed_outside_domain.yaml", "feed_outside_domain.yaml", 8,
     "feeds[0].region: the region reaches outside the domain"},
    {"feed_too_small.yaml", "feed_too_small.yaml", 8,
     "the region is 0.0005 m wide along x but the largest particles are 0.001 m across"},
    {"field_picture_without_field.yaml", "field_picture_without_field.yaml", 8,
     "output.field: the field picture needs a field, expected an electrostatics section"},
    {"fractions_sum.yaml", "fractions_sum.yaml", 11,
     "feeds[0].mix: the fractions add up to 0.9, expected 1"},
    {"geometry_two_shapes.yaml", "geometry_two_shapes.yaml", 8,
     "got 2 (box and cylinder), expected exactly one of plane, box, cylinder or mesh"},
    {"include_cycle.yaml", "fragments/cycle_b.yaml", 1, "include cycle: "},
    {"include_missing.yaml", "include_missing.yaml", 4,
     "fragments/no_such_machine.yaml': no such file"},
    {"joint_without_dynamic_body.yaml", "joint_without_dynamic_body.yaml", 11,
     "joints[0].body_b: neither body is dynamic"},
    {"json_syntax.json", "json_syntax.json", 4, "invalid JSON: syntax error"},
    {"many_errors.yaml", "many_errors.yaml", 3, "got 'apdg'"},
    {"many_errors.yaml", "many_errors.yaml", 5,
     "materials.copper.density: -1 is out of range, expected > 0 kg/m^3"},
    {"many_errors.yaml", "many_errors.yaml", 5,
     "unknown key 'restitutoin' (did you mean 'restitution'?)"},
    {"many_errors.yaml", "many_errors.yaml", 6,
     "gravity[1]: '-9.81 m/s' is a speed (m/s), expected an acceleration (m/s^2)"},
    {"material_without_density.yaml", "material_without_density.yaml", 11,
     "feeds[0].mix[0].material: material 'steel' has no density"},
    {"missing_end.yaml", "missing_end.yaml", 2,
     "time.end: missing required key 'end', expected a time (s)"},
    {"missing_mesh.yaml", "missing_mesh.yaml", 9, "bad_scenes/meshes/nowhere.stl: no such file"},
    {"missing_time.yaml", "missing_time.yaml", 1, "time: missing required key 'time'"},
    {"motion_and_dynamic.yaml", "motion_and_dynamic.yaml", 11,
     "a body with a prescribed motion cannot be dynamic"},
    {"motor_wrong_kind.yaml", "motor_wrong_kind.yaml", 15,
     "motors[0].speed: '60 rpm' does not fit a prismatic joint, expected a speed (m/s)"},
    {"negative_density.yaml", "negative_density.yaml", 4,
     "'-8960 kg/m^3' is out of range, expected > 0 kg/m^3"},
    {"negative_friction.yaml", "negative_friction.yaml", 4, "-0.1 is out of range, expected >= 0"},
    {"not_a_mapping.yaml", "not_a_mapping.yaml", 1,
     "got a list of 2 items, expected a mapping of scene keys"},
    {"outlet_oblique.yaml", "outlet_oblique.yaml", 9,
     "got an oblique normal, expected one along x, y or z"},
    {"pose_axis_and_rotation.yaml", "pose_axis_and_rotation.yaml", 11,
     "both axis and rotation given"},
    {"product_outside_bins.yaml", "product_outside_bins.yaml", 9,
     "collectors[0].products.heavy: the range leaves the bins [0, 0.4] m"},
    {"products_overlap.yaml", "products_overlap.yaml", 9,
     "collectors[0].products.heavy: overlaps product 'light'"},
    {"rate_without_unit.yaml", "rate_without_unit.yaml", 9,
     "feeds[0].rate: a number without a unit is ambiguous"},
    {"restitution_above_one.yaml", "restitution_above_one.yaml", 6,
     "1.5 is out of range, expected <= 1"},
    {"shape_file_bad_row.yaml", "shape_file_bad_row.yaml", 8,
     "shapes/bad_row.csv:4: expected a row x,y,z,r of numbers with r > 0"},
    {"shell_too_thick.yaml", "shell_too_thick.yaml", 9,
     "a wall of 0.2 m fills the radius (0.16 m)"},
    {"sieve_not_rising.yaml", "sieve_not_rising.yaml", 17,
     "size.sieve[2]: invalid sieve row: sizes must increase"},
    {"step_longer_than_end.yaml", "step_longer_than_end.yaml", 4,
     "step 1 s is longer than the run (end 0.1 s)"},
    {"unit_dimension.yaml", "unit_dimension.yaml", 8,
     "'20 g/s' is a mass rate (kg/s), expected a length (m)"},
    {"unknown_joint_body.yaml", "unknown_joint_body.yaml", 12,
     "unknown body 'padle' (did you mean 'paddle'?)"},
    {"unknown_key.yaml", "unknown_key.yaml", 4,
     "materials.copper.densty: unknown key 'densty' (did you mean 'density'?)"},
    {"unknown_material.yaml", "unknown_material.yaml", 9,
     "unknown material 'stel' (did you mean 'steel'?)"},
    {"unknown_motor_joint.yaml", "unknown_motor_joint.yaml", 14,
     "motors[0].joint: unknown joint 'hinj'"},
    {"unknown_section.yaml", "unknown_section.yaml", 6,
     "unknown key 'colectors' (did you mean 'collectors'?)"},
    {"unknown_shape.yaml", "unknown_shape.yaml", 13,
     "unknown shape 'flak' (did you mean 'flake'?)"},
    {"unknown_unit.yaml", "unknown_unit.yaml", 2,
     "'1 mss': unknown unit 'mss', expected a time (s)"},
    {"vector_length.yaml", "vector_length.yaml", 3,
     "gravity: got a list of 2 items, expected exactly 3 items"},
    {"version.yaml", "version.yaml", 1, "ces_sim: got 2, expected 1"},
    {"wrong_type.yaml", "wrong_type.yaml", 4,
     "solver.max_iterations: got 'many', expected an integer"},
    {"yaml_syntax.yaml", "yaml_syntax.yaml", 4, "invalid YAML: end of sequence flow not found"},
    {"zero_axis.yaml", "zero_axis.yaml", 10,
     "bodies[0].pose.axis: got a zero vector, expected a direction"},
    {"zero_step.yaml", "zero_step.yaml", 3, "time.step: '0 s' is out of range, expected > 0 s"},
    // Hostile input: bounds, numbers out of range, encodings, includes.
    {"alias_bomb.yaml", "alias_bomb.yaml", 4, "the scene expands to more than 200000 values"},
    {"apostrophe_key.yaml", "apostrophe_key.yaml", 3, "typo'd key: unknown key 'typo'd key'"},
    {"bins_count_huge.yaml", "bins_count_huge.yaml", 6,
     "collectors[0].bins.count: 1000000000 is out of range, expected <= 100000"},
    {"data_file_not_regular.yaml", "data_file_not_regular.yaml", 7,
     "shapes.grain.file: cannot read the shape: /dev/zero: not a regular file"},
    {"feed_mass_rate_too_high.yaml", "feed_mass_rate_too_high.yaml", 14,
     "feeds[1].rate: feed 'dust' makes about 4263"},
    {"feed_rate_too_high.yaml", "feed_rate_too_high.yaml", 9,
     "feeds[0].rate: feed 'feeder' makes about 100000000000 particles over the run (all feeds "
     "100000000000), expected at most 10000000 in all"},
    {"include_outside.yaml", "include_outside.yaml", 4,
     "include: '/etc/passwd' is outside the scene's folder"},
    {"include_outside.yaml", "include_outside.yaml", 5,
     "include: '../../../../../../../../etc/shadow' is outside the scene's folder"},
    {"include_outside.yaml", "include_outside.yaml", 6,
     "include: '../scenes/tiny.yaml' is outside the scene's folder"},
    {"integer_wraps.yaml", "integer_wraps.yaml", 3,
     "solver.max_iterations: 2147483648 is out of range, expected <= 1000000"},
    {"invalid_utf8.yaml", "invalid_utf8.yaml", 3, "invalid UTF-8 (byte 0xa1), expected UTF-8 text"},
    {"key_too_long.yaml", "key_too_long.yaml", 4, "a key path longer than 256 characters"},
    {"nesting_too_deep.yaml", "nesting_too_deep.yaml", 3, "nested deeper than 32 levels"},
    {"number_overflow.yaml", "number_overflow.yaml", 3,
     "time.end: '4e99999999999 s': number out of range"},
    {"number_underflow.yaml", "number_underflow.yaml", 3,
     "time.step: '4e-99999999999 s': number out of range"},
    {"plain_number_out_of_range.yaml", "plain_number_out_of_range.yaml", 3,
     "contact.envelope: 1e999 is out of range"},
    {"step_subnormal.yaml", "step_subnormal.yaml", 2, "time.step: '1e-320 s': number out of range"},
    {"shape_too_many_spheres.yaml", "shape_too_many_spheres.yaml", 8,
     "shapes.chain.spheres: a shape of 1001 spheres, expected at most 1000"},
    {"too_many_shapes.yaml", "too_many_shapes.yaml", 27,
     "feeds[0].mix[16].shape: a particle shape past the first 16"},
    {"too_many_materials.yaml", "too_many_materials.yaml", 3,
     "materials: 257 materials, expected at most 256"},
    {"bin_tallies.yaml", "bin_tallies.yaml", 5,
     "collectors: 100000 bins for 101 materials make 10100000 tallies, expected at most "
     "10000000 (fewer bins)"},
    {"trajectory_frames.yaml", "trajectory_frames.yaml", 4,
     "output.trajectories.every: a frame every step (0.001 s) makes 1000000 trajectory frames, "
     "expected at most 100000"},
    {"too_many_steps.yaml", "too_many_steps.yaml", 3,
     "time.step: a step of 1e-06 s makes 100000000 steps to the end (100 s), expected at most "
     "10000000"},
    {"unit_power_overflow.yaml", "unit_power_overflow.yaml", 4,
     "time.end: '4 s^99999999999': a unit power beyond 16"},
    {"unit_power_wraps.yaml", "unit_power_wraps.yaml", 7,
     "'1 km^1000000000': a unit power beyond 16"},
    {"utf8_escape_surrogate.yaml", "utf8_escape_surrogate.yaml", 3,
     "invalid YAML: invalid unicode"},
    // Scenes that load but could not do what they say.
    {"bins_outside_domain.yaml", "bins_outside_domain.yaml", 6,
     "collectors[0].bins: the bins [0.6, 0.9] m lie outside the domain"},
    {"body_outside_domain.yaml", "body_outside_domain.yaml", 12,
     "bodies[1].pose: body 'splitter' lies outside the domain"},
    {"body_outside_domain.yaml", "body_outside_domain.yaml", 16,
     "bodies[2].pose: plane 'ceiling' misses the domain"},
    {"feed_inside_body.yaml", "feed_inside_body.yaml", 14,
     "feeds[0].region: the region lies inside body 'drum', so no particle can be placed"},
    {"voltage_without_unit.yaml", "voltage_without_unit.yaml", 20,
     "electrostatics.electrodes[0].voltage: a number without a unit is ambiguous here, expected "
     "a voltage (V)"},
};

class BadScene : public ::testing::TestWithParam<std::string> {};

// Each bad scene reports each expected problem at its line, and nothing it
// does not expect.
TEST_P(BadScene, ReportsTheProblemAtItsLine) {
  const std::vector<Diagnostic> errors = load_errors(kBadSceneDir + GetParam());
  std::size_t expected = 0;
  for (const Expected& e : kExpectations) {
    if (GetParam() != e.file) continue;
    ++expected;
    const bool found = std::any_of(errors.begin(), errors.end(), [&](const Diagnostic& d) {
      return d.file == kBadSceneDir + e.where && d.line == e.line && d.column > 0 &&
             (d.path + ": " + d.message).find(e.message) != std::string::npos;
    });
    EXPECT_TRUE(found) << "expected at " << e.where << ":" << e.line << ": " << e.message
                       << "\ngot:\n"
                       << all(errors);
  }
  EXPECT_EQ(errors.size(), expected) << all(errors);
}

std::vector<std::string> bad_scene_files() {
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(kBadSceneDir))
    if (entry.is_regular_file()) files.push_back(entry.path().filename().string());
  std::sort(files.begin(), files.end());
  return files;
}

INSTANTIATE_TEST_SUITE_P(Scene, BadScene, ::testing::ValuesIn(bad_scene_files()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param;
                           std::replace_if(
                               name.begin(), name.end(), [](char c) { return !std::isalnum(c); },
                               '_');
                           return name;
                         });

TEST(SceneBadScenes, EveryFileHasExpectations) {
  const auto files = bad_scene_files();
  EXPECT_GE(files.size(), 25u);
  for (const std::string& f : files) {
    const bool listed = std::any_of(std::begin(kExpectations), std::end(kExpectations),
                                    [&](const Expected& e) { return f == e.file; });
    EXPECT_TRUE(listed) << f << " has no expectations in kExpectations";
  }
}

TEST(SceneBadScenes, DiagnosticFormat) {
  const auto errors = load_errors(kBadSceneDir + "unknown_key.yaml");
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].str(),
            kBadSceneDir +
                "unknown_key.yaml:4:12: materials.copper.densty: unknown key 'densty' "
                "(did you mean 'density'?)");
}

}  // namespace
}  // namespace ces::scene
