// ces-export on STEP assemblies written here with OpenCASCADE: exact
// cylinders, boxes and meshes from the assembly, the file's unit, a file
// that is not STEP, and the reference machine's file made malformed. Only in
// a build with OpenCASCADE.
#ifdef CES_EXPORT_HAVE_OCCT
#include <gtest/gtest.h>

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
#include <array>
#include <fstream>
#include <regex>
#include <vector>

#include "export_support.hpp"
#include "support.hpp"

namespace {

using namespace ces::export_test;
using ces::kPi;
using ces::Vec3;
using ces::test::fresh_dir;
using ces::test::read_text;

const fs::path kSourceRoot = CES_SOURCE_DIR;

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

// meshes/ces/ces_machine.step with every match of `pattern` replaced, written
// to `path`.
void write_edited_reference(const fs::path& path, const std::string& pattern,
                            const std::string& replacement) {
  const std::string text = read_text(kSourceRoot / "meshes/ces/ces_machine.step");
  const std::string edited = std::regex_replace(text, std::regex(pattern), replacement);
  ASSERT_NE(edited, text) << pattern;
  std::ofstream(path) << edited;
}

// The reference machine exported from `step` with its annotations.
Exported export_edited(const fs::path& step, const fs::path& work) {
  return run(step, read_text(kSourceRoot / "meshes/ces/annotations.yaml"), work);
}

// The reference machine read in inches: the unit slip is named before any
// part's own check (its wire, 2.54 mm thick, is too thick to ionise).
TEST(ExportStep, AUnitSlipIsNamedBeforeThePartsChecks) {
  const fs::path work = fresh_dir("export_step_inches");
  const Exported e =
      run(kSourceRoot / "meshes/ces/ces_machine.step",
          "units: in\n" + read_text(kSourceRoot / "meshes/ces/annotations.yaml"), work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(
      e.err.find("so the units look wrong: the CAD was read in in (units in the "
                 "annotations; the file says millimetre); if the CAD is in mm, set units: mm"),
      std::string::npos)
      << e.err;
  EXPECT_EQ(e.err.find("too thick"), std::string::npos) << e.err;
}

// A product named with a character past ASCII (STEP's \X2\ escape) keeps
// it, as UTF-8: the annotations name it as the CAD shows it, and the
// report, JSON, holds it (an ASCII conversion made 'St\xE4nder', which
// no annotation could name and the report could not hold).
TEST(ExportStep, ProductNamesPastAsciiAreUtf8) {
  const fs::path work = fresh_dir("export_step_utf8");
  const fs::path step = work / "machine.step";
  write_edited_reference(step, R"(PRODUCT\('stand','stand')",
                         R"(PRODUCT('St\X2\00E4\X0\nder','St\X2\00E4\X0\nder')");
  std::string annotations = read_text(kSourceRoot / "meshes/ces/annotations.yaml");
  annotations.replace(annotations.find("  stand:"), 8, "  \"St\u00e4nder\":");
  const Exported e = run(step, annotations, work);
  ASSERT_EQ(e.code, 0) << e.err;
  EXPECT_EQ(e.report["ignored"], nlohmann::json::array({"St\u00e4nder"}));
}

// Files that crash OpenCASCADE (a reference to a missing entity, an entity
// that refers to itself, a circle of radius 1e300) are errors naming the
// file, like a file that is not STEP.
TEST(ExportStep, FilesThatCrashOpenCascadeAreErrors) {
  const fs::path work = fresh_dir("export_step_crash");
  const std::vector<std::array<const char*, 3>> edits = {
      {"dangling.step", R"(#11 = AXIS2_PLACEMENT_3D\('',#12,)",
       "#11 = AXIS2_PLACEMENT_3D('',#999999,"},
      {"cycle.step", R"(#11 = AXIS2_PLACEMENT_3D\(.*\);)",
       "#11 = AXIS2_PLACEMENT_3D('',#11,#11,#11);"},
      {"radius.step", R"(CIRCLE\('',(#\d+),[^)]*\))", "CIRCLE('',$1,1.E300)"}};
  for (const auto& [name, pattern, replacement] : edits) {
    write_edited_reference(work / name, pattern, replacement);
    const Exported e = export_edited(work / name, work);
    EXPECT_EQ(e.code, 2) << name;
    EXPECT_NE(e.err.find("error: cannot read " + (work / name).string() + ": its reader stopped"),
              std::string::npos)
        << e.err;
    expect_nothing_written(e);
  }
}

// A zero axis direction makes an exact cylinder endless: refused, naming
// the file and the part, as a part over 20 m across is, though its
// triangles are of the size they should be.
TEST(ExportStep, EndlessCylindersAreRefused) {
  const fs::path work = fresh_dir("export_step_zero_direction");
  const fs::path step = work / "zero.step";
  write_edited_reference(step, R"(DIRECTION\('',\(0\.,0\.,1\.\)\))", "DIRECTION('',(0.,0.,0.))");
  const Exported e = export_edited(step, work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find(step.string() + ": drum 'drum' is "), std::string::npos) << e.err;
  EXPECT_NE(e.err.find(" m long (exact STEP surface) though its triangles span "),
            std::string::npos)
      << e.err;
  expect_nothing_written(e);
}

// Coordinates of 1e300 are reported at the STEP file, not as the
// non-finite electrode distances they become in the scene.
TEST(ExportStep, CoordinatesOutOfRangeAreErrorsOfTheFile) {
  const fs::path work = fresh_dir("export_step_far");
  const fs::path step = work / "far.step";
  write_edited_reference(step, R"(#(12|16|20|24|28) = CARTESIAN_POINT\('',\([^,]*,)",
                         "#$1 = CARTESIAN_POINT('',(1.E300,");
  const Exported e = export_edited(step, work);
  EXPECT_EQ(e.code, 2);
  EXPECT_NE(e.err.find("error: cannot read " + step.string() + ": part '"), std::string::npos)
      << e.err;
  EXPECT_NE(e.err.find("expected coordinates within 1e+06 m of the origin"), std::string::npos)
      << e.err;
  EXPECT_EQ(e.err.find("annotations.yaml"), std::string::npos) << e.err;
  expect_nothing_written(e);
}

}  // namespace
#endif
