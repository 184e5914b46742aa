// The reference machine as CAD (meshes/ces: ces_machine.step, made by
// exporter/tools/make_ces_cad.cpp, and its annotations): exported, it runs
// as scenes/ces_pcb.yaml does; exported as STL it gives the primitives its
// STEP gives; without its frame it is refused with the frame that fixes it.
// Only in a build with OpenCASCADE.
#ifdef CES_EXPORT_HAVE_OCCT
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <vector>

#include "export_support.hpp"
#include "parts.hpp"
#include "scene/diagnostics.hpp"
#include "scene/resolve.hpp"
#include "scene/schema.hpp"
#include "support.hpp"

namespace {

using namespace ces::exporter;
using namespace ces::export_test;
using ces::kPi;
using ces::Vec3;
using ces::test::fresh_dir;
using ces::test::read_text;

const fs::path kRoot = CES_SOURCE_DIR;

// meshes/ces/ces_machine.step exported with its annotations into work/out.
Exported export_reference(const fs::path& work) {
  return run(kRoot / "meshes/ces/ces_machine.step",
             read_text(kRoot / "meshes/ces/annotations.yaml"), work);
}

// The scene a file resolves to, as the loader reads it before compiling:
// includes merged, schema defaults filled, units in SI.
nlohmann::json resolved(const fs::path& scene_file) {
  ces::scene::Diagnostics diags;
  ces::scene::Budget budget;
  auto tree = ces::scene::load_tree(scene_file.string(), {}, budget, diags);
  if (tree) {
    ces::scene::apply_scene_set(*tree, diags);
    ces::scene::apply_defaults(*tree);
    ces::scene::convert_units(*tree, diags);
  }
  EXPECT_TRUE(tree && diags.empty()) << scene_file << " does not resolve";
  return tree ? ces::scene::to_json(*tree) : nullptr;
}

// The scene without what ces-export makes from the CAD: the bodies' shapes
// and poses, the electrodes' places and radii, the feeds' outlets and the
// collectors' planes and bin ranges. The runs compare those (the machine's
// frames, the field, the particles and the bins).
nlohmann::json without_cad(nlohmann::json scene) {
  for (auto& b : scene["bodies"]) {
    b.erase("geometry");
    b.erase("pose");
    if (b.contains("motion")) b["motion"]["rotation"].erase("center");
  }
  for (auto& e : scene["electrostatics"]["electrodes"]) {
    e.erase("polar");
    e.erase("radius");
  }
  for (auto& f : scene["feeds"]) f.erase("region");
  for (auto& c : scene["collectors"]) {
    c.erase("plane");
    for (const char* key : {"axis", "from", "to"}) c["bins"].erase(key);
  }
  return scene;
}

// Everything the annotations give the exported scene (materials, process,
// run and outputs, the electrodes' types, the drum's speed, ...) is what
// scenes/ces_pcb.yaml and its fragments say: a key changed or added there
// and not in meshes/ces/annotations.yaml shows here, by its path.
TEST(ExportRoundTrip, ReferenceAnnotationsSayWhatCesPcbSays) {
  const Exported e = export_reference(fresh_dir("export_round_trip_keys"));
  ASSERT_EQ(e.code, 0) << e.err;
  const nlohmann::json ref = without_cad(resolved(kRoot / "scenes/ces_pcb.yaml"));
  const nlohmann::json exp = without_cad(resolved(e.folder / "scene.yaml"));
  EXPECT_TRUE(exp == ref) << "what differs, as a patch from scenes/ces_pcb.yaml to the export:\n"
                          << nlohmann::json::diff(ref, exp).dump(1);
}

// The files of a run that must not differ between the two scenes: every
// table but steps.csv (which has wall times), the field, and each frame of
// the machine, the particles and their spheres.
std::vector<fs::path> run_files(const fs::path& dir) {
  std::vector<fs::path> files = {"bins.csv", "products.csv", "crossings.csv",
                                 "lost.csv", "field.csv",    "trajectories.pvd"};
  for (const auto& f : fs::directory_iterator(dir / "trajectories"))
    files.push_back("trajectories" / f.path().filename());
  std::sort(files.begin(), files.end());
  return files;
}

// The reference machine drawn as CAD (mm, z up, drum along -y, placed by
// the assembly) exported with its annotations runs as scenes/ces_pcb.yaml
// does, byte for byte.
TEST(ExportRoundTrip, ReferenceMachineRunsLikeCesPcb) {
  const fs::path work = fresh_dir("export_round_trip");
  const Exported e = export_reference(work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_EQ(e.err, "");  // every part has a role, every cylinder is exact
  // 0.45 s of a 40 ms feed: the copper and the first FR-4 land on both
  // sides of the splitters, the rest of the FR-4 still rides the drum and is
  // compared where it is. Until the end, not until every particle is
  // collected, which takes seconds more. One thread: the test runs beside
  // others (ctest -j2).
  const std::string shorter =
      " --quiet --threads 1 --set time.end=0.45s --set time.until=end"
      " --set feeds.nozzle.duration=0.04s";
  const auto ref = ces::test::ces_sim((kRoot / "scenes/ces_pcb.yaml").string() + " -o " +
                                      (work / "ref").string() + shorter);
  ASSERT_EQ(ref.code, 0) << ref.err;
  const auto exp = ces::test::ces_sim((e.folder / "scene.yaml").string() + " -o " +
                                      (work / "exp").string() + shorter);
  ASSERT_EQ(exp.code, 0) << exp.err;
  const auto cmp =
      ces::test::ces_sim("compare " + (work / "ref").string() + " " + (work / "exp").string());
  EXPECT_EQ(cmp.code, 0) << cmp.out << cmp.err;
  const auto files = run_files(work / "ref");
  EXPECT_EQ(run_files(work / "exp"), files);
  for (const fs::path& f : files)
    EXPECT_TRUE(read_text(work / "ref" / f) == read_text(work / "exp" / f)) << f << " differs";
}

// Without `frame`, the reference CAD (z up, the drum along -y) is refused
// with the frame that fixes it.
TEST(ExportBadInput, ReferenceStepWithoutFrame) {
  const fs::path work = fresh_dir("export_step_no_frame");
  std::string annotations = read_text(kRoot / "meshes/ces/annotations.yaml");
  const std::size_t at = annotations.find("\nframe:");
  ASSERT_NE(at, std::string::npos);
  annotations.erase(at + 1, annotations.find('\n', at + 1) - at);
  const Exported e = run(kRoot / "meshes/ces/ces_machine.step", annotations, work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("drum 'drum' is centred at [0.5, 0, 0.8] along [0, 1, 0] (scene frame)"),
            std::string::npos)
      << e.err;
  EXPECT_NE(e.err.find("expected frame: {origin: drum, up: [0, 0, 1]} in the annotations"),
            std::string::npos)
      << e.err;
  expect_nothing_written(e);
}

// A part's tessellation as a CAD program writes it to STL: float
// coordinates in mm.
void write_stl_mm(const fs::path& path, const Mesh& m) {
  std::vector<Triangle> t;
  for (const auto& tri : m.triangles)
    t.push_back({1e3 * m.vertices[tri[0]], 1e3 * m.vertices[tri[1]], 1e3 * m.vertices[tri[2]]});
  write_stl(path, t);
}

// The reference machine exported as STL (each part's tessellation, in mm,
// where the assembly places it) gives the primitives its STEP gives: the
// same kinds, cylinders fitted to 0.1 % of their radius, boxes (the second
// splitter tilted by 27 degrees) to float precision.
TEST(ExportRoundTrip, ReferenceMachineFromStlGivesTheStepPrimitives) {
  const fs::path work = fresh_dir("export_reference_stl");
  std::string unit;
  const std::vector<Part> parts =
      read_step((kRoot / "meshes/ces/ces_machine.step").string(), StepOptions{}, unit);
  fs::create_directories(work / "stl");
  for (const Part& p : parts) write_stl_mm(work / "stl" / (p.name + ".stl"), p.mesh);
  const std::string annotations = read_text(kRoot / "meshes/ces/annotations.yaml");
  fs::create_directories(work / "a");
  fs::create_directories(work / "b");
  const Exported step = run(kRoot / "meshes/ces/ces_machine.step", annotations, work / "a");
  const Exported stl = run(work / "stl", annotations, work / "b");
  ASSERT_EQ(step.code, 0) << step.err;
  ASSERT_EQ(stl.code, 0) << stl.err;
  EXPECT_EQ(stl.err, "");  // every part fitted, none left out
  ASSERT_EQ(stl.scene["bodies"].size(), step.scene["bodies"].size());
  for (const YAML::Node& a : step.scene["bodies"]) {
    const YAML::Node b = body(stl, a["name"].as<std::string>());  // STL parts come sorted by name
    SCOPED_TRACE(a["name"].as<std::string>());
    EXPECT_LT((vec(b["pose"]["position"]) - vec(a["pose"]["position"])).norm(), 1e-5);
    if (a["geometry"]["cylinder"]) {
      ASSERT_TRUE(b["geometry"]["cylinder"]) << b;
      const double r = a["geometry"]["cylinder"]["radius"].as<double>();
      EXPECT_NEAR(b["geometry"]["cylinder"]["radius"].as<double>(), r, 1e-3 * r);
      EXPECT_NEAR(b["geometry"]["cylinder"]["length"].as<double>(),
                  a["geometry"]["cylinder"]["length"].as<double>(), 1e-6);
      EXPECT_LT((vec(b["pose"]["axis"]) - vec(a["pose"]["axis"])).norm(), 1e-6);
    } else {
      ASSERT_TRUE(a["geometry"]["box"]) << a;
      ASSERT_TRUE(b["geometry"]["box"]) << b;
      EXPECT_LT((vec(b["geometry"]["box"]["size"]) - vec(a["geometry"]["box"]["size"])).norm(),
                1e-6);
      EXPECT_LT((pose_rotation(b) - pose_rotation(a)).norm(), 1e-6);
    }
  }
  ASSERT_EQ(stl.scene["electrostatics"]["electrodes"].size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    const YAML::Node ea = step.scene["electrostatics"]["electrodes"][k];
    const YAML::Node eb = stl.scene["electrostatics"]["electrodes"][k];
    SCOPED_TRACE(ea["name"].as<std::string>());
    EXPECT_NEAR(eb["polar"]["distance"].as<double>(), ea["polar"]["distance"].as<double>(), 1e-5);
    EXPECT_NEAR(std::stod(eb["polar"]["angle"].as<std::string>()),
                std::stod(ea["polar"]["angle"].as<std::string>()), 1e-3);
    EXPECT_NEAR(eb["radius"].as<double>(), ea["radius"].as<double>(),
                1e-3 * ea["radius"].as<double>());
  }
  EXPECT_EQ(stl.scene["electrostatics"]["electrodes"][1]["type"].as<std::string>(), "corona");
  const auto outlet = [](const Exported& e) { return e.scene["feeds"][0]["region"]["outlet"]; };
  EXPECT_LT((vec(outlet(stl)["center"]) - vec(outlet(step)["center"])).norm(), 1e-6);
  const auto plane = [](const Exported& e) { return e.scene["collectors"][0]["plane"]; };
  EXPECT_LT((vec(plane(stl)["point"]) - vec(plane(step)["point"])).norm(), 1e-6);
  // The fits' own measures, for the record.
  for (const char* name : {"drum", "brush", "electrode", "wire"})
    EXPECT_LT(report_part(stl, name)["cylinder_fit"]["rms_relative"].get<double>(), 0.005) << name;
  for (const char* name : {"splitter_1", "splitter_2"})
    EXPECT_LT(report_part(stl, name)["box_fit"]["volume_error"].get<double>(), 3e-5) << name;
}
}  // namespace
#endif
