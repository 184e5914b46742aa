// ces-export: CAD + annotations -> a scene ces-sim accepts. STEP assemblies
// written here with OpenCASCADE (when the build has it), the same machine as
// STL files, mesh cleaning and primitive recovery, bad input, and the round
// trip of the reference machine's CAD (meshes/ces/) against
// scenes/ces_pcb.yaml.
#include "export.hpp"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "fit.hpp"
#include "mesh.hpp"
#include "support.hpp"

#ifdef CES_EXPORT_HAVE_OCCT
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <STEPCAFControl_Writer.hxx>
#include <TDataStd_Name.hxx>
#include <TDocStd_Document.hxx>
#include <XCAFApp_Application.hxx>
#include <XCAFDoc_DocumentTool.hxx>
#include <XCAFDoc_ShapeTool.hxx>
#endif

namespace {

using namespace ces::exporter;
using ces::Vec3;
using ces::test::fresh_dir;
using ces::test::read_text;
namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;

// --- CAD written by the tests ----------------------------------------------

using Triangle = std::array<Vec3, 3>;

// Binary STL, as CAD programs write it (float coordinates).
void write_stl(const fs::path& path, const std::vector<Triangle>& triangles) {
  std::ofstream out(path, std::ios::binary);
  const char header[80] = {};
  out.write(header, 80);
  const auto count = std::uint32_t(triangles.size());
  out.write(reinterpret_cast<const char*>(&count), 4);
  for (const Triangle& t : triangles) {
    float record[12] = {};
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) record[3 + 3 * c + k] = float(t[c][k]);
    out.write(reinterpret_cast<const char*>(record), sizeof record);
    out.write("\0\0", 2);
  }
}

// A closed cylinder of `segments` sides along z, centred on `c`.
std::vector<Triangle> cylinder(double radius, double length, int segments,
                               const Vec3& c = Vec3::Zero()) {
  std::vector<Triangle> t;
  const Vec3 lo = c - 0.5 * length * Vec3::UnitZ(), hi = c + 0.5 * length * Vec3::UnitZ();
  for (int i = 0; i < segments; ++i) {
    const double a0 = 2 * kPi * i / segments, a1 = 2 * kPi * (i + 1) / segments;
    const Vec3 r0(radius * std::cos(a0), radius * std::sin(a0), 0),
        r1(radius * std::cos(a1), radius * std::sin(a1), 0);
    t.push_back({lo + r0, lo + r1, hi + r1});
    t.push_back({lo + r0, hi + r1, hi + r0});
    t.push_back({hi, hi + r0, hi + r1});
    t.push_back({lo, lo + r1, lo + r0});
  }
  return t;
}

std::vector<Triangle> box(const Vec3& lo, const Vec3& hi) {
  const Vec3 v[8] = {{lo.x(), lo.y(), lo.z()}, {hi.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), lo.z()},
                     {lo.x(), hi.y(), lo.z()}, {lo.x(), lo.y(), hi.z()}, {hi.x(), lo.y(), hi.z()},
                     {hi.x(), hi.y(), hi.z()}, {lo.x(), hi.y(), hi.z()}};
  const int f[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                        {2, 3, 7}, {2, 7, 6}, {1, 2, 6}, {1, 6, 5}, {0, 4, 7}, {0, 7, 3}};
  std::vector<Triangle> t;
  for (const auto& k : f) t.push_back({v[k[0]], v[k[1]], v[k[2]]});
  return t;
}

// The test machine in mm: a drum along z (R 160, 300 long), a box hopper
// above it and a plate splitter beside it.
void write_stl_machine(const fs::path& dir, double mm = 1.0, int drum_segments = 256) {
  fs::create_directories(dir);
  auto scaled = [&](std::vector<Triangle> t) {
    for (Triangle& tri : t)
      for (Vec3& v : tri) v *= mm;
    return t;
  };
  write_stl(dir / "drum.stl", scaled(cylinder(160, 300, drum_segments)));
  write_stl(dir / "hopper.stl", scaled(box({-50, 170, -50}, {-10, 200, 50})));
  write_stl(dir / "splitter.stl", scaled(box({150, -160, -150}, {152, -60, 150})));
}

const char* kSceneKeys = R"(
time: {step: 1 ms, end: 0.1 s}
gravity: [0, -9.81, 0]
materials:
  steel: {friction: 0.3}
)";

std::string machine_annotations(const std::string& drum_axis, const std::string& extra = "") {
  return "parts:\n"
         "  drum: {role: drum, material: steel, speed: 44.8 rpm, rotation_axis: " +
         drum_axis +
         "}\n"
         "  hopper: {role: hopper, material: steel}\n"
         "  \"split*\": {role: splitter, material: steel}\n" +
         extra + kSceneKeys;
}

#ifdef CES_EXPORT_HAVE_OCCT
struct StepPart {
  const char* name;
  TopoDS_Shape shape;
};

double millimetres_per(const std::string& unit) {
  return unit == "M" ? 1000.0 : unit == "INCH" ? 25.4 : 1.0;
}

// A STEP assembly of named parts, as XDE (and CAD programs) write it.
void write_step(const fs::path& path, const std::vector<StepPart>& parts, const char* unit = "MM") {
  Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_PrinterOStream));
  Handle(XCAFApp_Application) app = XCAFApp_Application::GetApplication();
  Handle(TDocStd_Document) doc;
  app->NewDocument("MDTV-XCAF", doc);
  const Handle(XCAFDoc_ShapeTool) tool = XCAFDoc_DocumentTool::ShapeTool(doc->Main());
  const TDF_Label assembly = tool->NewShape();
  TDataStd_Name::Set(assembly, "machine");
  for (const StepPart& p : parts) {
    const TDF_Label label = tool->AddShape(p.shape, false);
    TDataStd_Name::Set(label, p.name);
    tool->AddComponent(assembly, label, TopLoc_Location());
  }
  tool->UpdateAssemblies();
  // The shapes are drawn in `unit`: the session and the document say so
  // (the exporter sets the session to metres for its reading), and the
  // file is written in it.
  Interface_Static::SetCVal("xstep.cascade.unit", unit);
  Interface_Static::SetCVal("write.step.unit", unit);
  XCAFDoc_DocumentTool::SetLengthUnit(doc, millimetres_per(unit),
                                      UnitsMethods_LengthUnit_Millimeter);
  STEPCAFControl_Writer writer;
  ASSERT_TRUE(writer.Transfer(doc, STEPControl_AsIs));
  ASSERT_EQ(writer.Write(path.c_str()), IFSelect_RetDone);
  app->Close(doc);
}

// The STL machine's parts in a unit of `per_mm` per millimetre, the drum
// along x this time, centred on (0, 20, 30) mm.
std::vector<StepPart> step_machine(double per_mm = 1.0) {
  const double s = per_mm;
  return {
      {"drum", BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(-150 * s, 20 * s, 30 * s), gp::DX()), 160 * s,
                                        300 * s)
                   .Shape()},
      {"hopper",
       BRepPrimAPI_MakeBox(gp_Pnt(-50 * s, 170 * s, -50 * s), 40 * s, 30 * s, 100 * s).Shape()},
      {"splitter",
       BRepPrimAPI_MakeBox(gp_Pnt(150 * s, -160 * s, -150 * s), 2 * s, 100 * s, 300 * s).Shape()}};
}
#endif

// --- running it ------------------------------------------------------------

struct Exported {
  int code = -1;
  std::string out, err;
  fs::path folder;
  YAML::Node scene;
  nlohmann::json report;
};

Exported run(const fs::path& input, const std::string& annotations, const fs::path& work) {
  const fs::path file = work / "annotations.yaml";
  std::ofstream(file) << annotations;
  Exported e;
  e.folder = work / "out";
  std::ostringstream out, err;
  e.code = run_export({input.string(), file.string(), e.folder.string(), false}, out, err);
  e.out = out.str();
  e.err = err.str();
  if (e.code == 0) {
    e.scene = YAML::LoadFile((e.folder / "scene.yaml").string());
    e.report = nlohmann::json::parse(read_text(e.folder / "export_report.json"));
  }
  return e;
}

YAML::Node body(const Exported& e, const std::string& name) {
  for (const auto& b : e.scene["bodies"])
    if (b["name"].as<std::string>() == name) return b;
  ADD_FAILURE() << "no body " << name;
  return {};
}

Vec3 vec(const YAML::Node& n) { return {n[0].as<double>(), n[1].as<double>(), n[2].as<double>()}; }

const nlohmann::json& report_part(const Exported& e, const std::string& name) {
  for (const auto& p : e.report["parts"])
    if (p["name"] == name) return p;
  throw std::runtime_error("no part " + name + " in the report");
}

Vec3 json_vec(const nlohmann::json& j) {
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

// The bounding box of a binary STL's vertices.
std::pair<Vec3, Vec3> stl_bounds(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  in.seekg(80);
  std::uint32_t n = 0;
  in.read(reinterpret_cast<char*>(&n), 4);
  Vec3 lo = Vec3::Constant(1e300), hi = -lo;
  for (std::uint32_t t = 0; t < n; ++t) {
    float r[12];
    in.read(reinterpret_cast<char*>(r), sizeof r);
    in.ignore(2);
    for (int c = 1; c < 4; ++c) {
      const Vec3 v(r[3 * c], r[3 * c + 1], r[3 * c + 2]);
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  return {lo, hi};
}

void expect_validates(const Exported& e, const std::string& extra = "") {
  const auto v = ces::test::ces_sim("validate " + (e.folder / "scene.yaml").string() + extra);
  EXPECT_EQ(v.code, 0) << v.out << v.err;
}

// Failed exports leave neither the folder nor the one being built.
void expect_nothing_written(const Exported& e) {
  EXPECT_FALSE(fs::exists(e.folder));
  for (const auto& entry : fs::directory_iterator(e.folder.parent_path()))
    EXPECT_FALSE(entry.path().filename().string().starts_with(".out.")) << entry.path();
}

void expect_hopper(const Exported& e) {
  const YAML::Node hopper = body(e, "hopper");
  ASSERT_TRUE(hopper["geometry"]["mesh"]) << hopper;
  const fs::path mesh = e.folder / hopper["geometry"]["mesh"]["file"].as<std::string>();
  const auto [lo, hi] = stl_bounds(mesh);
  EXPECT_LT((lo - Vec3(-0.05, 0.17, -0.05)).norm(), 1e-7);  // float coordinates
  EXPECT_LT((hi - Vec3(-0.01, 0.20, 0.05)).norm(), 1e-7);
  const auto& box = report_part(e, "hopper")["mesh"]["bounding_box"];
  EXPECT_LT((json_vec(box["min"]) - Vec3(-0.05, 0.17, -0.05)).norm(), 1e-9);
  EXPECT_LT((json_vec(box["max"]) - Vec3(-0.01, 0.20, 0.05)).norm(), 1e-9);
  EXPECT_EQ(report_part(e, "hopper")["mesh"]["open_edges"], 0);
}

void expect_splitter_box(const Exported& e) {
  const YAML::Node s = body(e, "splitter");
  ASSERT_TRUE(s["geometry"]["box"]) << s;
  EXPECT_LT((vec(s["geometry"]["box"]["size"]) - Vec3(0.002, 0.1, 0.3)).norm(), 1e-6);
  EXPECT_LT((vec(s["pose"]["position"]) - Vec3(0.151, -0.11, 0)).norm(), 1e-6);
}

// --- STEP ------------------------------------------------------------------

#ifdef CES_EXPORT_HAVE_OCCT
TEST(ExportStep, AssemblyGivesAnExactDrumAndAMeshHopper) {
  const fs::path work = fresh_dir("export_step");
  write_step(work / "machine.step", step_machine());
  const Exported e = run(work / "machine.step", machine_annotations("[-1, 0, 0]"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  const YAML::Node drum = body(e, "drum");
  ASSERT_TRUE(drum["geometry"]["cylinder"]) << drum;
  EXPECT_NEAR(drum["geometry"]["cylinder"]["radius"].as<double>(), 0.16, 1e-9);
  EXPECT_NEAR(drum["geometry"]["cylinder"]["length"].as<double>(), 0.30, 1e-9);
  EXPECT_LT((vec(drum["pose"]["axis"]) - Vec3::UnitX()).norm(), 1e-9);
  EXPECT_LT((vec(drum["pose"]["position"]) - Vec3(0, 0.02, 0.03)).norm(), 1e-9);
  EXPECT_LT((vec(drum["motion"]["rotation"]["axis"]) + Vec3::UnitX()).norm(), 1e-12);
  EXPECT_EQ(drum["motion"]["rotation"]["speed"].as<std::string>(), "44.8 rpm");
  EXPECT_EQ(report_part(e, "drum")["cylinder"]["source"], "exact STEP surface");
  expect_hopper(e);
  expect_splitter_box(e);
  // OpenCASCADE's banners stay off stdout, which is the report.
  EXPECT_EQ(e.out.find("****"), std::string::npos) << e.out;
  EXPECT_NE(e.out.find("exact STEP surface"), std::string::npos) << e.out;
  expect_validates(e);
}

TEST(ExportStep, FileUnitsAreConvertedToMetres) {
  for (const auto& [unit, per_mm] : {std::pair{"M", 1e-3}, std::pair{"INCH", 1 / 25.4}}) {
    const fs::path work = fresh_dir(std::string("export_step_") + unit);
    write_step(work / "machine.step", step_machine(per_mm), unit);
    const Exported e = run(work / "machine.step", machine_annotations("[1, 0, 0]"), work);
    ASSERT_EQ(e.code, 0) << unit << ": " << e.err;
    EXPECT_NEAR(body(e, "drum")["geometry"]["cylinder"]["radius"].as<double>(), 0.16, 1e-9) << unit;
    EXPECT_NEAR(body(e, "drum")["geometry"]["cylinder"]["length"].as<double>(), 0.30, 1e-9) << unit;
  }
}

TEST(ExportStep, UnreadableFileIsAnError) {
  const fs::path work = fresh_dir("export_step_bad");
  std::ofstream(work / "broken.step") << "ISO-10303-21;\nthis is not STEP\n";
  const Exported e = run(work / "broken.step", machine_annotations("[1, 0, 0]"), work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("cannot read"), std::string::npos) << e.err;
  expect_nothing_written(e);
}

// The reference machine drawn as CAD (mm, z up, drum along -y, placed by
// the assembly) exported with its annotations runs like scenes/ces_pcb.yaml.
TEST(ExportRoundTrip, ReferenceMachineRunsLikeCesPcb) {
  const fs::path root = CES_SOURCE_DIR;
  if (!fs::exists(root / "scenes/ces_pcb.yaml"))
    GTEST_SKIP() << "scenes/ces_pcb.yaml not there yet";
  const fs::path work = fresh_dir("export_round_trip");
  const Exported e = run(root / "meshes/ces/ces_machine.step",
                         read_text(root / "meshes/ces/annotations.yaml"), work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_EQ(e.err, "");  // every part has a role, every cylinder is exact
  // 0.45 s with a 40 ms feed: the first particles land on both sides. One
  // thread: the test runs beside others (ctest -j2).
  const std::string shorter =
      " --quiet --threads 1 --set time.end=0.45s --set feeds.nozzle.duration=0.04s";
  const auto ref = ces::test::ces_sim((root / "scenes/ces_pcb.yaml").string() + " -o " +
                                      (work / "ref").string() + shorter);
  ASSERT_EQ(ref.code, 0) << ref.err;
  const auto exp = ces::test::ces_sim((e.folder / "scene.yaml").string() + " -o " +
                                      (work / "exp").string() + shorter);
  ASSERT_EQ(exp.code, 0) << exp.err;
  const auto cmp =
      ces::test::ces_sim("compare " + (work / "ref").string() + " " + (work / "exp").string());
  EXPECT_EQ(cmp.code, 0) << cmp.out << cmp.err;
}
#else
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

// --- mesh cleaning and primitives -----------------------------------------

Mesh soup(const std::vector<Triangle>& triangles) {
  Mesh m;
  for (const Triangle& t : triangles) {
    const auto base = std::uint32_t(m.vertices.size());
    for (const Vec3& v : t) m.vertices.push_back(v);
    m.triangles.push_back({base, base + 1, base + 2});
  }
  return m;
}

double signed_volume(const Mesh& m) {
  double v = 0;
  for (const auto& t : m.triangles)
    v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]])) / 6;
  return v;
}

TEST(ExportMesh, WeldsDropsDegenerateAndOrientsOutward) {
  std::vector<Triangle> t = box({0, 0, 0}, {1, 2, 3});
  for (Triangle& tri : t) std::swap(tri[1], tri[2]);           // all inward...
  std::swap(t[4][1], t[4][2]);                                 // ...but one
  t.push_back({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)});  // zero area
  Mesh m = soup(t);
  const MeshQuality q = clean(m, 1e-9);
  EXPECT_EQ(q.vertices, 8u);
  EXPECT_EQ(q.merged_vertices, 39u - 9u);  // (2, 0, 0) stays until its triangle goes
  EXPECT_EQ(q.degenerate_triangles, 1u);
  EXPECT_EQ(q.triangles, 12u);
  EXPECT_EQ(q.open_edges + q.non_manifold_edges + q.orientation_conflicts, 0u);
  EXPECT_EQ(q.closed_pieces, 1u);
  EXPECT_EQ(q.flipped_triangles, 11u);
  EXPECT_NEAR(signed_volume(m), 6.0, 1e-12);
}

TEST(ExportMesh, CountsOpenAndNonManifoldEdges) {
  Mesh sheet = soup({{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)},
                     {Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}});
  const MeshQuality open = clean(sheet, 1e-9);
  EXPECT_EQ(open.open_edges, 4u);
  EXPECT_EQ(open.flipped_triangles, 1u);  // the second ran the shared edge the same way
  EXPECT_EQ(open.closed_pieces, 0u);
  Mesh fin = soup({{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)},
                   {Vec3(1, 0, 0), Vec3(0, 0, 0), Vec3(0, -1, 0)},
                   {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)}});
  EXPECT_EQ(clean(fin, 1e-9).non_manifold_edges, 1u);
}

TEST(ExportFit, RotatedBoxIsABoxAndAnOpenOneIsNot) {
  std::vector<Triangle> t = box({-0.002, -0.075, -0.15}, {0.002, 0.075, 0.15});
  const Eigen::AngleAxisd turn(27 * kPi / 180, Vec3::UnitZ());
  for (Triangle& tri : t)
    for (Vec3& v : tri) v = turn * v + Vec3(0.2377, -0.1409, 0);
  Mesh m = soup(t);
  clean(m, 1e-12);
  const auto b = match_box(m, 1e-9);
  ASSERT_TRUE(b);
  EXPECT_LT((b->size - Vec3(0.004, 0.15, 0.3)).norm(), 1e-12);
  EXPECT_LT((b->center - Vec3(0.2377, -0.1409, 0)).norm(), 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(b->frame).angle(), 27 * kPi / 180, 1e-12);
  t.pop_back();
  t.pop_back();  // no left face
  Mesh open = soup(t);
  clean(open, 1e-12);
  EXPECT_FALSE(match_box(open, 1e-9));
}

TEST(ExportFit, CylinderAlongAnyAxis) {
  std::vector<Triangle> t = cylinder(0.053, 0.3, 128);
  const Eigen::AngleAxisd tilt(0.7, Vec3(1, 2, 3).normalized());
  for (Triangle& tri : t)
    for (Vec3& v : tri) v = tilt * v + Vec3(-0.213, 0.1, 0.05);
  Mesh m = soup(t);
  clean(m, 1e-12);
  const auto f = fit_cylinder(m);
  ASSERT_TRUE(f);
  EXPECT_NEAR(f->cylinder.radius, 0.053, 1e-12);
  EXPECT_NEAR(f->cylinder.length, 0.3, 1e-12);
  EXPECT_LT(f->cylinder.axis.cross(tilt * Vec3::UnitZ()).norm(), 1e-12);
  EXPECT_LT((f->cylinder.center - Vec3(-0.213, 0.1, 0.05)).norm(), 1e-12);
  EXPECT_LT(f->rms / f->cylinder.radius, 0.005);
}

}  // namespace
