// Scene files in: includes (merge, order, cycles), command-line overrides
// (--set) and removals (--unset), and the scene's own set: list.
#include "scene/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <variant>

#include "scene_support.hpp"

namespace ces::scene {
namespace {

using test::all;
using test::kMinimal;
using test::kScenes;
using test::load_errors;
using test::TempDir;

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
                                         {"contact.manifold", "four"},
                                     }));
  EXPECT_EQ(sim.model->solver.max_iterations, 7);
  EXPECT_EQ(sim.end_time, 0.02);
  EXPECT_EQ(sim.model->materials.materials()[std::size_t(sim.model->bodies[0].material)].name,
            "copper");
  EXPECT_EQ(sim.model->bodies[0].pose.position, Vec3(0, 0.001, 0));
  EXPECT_EQ(sim.feeds[0].velocity_spread, 0.0);
  EXPECT_EQ(sim.model->contact.envelope_fraction, 0.5);
  EXPECT_EQ(sim.model->contact.manifold, Manifold::Four);
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
  EXPECT_NE(errors[2].message.find("invalid key path 'solver..method', expected keys, indices or "
                                   "item names joined by dots"),
            std::string::npos)
      << all(errors);
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

// ------------------------------------------------------------------ --unset

// A scene with a solver section, a sleep section and two bodies.
std::string scene_to_unset(TempDir& dir) {
  return dir.write(
      "s.yaml",
      std::string(kMinimal) +
          "materials: {steel: {friction: 0.5}}\n"
          "bodies:\n"
          "  - {name: drum, geometry: {cylinder: {radius: 0.16, length: 0.3}}, material: steel}\n"
          "  - {name: floor, geometry: {plane: {point: [0, -0.2, 0], normal: [0, 1, 0]}}, "
          "material: steel}\n"
          "solver: {max_iterations: 7, sleep: {speed: 5 mm/s, time: 0.1 s}}\n");
}

// A removed key is as if the scene had never written it: the schema's
// default takes its place, a section without one (sleep) is gone, and a
// list item goes from its list.
TEST(SceneUnset, RemovesKeysSectionsAndListItems) {
  TempDir dir;
  const std::string scene = scene_to_unset(dir);
  const Simulation written = load(scene);
  ASSERT_EQ(written.model->solver.max_iterations, 7);
  ASSERT_TRUE(written.model->sleep.enabled);
  ASSERT_EQ(written.model->bodies.size(), 2u);
  LoadOptions o;
  o.removals = {"solver.max_iterations", "solver.sleep", "bodies.floor"};
  const Simulation removed = load(scene, o);
  const Simulation bare = load(dir.write("bare.yaml", kMinimal));
  EXPECT_EQ(removed.model->solver.max_iterations, bare.model->solver.max_iterations);
  EXPECT_FALSE(removed.model->sleep.enabled);
  ASSERT_EQ(removed.model->bodies.size(), 1u);
  EXPECT_EQ(removed.model->bodies[0].name, "drum");
  EXPECT_EQ(removed.resolved_yaml.find("sleep"), std::string::npos);
}

// Removals come before every --set, whatever their order on the command
// line: a section set after its removal holds only what --set gives it.
TEST(SceneUnset, GoesBeforeTheOverrides) {
  TempDir dir;
  const std::string scene = scene_to_unset(dir);
  LoadOptions o = sets({{"solver.sleep.time", "1 s"}});
  EXPECT_DOUBLE_EQ(load(scene, o).model->sleep.speed, 0.005);  // kept from the scene
  o.removals = {"solver.sleep"};
  const auto errors = load_errors(scene, o);
  ASSERT_EQ(errors.size(), 1u) << all(errors);
  EXPECT_NE(errors[0].str().find("speed"), std::string::npos) << errors[0].str();
  o.overrides = {{"solver.sleep", "{speed: 1 mm/s, time: 1 s}"}};
  EXPECT_DOUBLE_EQ(load(scene, o).model->sleep.speed, 0.001);
}

// A path the scene does not hold is reported at the removal, not ignored.
TEST(SceneUnset, WhatTheSceneDoesNotSetIsAnError) {
  TempDir dir;
  LoadOptions o;
  o.removals = {"solver.sleep", "solver.slep", "bodies.wall", "time.step.unit", "solver..x"};
  const auto errors = load_errors(scene_to_unset(dir), o);
  ASSERT_EQ(errors.size(), 4u) << all(errors);
  EXPECT_EQ(errors[0].str(),
            "--unset:2:1: solver.slep: the scene sets no 'solver.slep', expected a key or list "
            "item it sets");
  EXPECT_EQ(errors[1].line, 3);
  EXPECT_EQ(errors[2].line, 4);
  EXPECT_EQ(errors[3].line, 5);
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

}  // namespace
}  // namespace ces::scene
