// STEP (AP203/AP214) through OpenCASCADE's XDE reader: part names from the
// assembly, triangles from BRepMesh, exact cylinders from the B-rep. The
// file is read in a child process (read_step says why).
#include <BRepAdaptor_Surface.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_PrinterOStream.hxx>
#include <Poly_Triangulation.hxx>
#include <STEPCAFControl_Reader.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_Failure.hxx>
#include <TColStd_SequenceOfAsciiString.hxx>
#include <TCollection_AsciiString.hxx>
#include <TDF_LabelSequence.hxx>
#include <TDataStd_Name.hxx>
#include <TDocStd_Document.hxx>
#include <TopExp_Explorer.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <XCAFApp_Application.hxx>
#include <XCAFDoc_DocumentTool.hxx>
#include <XCAFDoc_ShapeTool.hxx>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "common/isolate.hpp"
#include "common/serial.hpp"
#include "parts.hpp"

namespace ces::exporter {
namespace {

Vec3 vec(const gp_XYZ& p) { return {p.X(), p.Y(), p.Z()}; }

// OpenCASCADE reports through Message printers on stdout; the exporter's
// stdout is its report, so they go.
void silence_occt() {
  Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_PrinterOStream));
}

// The label's name, or "" for none and for the placeholders ("=>[0:1:1:2]")
// OpenCASCADE gives unnamed assembly instances.
std::string label_name(const TDF_Label& label) {
  Handle(TDataStd_Name) name;
  if (!label.FindAttribute(TDataStd_Name::GetID(), name)) return "";
  // Without a replacement character OpenCASCADE writes UTF-8.
  const std::string s = TCollection_AsciiString(name->Get()).ToCString();
  return s.starts_with("=>") ? "" : s;
}

Mesh tessellate(const TopoDS_Shape& shape, const StepOptions& options) {
  BRepMesh_IncrementalMesh mesher(shape, options.deflection, false, options.angle, false);
  Mesh mesh;
  for (TopExp_Explorer e(shape, TopAbs_FACE); e.More(); e.Next()) {
    const TopoDS_Face& face = TopoDS::Face(e.Current());
    TopLoc_Location loc;
    const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, loc);
    if (tri.IsNull()) continue;
    const auto base = std::uint32_t(mesh.vertices.size());
    for (int i = 1; i <= tri->NbNodes(); ++i)
      mesh.vertices.push_back(vec(tri->Node(i).Transformed(loc.Transformation()).XYZ()));
    // Reversed faces have their material on the other side of the surface.
    const bool reversed = face.Orientation() == TopAbs_REVERSED;
    for (int i = 1; i <= tri->NbTriangles(); ++i) {
      int a = 0, b = 0, c = 0;
      tri->Triangle(i).Get(a, b, c);
      if (reversed) std::swap(b, c);
      mesh.triangles.push_back(
          {base + std::uint32_t(a - 1), base + std::uint32_t(b - 1), base + std::uint32_t(c - 1)});
    }
  }
  return mesh;
}

struct CylinderFace {
  Vec3 origin, axis;
  double radius, v0, v1;
};

bool same_surface(const CylinderFace& a, const CylinderFace& b) {
  const double tol = 1e-9 * std::max(a.radius, 1.0);
  const Vec3 offset = b.origin - a.origin;
  return std::abs(a.radius - b.radius) <= tol && a.axis.cross(b.axis).norm() <= 1e-9 &&
         (offset - offset.dot(a.axis) * a.axis).norm() <= tol;
}

std::vector<CylinderFace> cylinder_faces(const TopoDS_Shape& shape) {
  std::vector<CylinderFace> faces;
  for (TopExp_Explorer e(shape, TopAbs_FACE); e.More(); e.Next()) {
    const BRepAdaptor_Surface s(TopoDS::Face(e.Current()));
    if (s.GetType() != GeomAbs_Cylinder) continue;
    const gp_Cylinder c = s.Cylinder();
    faces.push_back({vec(c.Location().XYZ()), vec(c.Axis().Direction().XYZ()), c.Radius(),
                     s.FirstVParameter(), s.LastVParameter()});
  }
  return faces;
}

// The largest cylindrical surface, its faces' extents along the axis joined.
std::optional<ExactCylinder> largest_cylinder(const TopoDS_Shape& shape) {
  const auto faces = cylinder_faces(shape);
  if (faces.empty()) return std::nullopt;
  const CylinderFace& outer = *std::max_element(
      faces.begin(), faces.end(), [](const auto& a, const auto& b) { return a.radius < b.radius; });
  ExactCylinder ex;
  const Vec3 axis = canonical_axis(outer.axis);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const CylinderFace& f : faces) {
    if (!same_surface(outer, f)) {
      ++ex.other_cylinders;
      continue;
    }
    ++ex.faces;
    for (double v : {f.v0, f.v1}) {
      const double along = (f.origin + v * f.axis).dot(axis);
      lo = std::min(lo, along);
      hi = std::max(hi, along);
    }
  }
  const Vec3 foot = outer.origin - outer.origin.dot(axis) * axis;
  ex.cylinder = {axis, foot + 0.5 * (lo + hi) * axis, outer.radius, hi - lo};
  return ex;
}

class Walker {
 public:
  Walker(const Handle(XCAFDoc_ShapeTool) & tool, const StepOptions& options)
      : tool_(tool), options_(options) {}

  // Assemblies are walked down to their parts, locations composed.
  void walk(const TDF_Label& label, const TopLoc_Location& loc, const std::string& instance) {
    if (tool_->IsAssembly(label)) {
      TDF_LabelSequence components;
      XCAFDoc_ShapeTool::GetComponents(label, components);
      for (int i = 1; i <= components.Length(); ++i) {
        TDF_Label referred;
        XCAFDoc_ShapeTool::GetReferredShape(components(i), referred);
        walk(referred, loc * XCAFDoc_ShapeTool::GetLocation(components(i)),
             label_name(components(i)));
      }
      return;
    }
    add_part(label, XCAFDoc_ShapeTool::GetShape(label).Moved(loc), instance);
  }

  std::vector<Part> parts;

 private:
  void add_part(const TDF_Label& label, const TopoDS_Shape& shape, const std::string& instance) {
    Part p;
    p.name = label_name(label);
    if (p.name.empty())
      p.name = instance.empty() ? "part_" + std::to_string(parts.size() + 1) : instance;
    p.instance = instance == p.name ? "" : instance;
    p.mesh = tessellate(shape, options_);
    p.exact_cylinder = largest_cylinder(shape);
    parts.push_back(std::move(p));
  }

  Handle(XCAFDoc_ShapeTool) tool_;
  const StepOptions& options_;
};

std::string declared_unit(STEPCAFControl_Reader& reader) {
  TColStd_SequenceOfAsciiString lengths, angles, solid_angles;
  reader.ChangeReader().FileUnits(lengths, angles, solid_angles);
  return lengths.IsEmpty() ? "" : lengths.First().ToCString();
}

// Rescales parts read in the file's declared unit to the unit the
// annotations say the file really uses.
void override_unit(std::vector<Part>& parts, const std::string& declared, double metres_per_unit,
                   const std::string& path) {
  const auto file_scale = unit_scale(declared);
  if (!file_scale)
    throw InputError(path + ": its length unit '" + declared +
                     "' is not one ces-export knows, so units cannot override it");
  const double f = metres_per_unit / *file_scale;
  for (Part& p : parts) {
    for (Vec3& v : p.mesh.vertices) v *= f;
    if (p.exact_cylinder) {
      Cylinder& c = p.exact_cylinder->cylinder;
      c.center *= f;
      c.radius *= f;
      c.length *= f;
    }
  }
}

std::vector<Part> read_document(const std::string& path, const StepOptions& options,
                                std::string& file_unit) {
  Handle(XCAFApp_Application) app = XCAFApp_Application::GetApplication();
  Handle(TDocStd_Document) doc;
  app->NewDocument("MDTV-XCAF", doc);
  STEPCAFControl_Reader reader;
  reader.SetNameMode(true);
  // Metres, both through the session unit and the document's own unit
  // (OpenCASCADE 7.6 takes the document's when it has one).
  Interface_Static::SetCVal("xstep.cascade.unit", "M");
  XCAFDoc_DocumentTool::SetLengthUnit(doc, 1.0, UnitsMethods_LengthUnit_Meter);
  if (reader.ReadFile(path.c_str()) != IFSelect_RetDone)
    throw InputError("cannot read " + path + ": not a STEP file OpenCASCADE can read");
  file_unit = declared_unit(reader);
  if (!reader.Transfer(doc)) throw InputError("cannot read " + path + ": no shapes transferred");
  Walker walker(XCAFDoc_DocumentTool::ShapeTool(doc->Main()), options);
  TDF_LabelSequence free;
  XCAFDoc_DocumentTool::ShapeTool(doc->Main())->GetFreeShapes(free);
  for (int i = 1; i <= free.Length(); ++i) walker.walk(free(i), TopLoc_Location(), "");
  app->Close(doc);
  if (walker.parts.empty()) throw InputError("cannot read " + path + ": it holds no shapes");
  return std::move(walker.parts);
}

// ------------------------------------------------------------ across a pipe

struct StepRead {
  std::vector<Part> parts;
  std::string file_unit;
};

// A part as bytes for the parent (both ends are the same program), and
// back.
void put(ByteWriter& out, const Part& p) {
  out.text(p.name);
  out.text(p.instance);
  out.values(p.mesh.vertices);
  out.values(p.mesh.triangles);
  out.value(char(p.exact_cylinder.has_value()));
  if (!p.exact_cylinder) return;
  const ExactCylinder& e = *p.exact_cylinder;
  out.value(e.cylinder.axis);
  out.value(e.cylinder.center);
  out.value(e.cylinder.radius);
  out.value(e.cylinder.length);
  out.value(e.faces);
  out.value(e.other_cylinders);
}

Part get_part(ByteReader& in) {
  Part p;
  p.name = in.text();
  p.instance = in.text();
  in.values(p.mesh.vertices);
  in.values(p.mesh.triangles);
  if (!in.value<char>()) return p;
  ExactCylinder& e = p.exact_cylinder.emplace();
  in.value(e.cylinder.axis);
  in.value(e.cylinder.center);
  in.value(e.cylinder.radius);
  in.value(e.cylinder.length);
  in.value(e.faces);
  in.value(e.other_cylinders);
  return p;
}

// The child's answer: 'P' and the parts, or 'E' and the error message.
std::string answer(const std::string& path, const StepOptions& options) {
  try {
    silence_occt();
    StepRead read;
    read.parts = read_document(path, options, read.file_unit);
    ByteWriter out;
    out.value('P');
    out.text(read.file_unit);
    out.value(std::uint64_t(read.parts.size()));
    for (const Part& part : read.parts) put(out, part);
    return std::move(out).take();
  } catch (const InputError& e) {
    return std::string("E") + e.what();
  } catch (const Standard_Failure& e) {
    return "Ecannot read " + path + ": OpenCASCADE: " + e.GetMessageString();
  } catch (const std::exception& e) {
    return "Ecannot read " + path + ": " + e.what();
  }
}

// Runs answer() in a child process under limits (common/isolate.hpp) and
// returns it; a child that dies or runs past them is an InputError naming
// the file.
std::string answer_in_child(const std::string& path, const StepOptions& options) {
  try {
    return run_isolated([&] { return answer(path, options); }, reader_limits(path));
  } catch (const std::runtime_error& e) {
    throw InputError("cannot read " + path + ": " + e.what() +
                     ", expected a well-formed STEP file (a reference to a missing entity, an "
                     "entity that refers to itself or a value out of range can crash "
                     "OpenCASCADE)");
  }
}

StepRead unpack(const std::string& bytes, const std::string& path) {
  if (bytes.front() == 'E') throw InputError(bytes.substr(1));
  ByteReader in(bytes);
  in.value<char>();
  StepRead read;
  read.file_unit = in.text();
  const auto parts = in.value<std::uint64_t>();
  for (std::uint64_t k = 0; k < parts; ++k) read.parts.push_back(get_part(in));
  if (!in.at_end())
    throw std::runtime_error("the STEP reader's answer for " + path + " is too long");
  return read;
}

}  // namespace

bool have_step_reader() { return true; }

// OpenCASCADE crashes (SIGSEGV) on some malformed files instead of
// throwing: an entity that refers to one the file lacks, or to itself, a
// radius of 1e300. Its own remedy, OSD::SetSignal with OCC_CATCH_SIGNALS,
// jumps out of the signal handler past the destructors of every frame in
// between and leaves OpenCASCADE's state, and the heap a wild write may
// have hit, as the fault left them: the process must not go on trusting
// them, and a fault it does not catch still kills the exporter silently.
// So a forked child reads the file and sends the parts back through a
// pipe: whatever the file does to the child, the exporter survives it and
// names the file.
std::vector<Part> read_step(const std::string& path, const StepOptions& options,
                            std::string& file_unit) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError("cannot read " + path + ": no such file");
  StepRead read = unpack(answer_in_child(path, options), path);
  file_unit = read.file_unit;
  if (options.unit_override) override_unit(read.parts, file_unit, *options.unit_override, path);
  for (Part& p : read.parts) p.source = path;
  return std::move(read.parts);
}

}  // namespace ces::exporter
