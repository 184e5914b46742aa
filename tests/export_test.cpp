// ces-export on STL/OBJ folders: fitted cylinders and boxes, meshes, units,
// frames, electrodes, gravity and the domain, the one-screen summary, the
// README's example, and bad input named at its line of the annotations.
// Built twice: into ces_tests and, with OpenCASCADE, into
// ces_export_stl_tests against the STL-only exporter, where STEP input must
// be a clear error.
#include "export.hpp"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common/path.hpp"
#include "export_support.hpp"
#include "support.hpp"

namespace {

using namespace ces::exporter;
using namespace ces::export_test;
using ces::kPi;
using ces::Vec3;
using ces::test::fresh_dir;
using ces::test::read_text;

#ifndef CES_EXPORT_HAVE_OCCT
TEST(ExportStep, WithoutOpenCascadeStepIsAClearError) {
  const fs::path work = fresh_dir("export_no_occt");
  std::ofstream(work / "machine.step") << "ISO-10303-21;\n";
  const Exported e = run(work / "machine.step", machine_annotations("[1, 0, 0]"), work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("built without OpenCASCADE"), std::string::npos) << e.err;
  expect_nothing_written(e);
}
#endif

// --- STL/OBJ ---------------------------------------------------------------

TEST(ExportStl, DrumBecomesAFittedCylinder) {
  const fs::path work = fresh_dir("export_stl");
  write_stl_machine(work / "cad");
  const Exported e = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  const YAML::Node drum = body(e, "drum");
  ASSERT_TRUE(drum["geometry"]["cylinder"]) << drum;
  EXPECT_NEAR(drum["geometry"]["cylinder"]["radius"].as<double>(), 0.16, 0.001 * 0.16);
  EXPECT_NEAR(drum["geometry"]["cylinder"]["length"].as<double>(), 0.30, 1e-6);
  EXPECT_LT((vec(drum["pose"]["axis"]) - Vec3::UnitZ()).norm(), 1e-9);
  const auto& fit = report_part(e, "drum")["cylinder_fit"];
  EXPECT_TRUE(fit["used"].get<bool>());
  EXPECT_LT(fit["rms_relative"].get<double>(), 0.005);
  EXPECT_NE(e.out.find("fitted, RMS"), std::string::npos) << e.out;
  expect_hopper(e);
  expect_splitter_box(e);
  expect_validates(e);
}

TEST(ExportStl, CoarseDrumStaysAMeshWithAWarning) {
  const fs::path work = fresh_dir("export_stl_coarse");
  write_stl_machine(work / "cad", 1.0, 12);  // a dodecagon: facets 3.4 % inside the circle
  const Exported e = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_TRUE(body(e, "drum")["geometry"]["mesh"]) << body(e, "drum");
  EXPECT_NE(e.err.find("misses the mesh by"), std::string::npos) << e.err;
  EXPECT_NE(e.err.find("kept as a mesh"), std::string::npos) << e.err;
  EXPECT_FALSE(report_part(e, "drum")["cylinder_fit"]["used"].get<bool>());
  expect_validates(e);
}

TEST(ExportStl, UnitsFromTheAnnotations) {
  const fs::path work = fresh_dir("export_stl_inch");
  write_stl_machine(work / "cad", 1 / 25.4);
  const Exported e = run(work / "cad", "units: in\n" + machine_annotations("[0, 0, 1]"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_NEAR(body(e, "drum")["geometry"]["cylinder"]["radius"].as<double>(), 0.16, 0.001 * 0.16);
}

TEST(ExportStl, PartsWithoutRoleAreListedAndLeftOut) {
  const fs::path work = fresh_dir("export_stl_unassigned");
  write_stl_machine(work / "cad");
  write_stl(work / "cad" / "bolt_1.stl", box({0, 0, 0}, {5, 5, 5}));
  write_stl(work / "cad" / "bolt_2.stl", box({10, 0, 0}, {15, 5, 5}));
  const Exported e = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_NE(e.err.find("2 part(s) have no role and are left out: bolt_1, bolt_2"),
            std::string::npos)
      << e.err;
  EXPECT_EQ(e.scene["bodies"].size(), 3u);
  EXPECT_EQ(e.report["unassigned"].size(), 2u);
}

// An included fragment stays an include (its path made relative to the
// scene) and its domain is kept; joints, a part's own friction and an OBJ
// part come through.
TEST(ExportStl, IncludesJointsAndObjParts) {
  const fs::path work = fresh_dir("export_stl_include");
  write_stl_machine(work / "cad");
  fs::remove(work / "cad" / "hopper.stl");
  std::ofstream(work / "cad" / "chute.obj") << "v 0 130 0\nv 120 10 0\nv 120 40 -40\nv 0 160 -40\n"
                                               "f 1 2 3\nf 1 3 4\n";
  fs::create_directories(work / "common");
  std::ofstream(work / "common" / "settings.yaml")
      << kSceneKeys << "  plate: {friction: 0.2, density: 7800 kg/m^3}\n"
      << "domain: {box: {min: [-1, -1, -1], max: [1, 1, 1]}}\n";
  const Exported e =
      run(work / "cad",
          "include: common/settings.yaml\n"
          "parts:\n"
          "  drum: {role: drum, material: steel, rpm: 44.8, rotation_axis: [0, 0, -1],\n"
          "         joint: {mass: 20 kg, max_force: 50 N m}}\n"
          "  chute: {role: wall, friction: 0.4}\n"
          "  splitter: {role: splitter, material: plate,\n"
          "             joint: {position: 10 mm, max_speed: 0.01 m/s}}\n",
          work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_EQ(e.scene["include"][0].as<std::string>(), "../common/settings.yaml");
  EXPECT_FALSE(e.scene["domain"]);
  EXPECT_EQ(e.scene["joints"][0]["type"].as<std::string>(), "revolute");
  EXPECT_LT((vec(e.scene["joints"][0]["axis"]) + Vec3::UnitZ()).norm(), 1e-12);
  EXPECT_EQ(e.scene["motors"][0]["speed"].as<std::string>(), "44.8 rpm");
  EXPECT_EQ(e.scene["joints"][1]["type"].as<std::string>(), "prismatic");
  EXPECT_LT((vec(e.scene["joints"][1]["axis"]) - Vec3::UnitX()).norm(), 1e-12);  // across the plate
  EXPECT_EQ(e.scene["motors"][1]["position"].as<std::string>(), "10 mm");
  EXPECT_EQ(body(e, "chute")["material"].as<std::string>(), "chute");
  EXPECT_EQ(e.scene["materials"]["chute"]["friction"].as<double>(), 0.4);
  EXPECT_EQ(report_part(e, "chute")["mesh"]["open_edges"], 4);
  // The fragment stays where it is, outside the scene's folder: ces-sim is
  // told where (and refuses the include without it).
  const std::string common = fs::weakly_canonical(work / "common").string();
  EXPECT_NE(e.err.find("run it with --include-path " + common), std::string::npos) << e.err;
  EXPECT_EQ(ces::test::ces_sim("validate " + (e.folder / "scene.yaml").string()).code, 2);
  expect_validates(e, " --include-path " + common);
}

// The annotations' includes are held to their folder and the --include-path
// ones, as a scene's are: any other file, or a link out, is refused before
// it is opened, the same whether it exists or not, and none of it is quoted.
TEST(ExportBadInput, IncludesOutsideTheAnnotationsFolder) {
  const fs::path work = fresh_dir("export_include_outside");
  write_stl_machine(work / "cad");
  const fs::path elsewhere = work / "elsewhere", own = work / "own";
  fs::create_directories(elsewhere);
  fs::create_directories(own);
  std::ofstream(elsewhere / "secret.yaml") << "password: hunter2\n";
  fs::create_symlink(elsewhere / "secret.yaml", own / "link.yaml");
  const std::vector<std::string> names = {"../elsewhere/secret.yaml",
                                          (elsewhere / "secret.yaml").string(),
                                          "../elsewhere/none.yaml", "link.yaml"};
  for (const std::string& name : names) {
    const Exported e =
        run(work / "cad", "include: " + name + "\n" + machine_annotations("[0, 0, -1]"), own);
    EXPECT_EQ(e.code, 2) << name;
    EXPECT_NE(e.err.find("annotations.yaml:1:10: include: '" + name +
                         "' is outside the folder of annotations.yaml"),
              std::string::npos)
        << e.err;
    EXPECT_EQ(e.err.find("hunter2"), std::string::npos) << e.err;
    expect_nothing_written(e);
  }
  std::ofstream(elsewhere / "settings.yaml")
      << "domain: {box: {min: [-1, -1, -1], max: [1, 1, 1]}}\n";
  const Exported allowed =
      run(work / "cad", "include: ../elsewhere/settings.yaml\n" + machine_annotations("[0, 0, -1]"),
          own, {elsewhere.string()});
  ASSERT_EQ(allowed.code, 0) << allowed.err;
  EXPECT_FALSE(allowed.scene["domain"]);
  expect_validates(allowed, " --include-path " + fs::weakly_canonical(elsewhere).string());
}

// The field models want the drum's axis on z through the origin: CAD drawn
// elsewhere is moved there by `frame`, or refused with a hint.
TEST(ExportStl, ElectrodesAndTheDrumFrame) {
  const fs::path work = fresh_dir("export_stl_frame");
  write_stl_machine(work / "cad");
  const double a = 30 * kPi / 180;
  write_stl(work / "cad" / "electrode.stl",
            cylinder(19, 300, 128, Vec3(267 * std::cos(a), 267 * std::sin(a), 0)));
  const std::string parts =
      machine_annotations("[0, 0, -1]", "  electrode: {role: electrode, voltage: -35 kV}\n");
  const Exported moved = run(work / "cad", "frame: {origin: [0, 0.1, 0]}\n" + parts, work);
  EXPECT_EQ(moved.code, 2);
  EXPECT_NE(moved.err.find("annotations.yaml:3:3: drum 'drum' is centred at [0, -0.1, 0]"),
            std::string::npos)
      << moved.err;
  EXPECT_NE(moved.err.find("frame: {origin: drum"), std::string::npos) << moved.err;
  const Exported e = run(work / "cad", parts, work);
  ASSERT_EQ(e.code, 0) << e.err;
  const YAML::Node es = e.scene["electrostatics"];
  EXPECT_EQ(es["drum"].as<std::string>(), "drum");
  EXPECT_NEAR(es["electrodes"][0]["polar"]["distance"].as<double>(), 0.267, 1e-6);
  const std::string angle = es["electrodes"][0]["polar"]["angle"].as<std::string>();
  EXPECT_TRUE(angle.ends_with(" deg")) << angle;
  EXPECT_NEAR(std::stod(angle), 30.0, 1e-4);  // float STL coordinates
  EXPECT_NEAR(es["electrodes"][0]["radius"].as<double>(), 0.019, 1e-6);
  EXPECT_EQ(es["electrodes"][0]["voltage"].as<std::string>(), "-35 kV");
  expect_validates(e);
}

// The reference machine's two electrodes as STL, in mm: the static one
// (19 mm) at 267 mm and 30 deg, the corona wire (0.1 mm, 72 sides) at
// 210.1 mm and 75 deg.
void write_electrodes(const fs::path& dir) {
  const auto at = [](double distance, double degrees) {
    return Vec3(distance * std::cos(degrees * kPi / 180), distance * std::sin(degrees * kPi / 180),
                0);
  };
  write_stl(dir / "electrode.stl", cylinder(19, 300, 128, at(267, 30)));
  write_stl(dir / "wire.stl", cylinder(0.1, 300, 72, at(210.1, 75)));
}

const char* kLineCharges = "electrostatics: {field: {model: line_charges}}\n";

// A corona wire drawn as a thin cylinder: its electrode has the wire's
// radius and the rule's type and corona keys, and the scene runs the wire.
TEST(ExportStl, CoronaWireElectrodeWithItsKeys) {
  const fs::path work = fresh_dir("export_stl_corona");
  write_stl_machine(work / "cad");
  write_electrodes(work / "cad");
  const Exported e =
      run(work / "cad",
          machine_annotations("[0, 0, -1]",
                              "  electrode: {role: electrode, voltage: -35 kV}\n"
                              "  wire: {role: electrode, type: corona, voltage: -35 kV,\n"
                              "         mobility: 1.9 cm^2/V/s, air_density: 0.95}\n") +
              kLineCharges,
          work);
  ASSERT_EQ(e.code, 0) << e.err;
  const YAML::Node electrode = e.scene["electrostatics"]["electrodes"][0];
  EXPECT_FALSE(electrode["type"]) << electrode;
  const YAML::Node wire = e.scene["electrostatics"]["electrodes"][1];
  EXPECT_EQ(wire["name"].as<std::string>(), "wire");
  EXPECT_EQ(wire["type"].as<std::string>(), "corona");
  EXPECT_EQ(wire["mobility"].as<std::string>(), "1.9 cm^2/V/s");
  EXPECT_EQ(wire["air_density"].as<double>(), 0.95);
  EXPECT_EQ(wire["voltage"].as<std::string>(), "-35 kV");
  EXPECT_NEAR(wire["radius"].as<double>(), 1e-4, 1e-7);  // float STL coordinates
  EXPECT_NEAR(wire["polar"]["distance"].as<double>(), 0.2101, 1e-6);
  EXPECT_NEAR(std::stod(wire["polar"]["angle"].as<std::string>()), 75.0, 1e-3);
  expect_validates(e);
}

// Corona keys are checked at their line: a type that is neither, a
// mobility without its unit or below zero, an air density of 0, and corona
// keys on an electrode that does not ionise.
TEST(ExportBadInput, CoronaKeys) {
  const fs::path work = fresh_dir("export_bad_corona");
  write_stl_machine(work / "cad");
  write_electrodes(work / "cad");
  const Exported e =
      run(work / "cad",
          machine_annotations("[0, 0, -1]",
                              "  electrode: {role: electrode, voltage: -35 kV, air_density: 1}\n"
                              "  wire: {role: electrode, type: ionising, voltage: -35 kV,\n"
                              "         mobility: 2.1, air_density: 0}\n") +
              kLineCharges,
          work);
  EXPECT_EQ(e.code, 2);
  for (const char* message :
       {"annotations.yaml:5:62: parts.electrode.air_density: air_density is a corona wire's, but "
        "this electrode is static (the default type), expected type: corona with it",
        "annotations.yaml:6:33: parts.wire.type: got 'ionising', expected static or corona",
        "annotations.yaml:7:20: parts.wire.mobility: got 2.1, a number without a unit, expected "
        "an ion mobility with its unit such as '2.1 cm^2/V/s' ('2.1 m^2/V/s' if m^2/V/s are "
        "meant)",
        "annotations.yaml:7:38: parts.wire.air_density: got 0, expected a relative air density > 0 "
        "such as 1 (1 at 20 degC and 1 atm)"})
    EXPECT_NE(e.err.find(message), std::string::npos) << message << "\n" << e.err;
  expect_nothing_written(e);
  const Exported negative = run(work / "cad",
                                machine_annotations("[0, 0, -1]",
                                                    "  wire: {role: electrode, type: corona, "
                                                    "voltage: -35 kV, mobility: -2 cm^2/V/s}\n"),
                                work);
  EXPECT_EQ(negative.code, 2);
  EXPECT_NE(negative.err.find("annotations.yaml:5:68: parts.wire.mobility: got '-2 cm^2/V/s', "
                              "expected a positive ion mobility such as '2.1 cm^2/V/s'"),
            std::string::npos)
      << negative.err;
}

// The 19 mm electrode given type: corona would never ionise: refused at its
// type with the radius the part has.
TEST(ExportBadInput, CoronaWireTooThick) {
  const fs::path work = fresh_dir("export_bad_thick_wire");
  write_stl_machine(work / "cad");
  write_electrodes(work / "cad");
  const Exported e =
      run(work / "cad",
          machine_annotations("[0, 0, -1]",
                              "  electrode: {role: electrode, type: corona, voltage: -35 kV}\n"
                              "  wire: {role: electrode, type: corona, voltage: -35 kV}\n") +
              kLineCharges,
          work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("annotations.yaml:5:38: parts.electrode.type: electrode 'electrode' has a "
                       "radius of 19 mm (fitted), too thick to ionise: expected a corona wire of "
                       "radius at most 1 mm, or type: static for a field electrode"),
            std::string::npos)
      << e.err;
  expect_nothing_written(e);
}

// Materials keep every key they are given: the annotations' own entries,
// copied as scene keys, and a part's own material, made of whichever
// material keys its rule has.
TEST(ExportStl, MaterialKeysComeThrough) {
  const fs::path work = fresh_dir("export_stl_materials");
  write_stl_machine(work / "cad");
  const std::string parts =
      "parts:\n"
      "  drum: {role: drum, material: steel, speed: 44.8 rpm, rotation_axis: [0, 0, -1]}\n"
      "  hopper: {role: hopper, friction: 0.4, restitution: 0.1, youngs_modulus: 2 GPa,\n"
      "           poisson_ratio: 0.35}\n";
  const Exported e = run(work / "cad",
                         parts + "  splitter: {role: splitter, material: rubber}\n" + kSceneKeys +
                             "  rubber: {friction: 0.8, restitution: 0.4, density: 1100 kg/m^3,\n"
                             "           youngs_modulus: 10 MPa, poisson_ratio: 0.49}\n",
                         work);
  ASSERT_EQ(e.code, 0) << e.err;
  const YAML::Node hopper = e.scene["materials"]["hopper"];
  EXPECT_EQ(hopper["friction"].as<double>(), 0.4);
  EXPECT_EQ(hopper["restitution"].as<double>(), 0.1);
  EXPECT_EQ(hopper["youngs_modulus"].as<std::string>(), "2 GPa");
  EXPECT_EQ(hopper["poisson_ratio"].as<double>(), 0.35);
  EXPECT_EQ(hopper.size(), 4u);
  const YAML::Node rubber = e.scene["materials"]["rubber"];
  EXPECT_EQ(rubber["density"].as<std::string>(), "1100 kg/m^3");
  EXPECT_EQ(rubber["youngs_modulus"].as<std::string>(), "10 MPa");
  EXPECT_EQ(rubber["poisson_ratio"].as<double>(), 0.49);
  EXPECT_EQ(rubber.size(), 5u);
  expect_validates(e);
  const Exported both =
      run(work / "cad",
          parts + "  splitter: {role: splitter, material: steel, density: 1}\n" + kSceneKeys, work);
  EXPECT_EQ(both.code, 2);
  EXPECT_NE(both.err.find("annotations.yaml:5:56: parts.splitter.density: both material and "
                          "density given, expected a material (a materials entry), or material "
                          "keys for a material of this part alone"),
            std::string::npos)
      << both.err;
}

// Splitter plates tilted as drawn, in float STL coordinates: each a box body
// of the plate's size, turned as the plate is (up to the box's symmetry).
TEST(ExportStl, TiltedSplittersAreBoxes) {
  const fs::path work = fresh_dir("export_stl_tilted");
  write_stl_machine(work / "cad");
  const std::vector<double> tilts = {-20, 27, 60, 89};
  const Vec3 size(4, 150, 300);
  for (std::size_t i = 0; i < tilts.size(); ++i) {
    const Eigen::AngleAxisd turn(tilts[i] * kPi / 180, Vec3::UnitZ());
    std::vector<Triangle> t = centred_box(size);
    for (Triangle& tri : t)
      for (Vec3& v : tri) v = turn * v + Vec3(250.0 + 60 * double(i), -200, 0);
    write_stl(work / "cad" / ("splitter_" + std::to_string(i) + ".stl"), t);
  }
  const Exported e = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_EQ(e.err.find("kept as a mesh"), std::string::npos) << e.err;
  for (std::size_t i = 0; i < tilts.size(); ++i) {
    SCOPED_TRACE(tilts[i]);
    const YAML::Node b = body(e, "splitter_" + std::to_string(i));
    ASSERT_TRUE(b["geometry"]["box"]) << b;
    const Vec3 got = vec(b["geometry"]["box"]["size"]);
    const ces::Mat3 frame = pose_rotation(b);
    const ces::Mat3 r = Eigen::AngleAxisd(tilts[i] * kPi / 180, Vec3::UnitZ()).toRotationMatrix();
    for (int k = 0; k < 3; ++k) {
      Eigen::Index j = 0;
      (frame.transpose() * r.col(k)).cwiseAbs().maxCoeff(&j);
      EXPECT_GT(std::abs(frame.col(j).dot(r.col(k))), 1.0 - 1e-9) << "edge " << k;
      EXPECT_NEAR(got[j], 1e-3 * size[k], 1e-6) << "edge " << k;
    }
    EXPECT_LT((vec(b["pose"]["position"]) - Vec3(0.25 + 0.06 * double(i), -0.2, 0)).norm(), 1e-6);
    EXPECT_TRUE(report_part(e, "splitter_" + std::to_string(i))["box_fit"]["used"].get<bool>());
  }
  expect_validates(e);
}

const char* kNoGravityKeys = R"(
time: {step: 1 ms, end: 0.1 s}
materials:
  steel: {friction: 0.3}
)";

// Without gravity a feed hangs at its outlet: the exporter writes it along
// -y of the scene, which the frame's up makes the CAD's down. Given in the
// annotations, it is theirs alone (lists would otherwise join).
TEST(ExportStl, GravityIsWrittenUnlessGiven) {
  const fs::path work = fresh_dir("export_stl_gravity");
  write_stl_machine(work / "cad");
  const std::string parts =
      "parts:\n"
      "  drum: {role: drum, material: steel, speed: 44.8 rpm, rotation_axis: [0, 0, -1]}\n"
      "  hopper: {role: hopper, material: steel}\n"
      "  splitter: {role: splitter, material: steel}\n";
  const Exported made = run(work / "cad", parts + kNoGravityKeys, work);
  ASSERT_EQ(made.code, 0) << made.err;
  ASSERT_EQ(made.scene["gravity"].size(), 3u);
  EXPECT_EQ(made.scene["gravity"][0].as<double>(), 0.0);
  EXPECT_EQ(made.scene["gravity"][1].as<std::string>(), "-9.81 m/s^2");
  EXPECT_EQ(made.scene["gravity"][2].as<double>(), 0.0);
  EXPECT_NE(made.out.find("gravity:    [0, -9.81, 0] m/s^2 (ces-export's: down is the CAD's "
                          "[0, -1, 0])"),
            std::string::npos)
      << made.out;
  // The CAD drawn z up: `frame: up` says so, and down is the CAD's -z.
  const Exported up =
      run(work / "cad", "frame: {up: [0, 0, 1], axis: [1, 0, 0]}\n" + parts + kNoGravityKeys, work);
  ASSERT_EQ(up.code, 0) << up.err;
  EXPECT_EQ(up.scene["gravity"][1].as<std::string>(), "-9.81 m/s^2");
  EXPECT_NE(up.out.find("down is the CAD's [0, 0, -1]"), std::string::npos) << up.out;
  const Exported given =
      run(work / "cad", parts + kNoGravityKeys + "gravity: [0, 0, -9.81 m/s^2]\n", work);
  ASSERT_EQ(given.code, 0) << given.err;
  ASSERT_EQ(given.scene["gravity"].size(), 3u);
  EXPECT_EQ(given.scene["gravity"][2].as<std::string>(), "-9.81 m/s^2");
  EXPECT_NE(given.out.find("gravity:    [0, 0, -9.81] m/s^2 (from the annotations)"),
            std::string::npos)
      << given.out;
}

std::size_t line_count(const std::string& text) {
  return std::size_t(std::count(text.begin(), text.end(), '\n'));
}

// What ces-export made, on one screen: parts by kind with their fits, the
// domain, gravity, feeds and collectors, and the command to run it.
TEST(ExportStl, SummaryOnOneScreen) {
  const fs::path work = fresh_dir("export_stl_summary");
  write_stl_machine(work / "cad");
  write_stl(work / "cad" / "outlet.stl", box({-60, 180, -40}, {0, 182, 40}));
  write_stl(work / "cad" / "floor.stl", box({-200, -250, -150}, {300, -248, 150}));
  write_stl(work / "cad" / "bolt.stl", box({0, 0, 0}, {5, 5, 5}));
  const Exported e =
      run(work / "cad",
          machine_annotations("[0, 0, -1]",
                              "  outlet: {role: feed_outlet, feed: {rate: 5 g/s, duration: 0.1 s,\n"
                              "           mix: [{material: grit, size: {constant: 1 mm}}]}}\n"
                              "  floor: {role: collector_plane}\n"
                              "  bolt: {role: ignore}\n") +
              "  grit: {density: 2500 kg/m^3, friction: 0.5}\n",
          work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_LE(line_count(e.out), 24u) << e.out;
  for (const char* line :
       {"made: 1 cylinder, 1 box, 1 mesh, 1 feed outlet, 1 collector plane; 1 left out\n",
        "fitted, RMS", "off its box by", "meshes/hopper.stl: 12 triangles, 0 open",
        "left out (role: ignore): bolt\n",
        "gravity:    [0, -9.81, 0] m/s^2 (from the annotations)\n",
        "domain:     [-0.25, -0.3, -0.2] to [0.35, 0.25, 0.2] m (ces-export's",
        "feed:       outlet: 5 g/s from 0 s for 0.1 s out of [-0.06, 0.181, -0.04] to [0, 0.181, "
        "0.04]\n",
        "collector:  floor: 50 bins along [1, 0, 0] from -0.2 m to 0.3 m on the plane through "
        "[0.05, -0.249, 0] facing [0, 1, 0]\n",
        "next:       ces-sim "})
    EXPECT_NE(e.out.find(line), std::string::npos) << line << "\n" << e.out;
}

// --- the README's example --------------------------------------------------

// Mass of `material` per product, from products.csv.
std::map<std::string, double> product_masses(const fs::path& csv, const std::string& material) {
  std::istringstream in(read_text(csv));
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  for (std::istringstream h(line); std::getline(h, line, ',');) header.push_back(line);
  const auto column = [&](const char* name) {
    return std::size_t(std::find(header.begin(), header.end(), name) - header.begin());
  };
  std::map<std::string, double> mass;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    for (std::istringstream c(line); std::getline(c, line, ',');) cells.push_back(line);
    if (cells.at(column("material")) == material)
      mass[cells.at(column("product"))] = std::stod(cells.at(column("mass_kg")));
  }
  return mass;
}

// exporter/README.md's walk-through on meshes/example (STL in mm, z up, a
// 96-facet drum, a plate tilted by -20 degrees, no gravity in the
// annotations): every part fits, and a short run collects every particle
// fed, metals beyond the splitter and insulators before it.
TEST(ExportExample, TheReadmeMachineExportsAndSeparates) {
  const fs::path root = CES_SOURCE_DIR;
  const fs::path work = fresh_dir("export_example");
  std::ostringstream out, err;
  const int code = run_export(
      {(root / "meshes/example").string(), (root / "meshes/example/annotations.yaml").string(),
       (work / "example").string(), false, {}},
      out, err);
  ASSERT_EQ(code, 0) << err.str();
  EXPECT_EQ(err.str(), "");
  EXPECT_LE(line_count(out.str()), 24u) << out.str();
  const YAML::Node scene = YAML::LoadFile((work / "example/scene.yaml").string());
  for (const auto& b : scene["bodies"]) {
    const std::string name = b["name"].as<std::string>();
    const char* kind = name == "drum" ? "cylinder" : name == "splitter" ? "box" : "mesh";
    EXPECT_TRUE(b["geometry"][kind]) << b;
  }
  EXPECT_EQ(scene["gravity"][1].as<std::string>(), "-9.81 m/s^2");
  const auto run = ces::test::ces_sim(
      (work / "example/scene.yaml").string() + " -o " + (work / "run").string() +
      " --quiet --threads 1 --set feeds.feed.duration=0.05s --set time.end=0.6s");
  ASSERT_EQ(run.code, 0) << run.err;
  const auto summary = nlohmann::json::parse(read_text(work / "run/summary.json"));
  const auto& balance = summary["balance"];
  EXPECT_GT(balance["fed"]["count"].get<int>(), 50);
  EXPECT_EQ(balance["collected"]["count"], balance["fed"]["count"]);
  const auto copper = product_masses(work / "run/products.csv", "copper");
  const auto fr4 = product_masses(work / "run/products.csv", "fr4");
  EXPECT_GT(copper.at("conductor"), 0.9 * (copper.at("conductor") + copper.at("nonconductor")));
  EXPECT_GT(fr4.at("nonconductor"), 0.9 * (fr4.at("conductor") + fr4.at("nonconductor")));
}

// --- bad input -------------------------------------------------------------

TEST(ExportBadInput, UnreadableMeshesAndMissingInput) {
  const fs::path work = fresh_dir("export_bad_mesh");
  write_stl_machine(work / "cad");
  std::ofstream(work / "cad" / "hopper.stl") << "solid broken\n  facet normal 0 0 1\n  garbage\n";
  const Exported corrupt = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  EXPECT_EQ(corrupt.code, 2);
  EXPECT_NE(corrupt.err.find("cannot read"), std::string::npos) << corrupt.err;
  EXPECT_NE(corrupt.err.find("hopper.stl"), std::string::npos) << corrupt.err;
  expect_nothing_written(corrupt);
  const Exported missing = run(work / "nowhere", machine_annotations("[0, 0, -1]"), work);
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("no such file or folder"), std::string::npos) << missing.err;
}

TEST(ExportBadInput, AnnotationsNamingMissingPartsOrUnknownKeys) {
  const fs::path work = fresh_dir("export_bad_names");
  write_stl_machine(work / "cad");
  const Exported typo = run(work / "cad",
                            "parts:\n  drumm: {role: drum, material: steel}\n  hopper: {role: "
                            "hopper, material: steel}\n" +
                                std::string(kSceneKeys),
                            work);
  EXPECT_EQ(typo.code, 2);
  EXPECT_NE(
      typo.err.find(
          "annotations.yaml:2:3: parts.drumm: no part is named 'drumm' (did you mean 'drum'?)"),
      std::string::npos)
      << typo.err;
  expect_nothing_written(typo);
  const Exported key = run(work / "cad",
                           "parts:\n  drum: {role: drum, material: steel, rmp: 44.8}\n" +
                               std::string(kSceneKeys) + "solvr: {method: apgd}\n",
                           work);
  EXPECT_EQ(key.code, 2);
  EXPECT_NE(key.err.find("annotations.yaml:2:39: parts.drum.rmp: unknown key 'rmp' for a drum (did "
                         "you mean 'rpm'?)"),
            std::string::npos)
      << key.err;
  EXPECT_NE(key.err.find(":8:1: solvr: unknown key 'solvr'"), std::string::npos) << key.err;
  EXPECT_NE(key.err.find("(did you mean 'solver'?)"), std::string::npos) << key.err;
}

TEST(ExportBadInput, UnitsThatLookWrong) {
  const fs::path work = fresh_dir("export_bad_units");
  write_stl_machine(work / "metres", 1e-3);  // drawn in m, read as mm: 0.32 mm across
  const Exported small = run(work / "metres", machine_annotations("[0, 0, 1]"), work);
  EXPECT_EQ(small.code, 2);
  EXPECT_NE(small.err.find("units look wrong"), std::string::npos) << small.err;
  EXPECT_NE(small.err.find("set units: m"), std::string::npos) << small.err;
  expect_nothing_written(small);
  write_stl_machine(work / "mm");  // drawn in mm, read as m: a drum 320 m across
  const Exported large = run(work / "mm", "units: m\n" + machine_annotations("[0, 0, 1]"), work);
  EXPECT_EQ(large.code, 2);
  EXPECT_NE(large.err.find("drum 'drum' is 320 m across"), std::string::npos) << large.err;
  EXPECT_NE(large.err.find("set units: mm"), std::string::npos) << large.err;
  write_stl_machine(work / "inches", 1 / 25.4);  // drawn in inches, read as mm: r 6.3 mm
  const Exported inches = run(work / "inches", machine_annotations("[0, 0, 1]"), work);
  EXPECT_EQ(inches.code, 2);
  EXPECT_NE(inches.err.find("drum 'drum' has a radius of 6.299 mm, so the units look wrong"),
            std::string::npos)
      << inches.err;
  EXPECT_NE(inches.err.find("set units: in"), std::string::npos) << inches.err;
}

// `units: in` on CAD drawn in mm makes a drum 4 m in radius: named as the
// unit slip it is, with the unit that fits.
TEST(ExportBadInput, InchesOnAMillimetreModel) {
  const fs::path work = fresh_dir("export_bad_inches");
  write_stl_machine(work / "cad");
  const Exported e = run(work / "cad", "units: in\n" + machine_annotations("[0, 0, 1]"), work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("drum 'drum' has a radius of 4.064 m, so the units look wrong: the CAD "
                       "was read in in (units in the annotations); if the CAD is in mm, set "
                       "units: mm"),
            std::string::npos)
      << e.err;
  expect_nothing_written(e);
}

// The CAD's drum along its y (z up): the field models need it on z, and the
// message gives the frame that puts it there.
TEST(ExportBadInput, MachineDrawnInAnotherFrame) {
  const fs::path work = fresh_dir("export_bad_frame");
  fs::create_directories(work / "cad");
  const Eigen::AngleAxisd lay(kPi / 2, Vec3::UnitX());  // CAD z up: the drum along y
  const auto laid = [&](std::vector<Triangle> t, const Vec3& at) {
    for (Triangle& tri : t)
      for (Vec3& v : tri) v = lay * v + at;
    return t;
  };
  const double a = 30 * kPi / 180;
  write_stl(work / "cad" / "drum.stl", laid(cylinder(160, 300, 256), Vec3(0, 0, 800)));
  write_stl(work / "cad" / "electrode.stl",
            laid(cylinder(19, 300, 128), Vec3(267 * std::cos(a), 0, 800 + 267 * std::sin(a))));
  const std::string parts =
      "parts:\n"
      "  drum: {role: drum, material: steel, speed: 44.8 rpm, rotation_axis: [0, 1, 0]}\n"
      "  electrode: {role: electrode, voltage: -35 kV}\n" +
      std::string(kSceneKeys);
  const Exported e = run(work / "cad", parts, work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("annotations.yaml:2:3: drum 'drum' is centred at [0, 0, 0.8] along [0, 1, "
                       "0] (scene frame), but the field models need the drum's axis on z through "
                       "the origin; expected frame: {origin: drum, up: [0, 0, 1]} in the "
                       "annotations"),
            std::string::npos)
      << e.err;
  expect_nothing_written(e);
  const Exported fixed = run(work / "cad", "frame: {origin: drum, up: [0, 0, 1]}\n" + parts, work);
  ASSERT_EQ(fixed.code, 0) << fixed.err;
  EXPECT_NEAR(fixed.scene["electrostatics"]["electrodes"][0]["polar"]["distance"].as<double>(),
              0.267, 1e-6);
}

// A feed or a collector the exporter's own domain does not hold: the
// message says what that domain is and how to give another.
TEST(ExportBadInput, FeedOutsideTheDomainTheExporterMade) {
  const fs::path work = fresh_dir("export_bad_domain");
  write_stl_machine(work / "cad");
  const Exported e =
      run(work / "cad",
          machine_annotations("[0, 0, -1]") + "  grit: {density: 2500 kg/m^3, friction: 0.5}\n" +
              "feeds:\n"
              "  - {name: extra, rate: 1 g/s, mix: [{material: grit, size: {constant: 1 mm}}],\n"
              "     region: {box: {min: [0.5, 0.5, 0], max: [0.6, 0.6, 0.1]}}}\n"
              "collectors:\n"
              "  - {name: low, plane: {point: [0, -2, 0], normal: [0, 1, 0]},\n"
              "     bins: {axis: [1, 0, 0], from: -0.1, to: 0.1, count: 10}}\n",
          work);
  EXPECT_EQ(e.code, 2);
  const std::string domain =
      "(the domain is ces-export's: the parts' bounding box and a tenth of the machine around "
      "it, from [-0.196, -0.196, -0.186] to [0.196, 0.236, 0.186] m; expected the part inside "
      "it, or domain: {box: {min: [x, y, z], max: [x, y, z]}} in the annotations)";
  EXPECT_NE(e.err.find("annotations.yaml:13:"), std::string::npos) << e.err;  // the region
  EXPECT_NE(e.err.find("the region reaches outside the domain"), std::string::npos) << e.err;
  EXPECT_NE(e.err.find("the plane misses the domain"), std::string::npos) << e.err;
  EXPECT_EQ(std::count(e.err.begin(), e.err.end(), '\n'), 3) << e.err;  // 2 + "nothing written"
  std::size_t notes = 0;
  for (std::size_t at = e.err.find(domain); at != std::string::npos;
       at = e.err.find(domain, at + 1))
    ++notes;
  EXPECT_EQ(notes, 2u) << e.err;
  expect_nothing_written(e);
}

// A voltage or a drum speed without a unit would be read in SI (volts,
// rad/s): "-30" meant as kV, "44.8" meant as rpm. Refused, with the unit.
TEST(ExportBadInput, VoltageAndSpeedWithoutUnit) {
  const fs::path work = fresh_dir("export_bad_unitless");
  write_stl_machine(work / "cad");
  const Exported e = run(work / "cad",
                         "parts:\n"
                         "  drum: {role: drum, material: steel, speed: 44.8}\n"
                         "  electrode: {role: electrode, voltage: -30000}\n" +
                             std::string(kSceneKeys),
                         work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("annotations.yaml:2:46: parts.drum.speed: got 44.8, a number without a "
                       "unit, expected an angular speed with its unit such as '44.8 rpm' ('44.8 "
                       "rad/s' if rad/s are meant)"),
            std::string::npos)
      << e.err;
  EXPECT_NE(e.err.find("annotations.yaml:3:41: parts.electrode.voltage: got -30000, a number "
                       "without a unit, expected a voltage with its unit such as '-35 kV' "
                       "('-30000 V' if V are meant)"),
            std::string::npos)
      << e.err;
  expect_nothing_written(e);
  const Exported wrong = run(work / "cad",
                             "parts:\n"
                             "  drum: {role: drum, material: steel, speed: 44.8 rpm}\n"
                             "  electrode: {role: electrode, voltage: -30 mm}\n" +
                                 std::string(kSceneKeys),
                             work);
  EXPECT_EQ(wrong.code, 2);
  EXPECT_NE(wrong.err.find("parts.electrode.voltage: got '-30 mm', expected a voltage such as "
                           "'-35 kV'"),
            std::string::npos)
      << wrong.err;
}

// Exporting again replaces what the earlier export wrote and nothing else:
// the user's notes and a run written into the folder stay, the earlier
// export's mesh that this one does not write goes, and names a report was
// edited to list outside the folder are not touched.
TEST(ExportStl, ExportingAgainKeepsTheUsersFiles) {
  const fs::path work = fresh_dir("export_again");
  write_stl_machine(work / "cad");
  const Exported first = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(first.code, 0) << first.err;
  ASSERT_TRUE(fs::exists(first.folder / "meshes/hopper.stl"));
  std::ofstream(first.folder / "NOTES.txt") << "my notes\n";
  fs::create_directories(first.folder / "run");
  std::ofstream(first.folder / "run" / "bins.csv") << "bin\n";
  std::ofstream(work / "victim.txt") << "someone else's\n";
  nlohmann::json report = first.report;
  for (const std::string& name :
       std::vector<std::string>{"../victim.txt", (work / "victim.txt").string()})
    report["parts"].push_back({{"mesh_file", name}});
  std::ofstream(first.folder / "export_report.json") << report.dump();
  const Exported again =
      run(work / "cad",
          "parts:\n"
          "  drum: {role: drum, material: steel, speed: 44.8 rpm, rotation_axis: [0, 0, -1]}\n"
          "  \"split*\": {role: splitter, material: steel}\n" +
              std::string(kSceneKeys),
          work);
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_EQ(read_text(first.folder / "NOTES.txt"), "my notes\n");
  EXPECT_EQ(read_text(first.folder / "run" / "bins.csv"), "bin\n");
  EXPECT_TRUE(fs::exists(work / "victim.txt"));
  EXPECT_FALSE(fs::exists(first.folder / "meshes"));
  EXPECT_FALSE(again.scene["bodies"][2]) << again.scene["bodies"];  // drum and splitter only
  EXPECT_EQ(again.report["parts"].size(), 2u);
  for (const auto& entry : fs::directory_iterator(work))
    EXPECT_FALSE(entry.path().filename().string().starts_with(".out.")) << entry.path();
}

// A meshes/ folder the user replaced with a link to another folder is not
// written through: the export is refused before anything moves.
TEST(ExportStl, ExportingAgainWritesThroughNoLink) {
  const fs::path work = fresh_dir("export_linked_meshes");
  write_stl_machine(work / "cad");
  const Exported first = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(first.code, 0) << first.err;
  fs::create_directories(work / "elsewhere");
  std::ofstream(work / "elsewhere" / "hopper.stl") << "not a mesh of this export\n";
  fs::remove_all(first.folder / "meshes");
  fs::create_directory_symlink(work / "elsewhere", first.folder / "meshes");
  const std::string before = read_text(first.folder / "scene.yaml");
  const Exported again = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  EXPECT_EQ(again.code, 2) << again.err;
  EXPECT_NE(again.err.find("a link in the path leads out of the folder"), std::string::npos)
      << again.err;
  EXPECT_EQ(read_text(work / "elsewhere" / "hopper.stl"), "not a mesh of this export\n");
  EXPECT_EQ(read_text(first.folder / "scene.yaml"), before);
}

// What the export noticed is printed when it fails too: why a part is not
// the cylinder its role needs is in the warning the fit gives.
TEST(ExportStl, AFailedExportPrintsItsWarnings) {
  const fs::path work = fresh_dir("export_failed_warnings");
  write_stl_machine(work / "cad");
  std::string annotations = machine_annotations("[0, 0, -1]");
  const std::string hopper = "hopper: {role: hopper, material: steel}";
  annotations.replace(annotations.find(hopper), hopper.size(),
                      "hopper: {role: electrode, voltage: -30 kV}");
  const Exported e = run(work / "cad", annotations, work);
  EXPECT_EQ(e.code, 2);
  const std::size_t warning = e.err.find("warning: electrode 'hopper'");
  const std::size_t error = e.err.find("error: electrode 'hopper' is not a cylinder");
  ASSERT_NE(warning, std::string::npos) << e.err;
  ASSERT_NE(error, std::string::npos) << e.err;
  EXPECT_LT(warning, error) << e.err;
}

// The scene is named after the CAD folder however its path ends: "cad/"
// (as a shell completes it) named it "", which the loader refused at a
// line of the annotations that has no name key.
TEST(ExportStl, AFolderWithATrailingSlashNamesTheScene) {
  const fs::path work = fresh_dir("export_trailing_slash");
  write_stl_machine(work / "cad");
  const Exported e = run(work / "cad" / "", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_EQ(e.scene["name"].as<std::string>(), "cad");
}

// A part is named after its file, and a name goes into the scene and the
// JSON report: a file name that is not UTF-8 (Latin-1 'Schraube_\xe4')
// is refused naming the file, where the report's writer threw (exit 4).
TEST(ExportStl, FileNamesThatAreNotUtf8AreRefused) {
  const fs::path work = fresh_dir("export_latin1");
  write_stl_machine(work / "cad");
  fs::copy_file(work / "cad" / "hopper.stl", work / "cad" / "Schraube_\xe4.stl");
  const Exported e = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  EXPECT_EQ(e.code, 2) << e.err;
  EXPECT_NE(e.err.find("Schraube_\\xE4.stl: its name is not UTF-8 text"), std::string::npos)
      << e.err;
  expect_nothing_written(e);
}

// Exports into one folder publish one at a time: each removes the files its
// predecessor's report lists and it does not write, so two at once left a
// scene naming a mesh the other had removed. An export waits while the
// folder's parent is locked, then publishes.
TEST(ExportStl, ExportsIntoOneFolderPublishOneAtATime) {
  const fs::path work = fresh_dir("export_one_at_a_time");
  write_stl_machine(work / "cad");
  auto held = std::make_unique<ces::FolderLock>(work, true);
  auto waiting = std::async(std::launch::async, [&] {
    return run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  });
  EXPECT_EQ(waiting.wait_for(std::chrono::milliseconds(500)), std::future_status::timeout);
  EXPECT_FALSE(fs::exists(work / "out"));
  held.reset();
  const Exported done = waiting.get();
  EXPECT_EQ(done.code, 0) << done.err;
  EXPECT_TRUE(fs::exists(work / "out" / "scene.yaml"));
}

// Scene keys in the annotations are checked by the simulator's own loader;
// its findings point into the annotations, and an earlier export survives.
TEST(ExportBadInput, InvalidSceneKeysLeaveTheEarlierExportAlone) {
  const fs::path work = fresh_dir("export_bad_scene");
  write_stl_machine(work / "cad");
  const Exported good = run(work / "cad", machine_annotations("[0, 0, -1]"), work);
  ASSERT_EQ(good.code, 0) << good.err;
  const std::string before = read_text(good.folder / "scene.yaml");
  const Exported bad =
      run(work / "cad", machine_annotations("[0, 0, -1]") + "  copper: {friction: -1}\n", work);
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("annotations.yaml:10:22: materials.copper.friction"), std::string::npos)
      << bad.err;
  EXPECT_EQ(read_text(good.folder / "scene.yaml"), before);
  for (const auto& entry : fs::directory_iterator(work))
    EXPECT_FALSE(entry.path().filename().string().starts_with(".out.")) << entry.path();
}

}  // namespace
