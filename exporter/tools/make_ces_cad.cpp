// Writes meshes/ces/ces_machine.step: the reference machine of
// scenes/machines/ces_machine.yaml and ces_splitters.yaml (drum, brush,
// splitters, the static electrode and the corona wire, the feed's outlet and
// the collector's plate) as a CAD user would export it, so the round trip
// (CAD + annotations -> scene -> run) can be checked against the
// hand-written scene. Drawn like CAD, not like the scene: millimetres, z up,
// the drum axis along -y, the origin on the floor 800 mm below the drum axis
// and 500 mm behind it, each part at its own origin and placed by the
// assembly.
//
//   cmake --build build --target make_ces_cad && build/exporter/make_ces_cad
//   meshes/ces/ces_machine.step
#include <APIHeaderSection_MakeHeader.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <STEPCAFControl_Writer.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TDataStd_Name.hxx>
#include <TDocStd_Document.hxx>
#include <XCAFApp_Application.hxx>
#include <XCAFDoc_DocumentTool.hxx>
#include <XCAFDoc_ShapeTool.hxx>
#include <cmath>
#include <iostream>

namespace {

// Scene (x toward the electrode, y up, z along the drum; mm) to CAD.
gp_Trsf scene_to_cad() {
  gp_Trsf t;
  t.SetValues(1, 0, 0, 500,  //
              0, 0, -1, 0,   //
              0, 1, 0, 800);
  return t;
}

// A part placed at (x, y) of the scene, turned by `degrees` about z.
gp_Trsf at(double x, double y, double degrees = 0.0) {
  gp_Trsf turn, move;
  turn.SetRotation(gp::OZ(), degrees * M_PI / 180.0);
  move.SetTranslation(gp_Vec(x, y, 0.0));
  return scene_to_cad() * move * turn;
}

// A part on the drum's axis' polar grid, as the scene places electrodes.
gp_Trsf at_polar(double distance, double degrees) {
  const double a = degrees * M_PI / 180.0;
  return at(distance * std::cos(a), distance * std::sin(a));
}

// Solids centred on their own origin, cylinders along z.
TopoDS_Shape cylinder(double radius, double length) {
  return BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, -0.5 * length), gp::DZ()), radius, length)
      .Shape();
}

TopoDS_Shape box(double x, double y, double z) {
  return BRepPrimAPI_MakeBox(gp_Pnt(-0.5 * x, -0.5 * y, -0.5 * z), x, y, z).Shape();
}

void add(const Handle(XCAFDoc_ShapeTool) & tool, const TDF_Label& assembly, const char* name,
         const TopoDS_Shape& shape, const gp_Trsf& placement) {
  const TDF_Label part = tool->AddShape(shape, false);
  TDataStd_Name::Set(part, name);
  tool->AddComponent(assembly, part, TopLoc_Location(placement));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: make_ces_cad OUTPUT.step\n";
    return 2;
  }
  Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_PrinterOStream));
  Handle(XCAFApp_Application) app = XCAFApp_Application::GetApplication();
  Handle(TDocStd_Document) doc;
  app->NewDocument("MDTV-XCAF", doc);
  const Handle(XCAFDoc_ShapeTool) tool = XCAFDoc_DocumentTool::ShapeTool(doc->Main());
  const TDF_Label machine = tool->NewShape();
  TDataStd_Name::Set(machine, "ces_machine");
  // In the order of scenes/machines/ces_machine.yaml, then
  // ces_splitters.yaml: body order decides the order of contacts, and
  // electrode order that of the field's line charges, so the same order
  // gives the same run.
  add(tool, machine, "drum", cylinder(160, 300), at(0, 0));
  add(tool, machine, "brush", cylinder(53, 300), at(-213, 0));
  add(tool, machine, "splitter_1", box(4, 107, 303), at(160.35, -155.32, -15));
  add(tool, machine, "splitter_2", box(4, 150, 300), at(269.1, -140.9, 27));
  add(tool, machine, "electrode", cylinder(19, 300), at_polar(267, 30));
  add(tool, machine, "wire", cylinder(0.1, 300), at_polar(210.1, 75));
  add(tool, machine, "nozzle_outlet", box(100, 2, 182), at(-66, 184));
  // The collector plate spans the bins, from behind splitter 1 to the casing.
  add(tool, machine, "collector", box(1200, 2, 500), at(300, -210));
  add(tool, machine, "stand", box(1300, 20, 600), at(300, -240));
  tool->UpdateAssemblies();
  Interface_Static::SetCVal("xstep.cascade.unit", "MM");  // drawn in mm, written in mm
  Interface_Static::SetCVal("write.step.unit", "MM");
  STEPCAFControl_Writer writer;
  if (!writer.Transfer(doc, STEPControl_AsIs)) {
    std::cerr << "cannot transfer the machine to STEP\n";
    return 1;
  }
  // A fixed time stamp: the file is committed, and drawing it again with
  // nothing changed leaves it byte-identical.
  APIHeaderSection_MakeHeader header(writer.ChangeWriter().Model());
  header.SetTimeStamp(new TCollection_HAsciiString("1970-01-01T00:00:00"));
  if (writer.Write(argv[1]) != IFSelect_RetDone) {
    std::cerr << "cannot write " << argv[1] << "\n";
    return 1;
  }
  app->Close(doc);
  return 0;
}
