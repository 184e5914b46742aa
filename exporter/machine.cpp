#include "machine.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include "format.hpp"
#include "scene/diagnostics.hpp"
#include "scene/electrostatics.hpp"
#include "scene/scene.hpp"

namespace ces::exporter {
namespace {

// A machine part outside these sizes means a unit slip (mm read as m, or
// m read as mm), not a real separator.
constexpr double kLargestPart = 20.0;      // m
constexpr double kSmallestMachine = 0.01;  // m
// A separator's drum is centimetres to decimetres in radius: over a metre
// is CAD in mm read as inches or centimetres, under two centimetres CAD in
// inches or centimetres read as mm.
constexpr double kLargestDrumRadius = 1.0;    // m
constexpr double kSmallestDrumRadius = 0.02;  // m

std::string list_names(const std::vector<std::string>& names) {
  std::string s;
  for (std::size_t i = 0; i < names.size() && i < 20; ++i) s += (i ? ", " : "") + names[i];
  return names.size() > 20 ? s + ", ..." : s;
}

// Every rule must name at least one part; a `name` must name one part.
void check_rules(const std::vector<Part>& parts, const Annotations& a) {
  std::vector<std::string> names;
  for (const Part& p : parts) names.push_back(p.name);
  scene::Diagnostics diags;
  for (const Rule& r : a.rules) {
    const auto n =
        std::count_if(parts.begin(), parts.end(), [&](const Part& p) { return matches(r, p); });
    if (n == 0)
      diags.error(r.mark, r.spec->path,
                  "no part is named '" + r.pattern + "'" + scene::did_you_mean(r.pattern, names) +
                      ", expected one of the parts: " + list_names(names));
    if (n > 1 && r.spec->find("name"))
      diags.error(*r.spec->find("name"),
                  "'" + r.pattern + "' matches " + std::to_string(n) +
                      " parts but a name can go to one, expected a rule per part");
  }
  if (!diags.empty()) diags.raise();
}

class Names {
 public:
  // The first free of: the annotation's name, the part name, the instance
  // name, the part name with a number.
  std::string take(const Part& part, const Rule& rule) {
    if (const scene::Node* n = rule.spec->find("name")) return claim(n->string());
    if (!taken(part.name)) return claim(part.name);
    if (!part.instance.empty() && !taken(part.instance)) return claim(part.instance);
    for (int k = 2;; ++k)
      if (const std::string s = part.name + "_" + std::to_string(k); !taken(s)) return claim(s);
  }

 private:
  bool taken(const std::string& s) const { return used_.count(s) > 0; }
  std::string claim(const std::string& s) {
    used_.insert(s);
    return s;
  }
  std::set<std::string> used_;
};

// The exact cylinder, when it is the part's outer surface (the tessellation
// stays inside it).
bool use_exact(Placed& p, std::vector<std::string>& warnings) {
  const ExactCylinder& ex = *p.part->exact_cylinder;
  const Cylinder& c = ex.cylinder;
  double outermost = 0.0;
  for (const Vec3& v : p.mesh.vertices) {
    const Vec3 d = v - c.center;
    outermost = std::max(outermost, (d - d.dot(c.axis) * c.axis).norm());
  }
  if (outermost > c.radius * (1.0 + 1e-3)) {
    warnings.push_back(label(p) + ": its largest cylindrical face (radius " + metres(c.radius) +
                       ") is not its outer surface (the part reaches " + metres(outermost) +
                       " from that axis)");
    return false;
  }
  if (ex.other_cylinders > 0)
    warnings.push_back(
        label(p) + ": " + std::to_string(ex.other_cylinders) +
        " cylindrical face(s) of other radii or axes (a shaft, a bore?) are left out "
        "of the cylinder");
  p.cylinder = c;
  p.cylinder_source = "step";
  return true;
}

bool use_fit(Placed& p, double tolerance, std::vector<std::string>& warnings) {
  p.fit = fit_cylinder(p.mesh);
  if (!p.fit) {
    warnings.push_back(label(p) +
                       ": no cylinder can be fitted to its mesh (no side parallel to an axis)");
    return false;
  }
  const double relative = p.fit->rms / p.fit->cylinder.radius;
  if (relative > tolerance || p.fit->other_fraction > 0.01) {
    warnings.push_back(label(p) + ": the best cylinder (radius " + metres(p.fit->cylinder.radius) +
                       ") misses the mesh by " + metres(p.fit->rms) + " RMS (" + percent(relative) +
                       " of the radius, limit " + percent(tolerance) + "; " +
                       percent(p.fit->other_fraction) +
                       " of the area is neither side nor end caps)");
    return false;
  }
  p.cylinder = p.fit->cylinder;
  p.cylinder_source = "fit";
  return true;
}

bool recover_cylinder(Placed& p, double tolerance, std::vector<std::string>& warnings) {
  if (p.part->exact_cylinder && use_exact(p, warnings)) return true;
  return use_fit(p, tolerance, warnings);
}

std::string wanted_shape(const Placed& p, const char* fallback) {
  const scene::Node* s = p.rule->spec->find("shape");
  return s ? s->string() : fallback;
}

void place_drum(Placed& p, double tolerance, std::vector<std::string>& warnings) {
  const bool want = wanted_shape(p, "cylinder") == "cylinder";
  if (want && recover_cylinder(p, tolerance, warnings)) {
    p.output = Output::Cylinder;
    return;
  }
  if (want) warnings.back() += ": kept as a mesh";
  if (p.rule->spec->find("joint"))
    throw InputError(label(p) +
                     " has a joint, which needs a cylinder (a dynamic body cannot be a mesh)");
}

std::string box_misfit(const BoxFit& f) {
  const Vec3& s = f.box.size;
  return "its oriented box (" + metres(s.x()) + " x " + metres(s.y()) + " x " + metres(s.z()) +
         ") misses it by " + percent(f.volume_error) + " in volume and " + percent(f.face_error) +
         " in a face's area, with " + percent(f.other_area) +
         " of the area facing none of its faces (limit " + percent(kBoxTolerance) + ")";
}

void place_splitter(Placed& p, std::vector<std::string>& warnings) {
  if (wanted_shape(p, "box") == "box") {
    p.box_fit = fit_box(p.mesh);
    if (p.box_fit && p.box_fit->within(kBoxTolerance)) {
      p.box = p.box_fit->box;
      p.output = Output::Box;
      return;
    }
    if (p.box_fit)
      warnings.push_back(label(p) + ": " + box_misfit(*p.box_fit) + ": kept as a mesh");
  }
  if (p.rule->spec->find("joint"))
    throw InputError(label(p) +
                     " has a joint, which needs a box-shaped plate (a dynamic body cannot "
                     "be a mesh), but the part is " +
                     (p.box_fit ? "not a box: " + box_misfit(*p.box_fit) : "kept as a mesh"));
}

// Where a part's cylinder comes from, for messages.
const char* cylinder_origin(const Placed& p) {
  return p.cylinder_source == "step" ? "exact STEP surface" : "fitted";
}

// A corona wire thicker than the scene allows never ionises: refused at
// its rule with the cylinder the part gave, before the scene loader would.
void check_wire(const Placed& p) {
  const scene::Node* type = p.rule->spec->find("type");
  if (!type || type->string() != "corona" || p.cylinder->radius <= scene::kMaxCoronaWireRadius)
    return;
  throw InputError(where(type->mark) + type->path + ": " + label(p) + " has a radius of " +
                   metres(p.cylinder->radius) + " (" + cylinder_origin(p) +
                   "), too thick to ionise: expected a corona wire of radius at most " +
                   metres(scene::kMaxCoronaWireRadius) + ", or type: static for a field electrode");
}

Placed place(const Part& part, const Rule& rule, const Annotations& a, Names& names,
             std::vector<std::string>& warnings) {
  Placed p;
  p.part = &part;
  p.rule = &rule;
  p.name = names.take(part, rule);
  p.mesh = part.mesh;
  p.quality = clean(p.mesh, weld_tolerance(p.mesh));
  if (p.mesh.triangles.empty())
    throw InputError(label(p) + " (" + part.source + ") has no surface: all its " +
                     std::to_string(p.quality.input_triangles) + " triangles are degenerate");
  switch (rule.role) {
    case Role::Drum:
    case Role::Brush:
      place_drum(p, a.fit_tolerance, warnings);
      break;
    case Role::Splitter:
      place_splitter(p, warnings);
      break;
    case Role::Electrode:
      if (!recover_cylinder(p, a.fit_tolerance, warnings))
        throw InputError(label(p) + " is not a cylinder, which an electrode must be");
      p.output = Output::Electrode;  // its wire is checked once the units are
      break;
    case Role::FeedOutlet:
      p.output = Output::Feed;
      break;
    case Role::CollectorPlane:
      p.output = Output::Collector;
      break;
    default:
      break;
  }
  return p;
}

// Suggests the unit that makes the machine a plausible size (5 cm to 5 m).
std::string unit_suggestion(double extent, const UnitChoice& units) {
  for (const char* u : {"mm", "m", "in", "cm"}) {
    const double e = extent / units.scale * *unit_scale(u);
    if (e >= 0.05 && e <= 5.0) return "; if the CAD is in " + std::string(u) + ", set units: " + u;
  }
  return "";
}

// The cylinder a part becomes need not span its triangles: a STEP surface
// with a zero axis direction is endless. Checked once the triangles are
// known to fit the bound, so the file's geometry is at fault, not its unit
// (NaN counts as over).
void check_cylinder_length(const Placed& p) {
  if (!p.cylinder || p.cylinder->length <= kLargestPart) return;
  throw InputError(p.part->source + ": " + label(p) + " is a cylinder " +
                   metres(p.cylinder->length) + " long (" + cylinder_origin(p) +
                   ") though its triangles span " + metres(p.quality.bounds.size().maxCoeff()) +
                   ", expected at most " + metres(kLargestPart) +
                   " (an axis direction of zero makes it endless)");
}

void check_units(const Machine& m, const UnitChoice& units) {
  Bounds all;
  for (const Placed& p : m.parts) {
    all.add(p.quality.bounds);
    const double size = p.quality.bounds.size().maxCoeff();
    if (size > kLargestPart)
      throw InputError(label(p) + " is " + metres(size) +
                       " across, so the units look wrong: the CAD was read in " + units.how +
                       unit_suggestion(all.size().maxCoeff(), units));
    check_cylinder_length(p);
  }
  for (const Placed& p : m.parts)
    if (p.rule->role == Role::Drum && p.cylinder &&
        !(p.cylinder->radius >= kSmallestDrumRadius && p.cylinder->radius <= kLargestDrumRadius))
      throw InputError(label(p) + " has a radius of " + metres(p.cylinder->radius) +
                       ", so the units look wrong: the CAD was read in " + units.how +
                       unit_suggestion(all.size().maxCoeff(), units));
  if (!all.empty() && all.size().maxCoeff() < kSmallestMachine)
    throw InputError("the machine is " + metres(all.size().maxCoeff()) +
                     " across, so the units look wrong: the CAD was read in " + units.how +
                     unit_suggestion(all.size().maxCoeff(), units));
}

// The first drum that is a cylinder, in CAD coordinates; `why` says what
// kept each drum from being one.
std::optional<Cylinder> find_drum(const std::vector<Part>& parts, const Annotations& a,
                                  std::string& why) {
  for (const Part& part : parts) {
    const Rule* r = rule_for(a, part);
    if (!r || r->role != Role::Drum) continue;
    Placed p;
    p.part = &part;
    p.rule = r;
    p.mesh = part.mesh;
    clean(p.mesh, weld_tolerance(p.mesh));
    std::vector<std::string> noticed;  // place() reports them once the frame is set
    if (recover_cylinder(p, a.fit_tolerance, noticed)) return p.cylinder;
    for (const std::string& w : noticed) why += (why.empty() ? "" : "; ") + w;
  }
  return std::nullopt;
}

// scene point = rotation (CAD point - origin)
struct Rigid {
  Mat3 rotation = Mat3::Identity();
  Vec3 origin = Vec3::Zero();
};

Rigid frame_of(const std::vector<Part>& parts, const Annotations& a) {
  const Frame& f = a.frame;
  if (!f.given) return {};
  std::string why;
  const auto drum = find_drum(parts, a, why);
  if (f.origin_at_drum && !drum)
    throw InputError(where(f.mark) +
                     "frame: origin is drum, but no part with role drum is a cylinder" +
                     (why.empty() ? "" : " (" + why + ")"));
  Vec3 z = f.axis ? *f.axis : drum ? drum->axis : Vec3::UnitZ();
  if (std::abs(z.dot(f.up)) > 1e-6)
    throw InputError(where(f.mark) + "frame: " + (f.axis ? "axis " : "the drum's axis ") +
                     vector_text(z) + " is not perpendicular to up " + vector_text(f.up) +
                     ", expected up across the drum (the CAD direction that becomes +y)");
  z = (z - z.dot(f.up) * f.up).normalized();
  Rigid r;
  r.rotation.row(0) = f.up.cross(z);
  r.rotation.row(1) = f.up;
  r.rotation.row(2) = z;
  r.origin = f.origin_at_drum ? drum->center : f.origin;
  return r;
}

void move_part(Part& p, const Rigid& t) {
  for (Vec3& v : p.mesh.vertices) v = t.rotation * (v - t.origin);
  if (!p.exact_cylinder) return;
  Cylinder& c = p.exact_cylinder->cylinder;
  c.center = t.rotation * (c.center - t.origin);
  c.axis = canonical_axis(t.rotation * c.axis);
}

// File names safe on every system, unique.
void name_mesh_files(Machine& m) {
  std::set<std::string> used;
  for (Placed& p : m.parts) {
    if (p.output != Output::Mesh) continue;
    std::string stem = p.name;
    for (char& c : stem)
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') c = '_';
    std::string file = stem;
    for (int k = 2; used.count(file); ++k) file = stem + "_" + std::to_string(k);
    used.insert(file);
    p.mesh_file = "meshes/" + file + ".stl";
  }
}

}  // namespace

std::string label(const Placed& p) {
  return std::string(role_name(p.rule->role)) + " '" + p.part->name + "'";
}

Machine assemble(std::vector<Part> parts, const Annotations& a, const UnitChoice& units,
                 std::vector<std::string>& warnings) {
  check_rules(parts, a);
  Machine m;
  const Rigid frame = frame_of(parts, a);
  for (Part& p : parts) move_part(p, frame);
  m.cad = std::move(parts);
  m.rotation = frame.rotation;
  Names names;
  for (const Part& part : m.cad) {
    const Rule* r = rule_for(a, part);
    if (!r)
      m.unassigned.push_back(part.name);
    else if (r->role == Role::Ignore)
      m.ignored.push_back(part.name);
    else
      m.parts.push_back(place(part, *r, a, names, warnings));
  }
  if (!m.unassigned.empty())
    warnings.push_back(std::to_string(m.unassigned.size()) +
                       " part(s) have no role and are left out: " + list_names(m.unassigned) +
                       " (give them a role, or role: ignore)");
  if (m.parts.empty()) throw InputError("no part has a role, so there is nothing to export");
  check_units(m, units);
  for (const Placed& p : m.parts)
    if (p.output == Output::Electrode) check_wire(p);
  name_mesh_files(m);
  return m;
}

}  // namespace ces::exporter
