#include "export.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <utility>

#include "annotations.hpp"
#include "builder.hpp"
#include "common/path.hpp"
#include "format.hpp"
#include "machine.hpp"
#include "scene/diagnostics.hpp"
#include "scene/resolve.hpp"
#include "scene/scene.hpp"

namespace ces::exporter {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;
using scene::Mark;
using scene::Node;

// ------------------------------------------------------------------ reading

bool is_step(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".step" || ext == ".stp";
}

struct Cad {
  std::vector<Part> parts;
  UnitChoice units;
};

// Coordinates beyond this are a broken file, not a machine's placement:
// fits and frames square them, and a square overflows past 1e154.
constexpr double kFarthest = 1e6;  // m

// Every point of every part within kFarthest of the origin (NaN is not),
// so that a coordinate out of range is reported at the file that holds it
// rather than as whatever it becomes downstream.
void check_range(const std::vector<Part>& parts) {
  for (const Part& p : parts) {
    const auto check = [&](const Vec3& v) {
      if ((v.array().abs() <= kFarthest).all()) return;
      throw InputError("cannot read " + p.source + ": part '" + p.name + "' has a point at " +
                       vector_text(v) + " m, expected coordinates within " + metres(kFarthest) +
                       " of the origin");
    };
    for (const Vec3& v : p.mesh.vertices) check(v);
    if (p.exact_cylinder) check(p.exact_cylinder->cylinder.center);
  }
}

Cad read_cad(const std::string& input, const Annotations& a) {
  if (is_step(input)) {
    std::string declared;
    auto parts = read_step(input, {a.deflection, a.angle, a.unit}, declared);
    check_range(parts);
    if (a.unit)
      return {
          std::move(parts),
          {*a.unit, a.unit_name + " (units in the annotations; the file says " + declared + ")"}};
    return {std::move(parts),
            {unit_scale(declared).value_or(1.0), declared + " (the STEP file's unit)"}};
  }
  const double scale = a.unit.value_or(1e-3);
  auto parts = read_mesh_files(input, scale);
  check_range(parts);
  return {std::move(parts),
          {scale,
           a.unit ? a.unit_name + " (units in the annotations)" : "mm (the default for STL/OBJ)"}};
}

// The top-level keys the annotations' includes define (they decide, for
// example, whether the exporter makes a domain). The annotations are read
// as the scene loader reads a scene, so an include outside their folder and
// the --include-path folders is refused before it is opened: annotations
// must not be a way to read, or probe, a machine's files.
std::set<std::string> included_keys(const Annotations& a,
                                    const std::vector<std::string>& include_paths) {
  scene::Diagnostics diags;
  scene::Budget budget;
  const auto tree = scene::load_tree(a.path, include_paths, budget, diags);
  if (!diags.empty()) diags.raise();
  std::set<std::string> keys;
  for (const scene::Entry& e : tree->entries)
    if (e.key_mark.file != a.path) keys.insert(e.key);
  return keys;
}

// The folders of the annotations' includes: the scene includes them where
// they are, so ces-sim must be told it may read them (--include-path). The
// exporter's own --include-path folders follow, unannounced: the includes'
// own includes may come from them.
std::vector<std::string> include_folders(const Annotations& a,
                                         const std::vector<std::string>& include_paths,
                                         std::vector<std::string>& warnings) {
  std::error_code ec;
  std::set<std::string> folders;
  for (const Node* inc : a.includes) {
    const fs::path p = fs::absolute(fs::path(a.path).parent_path() / inc->string(), ec);
    folders.insert(fs::weakly_canonical(p, ec).parent_path().string());
  }
  for (const std::string& f : folders)
    warnings.push_back("the scene includes fragments from " + f + ": run it with --include-path " +
                       f);
  std::vector<std::string> all(folders.begin(), folders.end());
  for (const std::string& f : include_paths) {
    const std::string p = fs::weakly_canonical(fs::absolute(f, ec), ec).string();
    if (folders.insert(p).second) all.push_back(p);
  }
  return all;
}

// ------------------------------------------------------------------ the folder

constexpr const char* kReport = "export_report.json";

fs::path output_folder(const std::string& given) {
  fs::path out = fs::absolute(given).lexically_normal();
  return out.filename().empty() ? out.parent_path() : out;
}

// Replacing a folder ces-export did not write could destroy someone's work.
void check_output(const fs::path& out) {
  std::error_code ec;
  if (!fs::exists(out, ec)) return;
  if (!fs::is_directory(out, ec))
    throw InputError("cannot write to " + out.string() + ": it is a file, expected a folder");
  if (!fs::is_empty(out, ec) && !fs::exists(out / kReport, ec))
    throw InputError("cannot write to " + out.string() +
                     ": the folder exists and is not an earlier export (no export_report.json), "
                     "expected a new folder or an earlier export to replace");
}

// Beside the target, so relative paths out of it resolve the same.
fs::path sibling(const fs::path& out, const std::string& what) {
  std::string name = ".";
  name += out.filename().string();
  name += '.';
  name += what;
  name += '-';
  name += std::to_string(::getpid());
  return out.parent_path() / name;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw InputError("cannot write " + path.string());
}

// The files an export writes, relative to its folder, as its report says:
// the scene, the report and the parts' mesh files. A name that does not
// stay inside the folder is left out: a report is text anyone may edit.
std::vector<std::string> written_files(const json& report) {
  std::vector<std::string> files{kReport};
  const auto add = [&](const json& name) {
    if (name.is_string() && is_inner_file_name(name.get<std::string>()))
      files.push_back(name.get<std::string>());
  };
  if (!report.is_object()) return files;
  if (report.contains("scene")) add(report["scene"]);
  if (report.contains("parts") && report["parts"].is_array())
    for (const json& p : report["parts"])
      if (p.is_object() && p.contains("mesh_file")) add(p["mesh_file"]);
  return files;
}

// The files the earlier export in `out` wrote (none when its report does
// not parse).
std::vector<std::string> earlier_files(const fs::path& out) {
  std::ifstream in(out / kReport);
  const json report = json::parse(in, nullptr, false);
  return report.is_discarded() ? std::vector<std::string>{} : written_files(report);
}

// Moves the export's `files` from `temp` into `out`. Over an earlier
// export, file by file: the earlier export's files this one does not
// write again go, and nothing else in the folder is touched (the user's
// notes, a run written into it), as ces-sim treats its output folder. The
// report moves last, so the folder's report lists what it holds.
void publish(const fs::path& temp, const fs::path& out, const std::vector<std::string>& files) {
  // One export at a time publishes into the folder: two at once would each
  // remove the files the other's report does not list. The lock is the
  // parent's, which exists (the temporary folder is its child).
  const FolderLock one_at_a_time(absolute_path(out).parent_path(), true);
  std::error_code ec;
  if (!fs::exists(out, ec)) return fs::rename(temp, out);
  for (const std::string& f : files)
    if (fs::is_directory(out / f, ec))
      throw InputError("cannot write " + (out / f).string() +
                       ": it is a folder, expected a file of the earlier export or nothing");
  replace_files(temp, out, files, earlier_files(out), kReport);
  if (fs::is_directory(fs::symlink_status(out / "meshes", ec)))
    fs::remove(out / "meshes", ec);  // only when no file is left in it
}

// Removes the folder being built unless it was published.
class TempFolder {
 public:
  explicit TempFolder(fs::path p) : path_(std::move(p)) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// ------------------------------------------------------------------ validation

// Lines of the written scene to the marks of the nodes written there, so
// the loader's findings point into the annotations.
void index_lines(const Node& written, const Node& built, std::map<int, Mark>& lines) {
  lines[written.mark.line] = built.mark;
  for (std::size_t i = 0; i < std::min(written.items.size(), built.items.size()); ++i)
    index_lines(written.items[i], built.items[i], lines);
  for (std::size_t i = 0; i < std::min(written.entries.size(), built.entries.size()); ++i) {
    lines[written.entries[i].key_mark.line] = built.entries[i].key_mark;
    index_lines(written.entries[i].value, built.entries[i].value, lines);
  }
}

std::vector<scene::Diagnostic> map_back(std::vector<scene::Diagnostic> found,
                                        const std::string& written_path, const std::string& text,
                                        const Node& built) {
  scene::Diagnostics unused;
  scene::Budget budget;
  const auto parsed = scene::parse(text, written_path, false, budget, unused);
  std::map<int, Mark> lines;
  if (parsed) index_lines(*parsed, built, lines);
  for (scene::Diagnostic& d : found) {
    if (d.file != written_path) continue;  // in an included fragment: already right
    auto it = lines.upper_bound(d.line);
    const Mark& m = it == lines.begin() ? built.mark : (--it)->second;
    d.file = m.file;
    d.line = m.line;
    d.column = m.column;
  }
  return found;
}

// ------------------------------------------------------------------ report

const char* output_name(Output o) {
  switch (o) {
    case Output::Cylinder:
      return "cylinder";
    case Output::Box:
      return "box";
    case Output::Mesh:
      return "mesh";
    case Output::Electrode:
      return "electrode";
    case Output::Feed:
      return "feed outlet";
    case Output::Collector:
      return "collector plane";
  }
  return "?";
}

json cylinder_json(const Cylinder& c) {
  return {{"axis", vec_json(c.axis)},
          {"center", vec_json(c.center)},
          {"radius", c.radius},
          {"length", c.length}};
}

json part_json(const Placed& p) {
  json j{{"name", p.part->name}};
  if (!p.part->instance.empty()) j["instance"] = p.part->instance;
  j["role"] = role_name(p.rule->role);
  j["scene_name"] = p.name;
  j["becomes"] = output_name(p.output);
  if (p.cylinder) {
    j["cylinder"] = cylinder_json(*p.cylinder);
    j["cylinder"]["source"] =
        p.cylinder_source == "step" ? "exact STEP surface" : "least-squares fit";
  }
  if (p.fit) {
    j["cylinder_fit"] = cylinder_json(p.fit->cylinder);
    j["cylinder_fit"]["rms_residual"] = p.fit->rms;
    j["cylinder_fit"]["rms_relative"] = p.fit->rms / p.fit->cylinder.radius;
    j["cylinder_fit"]["other_area_fraction"] = p.fit->other_fraction;
    j["cylinder_fit"]["used"] = p.cylinder_source == "fit";
  }
  if (p.box_fit) {
    const Box& b = p.box_fit->box;
    const Eigen::AngleAxisd turn(b.frame);
    j["box_fit"] = {
        {"center", vec_json(b.center)},
        {"size", vec_json(b.size)},
        {"rotation", {{"axis", vec_json(turn.axis())}, {"angle_deg", turn.angle() * 180.0 / kPi}}},
        {"volume_error", p.box_fit->volume_error},
        {"face_error", p.box_fit->face_error},
        {"other_area", p.box_fit->other_area},
        {"used", p.box.has_value()}};
  }
  if (!p.mesh_file.empty()) j["mesh_file"] = p.mesh_file;
  j["mesh"] = p.quality.to_json();
  return j;
}

json report_json(const ExportOptions& o, const UnitChoice& units, const Machine& m,
                 const std::vector<std::string>& warnings) {
  json parts = json::array();
  for (const Placed& p : m.parts) parts.push_back(part_json(p));
  return {{"input", o.input},     {"annotations", o.annotations},
          {"units", units.how},   {"scene", "scene.yaml"},
          {"parts", parts},       {"unassigned", m.unassigned},
          {"ignored", m.ignored}, {"warnings", warnings}};
}

// ------------------------------------------------------------------ summary

std::string cylinder_text(const Placed& p) {
  const Cylinder& c = *p.cylinder;
  std::string s = "radius " + metres(c.radius) + ", length " + metres(c.length) + ", axis " +
                  vector_text(c.axis) + " through " + vector_text(c.center);
  if (p.cylinder_source == "step") return s + "; exact STEP surface";
  return s + "; fitted, RMS " + metres(p.fit->rms) + " = " + percent(p.fit->rms / c.radius) +
         " of the radius";
}

std::string box_text(const Placed& p) {
  const Box& b = *p.box;
  std::string s = metres(b.size.x()) + " x " + metres(b.size.y()) + " x " + metres(b.size.z()) +
                  " at " + vector_text(b.center);
  const Eigen::AngleAxisd turn(b.frame);
  char angle[32];
  std::snprintf(angle, sizeof angle, "%.4g deg", turn.angle() * 180.0 / kPi);
  if (turn.angle() > 1e-12)
    s += ", turned " + std::string(angle) + " about " + vector_text(turn.axis());
  return s + "; off its box by " + percent(p.box_fit->volume_error) + " in volume, " +
         percent(std::max(p.box_fit->face_error, p.box_fit->other_area)) + " in face area";
}

std::string part_text(const Placed& p) {
  if (p.cylinder) return cylinder_text(p);
  if (p.box) return box_text(p);
  const MeshQuality& q = p.quality;
  if (!p.mesh_file.empty())
    return p.mesh_file + ": " + std::to_string(q.triangles) + " triangles, " +
           std::to_string(q.open_edges) + " open and " + std::to_string(q.non_manifold_edges) +
           " non-manifold edges, " + std::to_string(q.closed_pieces) + " of " +
           std::to_string(q.pieces) + " pieces closed";
  return "from " + vector_text(q.bounds.min) + " to " + vector_text(q.bounds.max);
}

std::string plural(Output o, int n) {
  const std::string one = output_name(o);
  if (n == 1) return one;
  return o == Output::Box || o == Output::Mesh ? one + "es" : one + "s";
}

// "2 cylinders, 1 box, 1 feed outlet".
std::string counts_text(const Machine& m) {
  std::map<Output, int> count;
  for (const Placed& p : m.parts) ++count[p.output];
  std::string s;
  for (const auto& [output, n] : count)
    s += (s.empty() ? "" : ", ") + std::to_string(n) + " " + plural(output, n);
  const std::size_t out = m.unassigned.size() + m.ignored.size();
  return out ? s + "; " + std::to_string(out) + " left out" : s;
}

std::string frame_text(const Annotations& a, const Machine& m) {
  if (!a.frame.given) return "no frame: the CAD's axes are the scene's (+y up)";
  return "frame: the CAD's " + vector_text(m.rotation.row(1).transpose()) + " is up (+y), " +
         vector_text(m.rotation.row(2).transpose()) + " is +z, the origin " +
         (a.frame.origin_at_drum ? std::string("on the drum's axis")
                                 : "at " + vector_text(a.frame.origin));
}

std::string rate_text(const Feed& f) {
  char s[64];
  if (f.mass_rate > 0.0)
    std::snprintf(s, sizeof s, "%.4g g/s", 1e3 * f.mass_rate);
  else
    std::snprintf(s, sizeof s, "%.4g /s", f.count_rate);
  std::string text = s;
  std::snprintf(s, sizeof s, " from %.4g s", f.start);
  text += s;
  if (f.duration < 1e300) {
    std::snprintf(s, sizeof s, " for %.4g s", f.duration);
    text += s;
  }
  return text;
}

std::string collector_text(const Collector& c) {
  std::string s = std::to_string(c.bins) + " bins along " + vector_text(c.axis) + " from " +
                  metres(c.from) + " to " + metres(c.to) + " on the plane through " +
                  vector_text(c.point) + " facing " + vector_text(c.normal);
  for (std::size_t i = 0; i < c.products.size(); ++i)
    s += (i ? ", " : "; products ") + c.products[i].name;
  return s;
}

struct Summary {
  const ExportOptions& options;
  const Annotations& annotations;
  const UnitChoice& units;
  const Machine& machine;
  const Simulation& sim;
  const std::set<std::string>& made;  // top-level keys ces-export wrote itself
  const std::vector<std::string>& include_paths;  // the folders its includes come from
};

void print_parts(std::ostream& out, const Machine& m) {
  char line[160];
  for (const Placed& p : m.parts) {
    std::snprintf(line, sizeof line, "  %-14s %-15s %-15s ", p.name.c_str(),
                  role_name(p.rule->role), output_name(p.output));
    out << line << part_text(p) << "\n";
  }
  const auto list = [&](const std::vector<std::string>& names, const char* why) {
    if (names.empty()) return;
    out << "  left out (" << why << "): ";
    for (std::size_t i = 0; i < names.size(); ++i) out << (i ? ", " : "") << names[i];
    out << "\n";
  };
  list(m.ignored, "role: ignore");
  list(m.unassigned, "no role");
}

// What the run will see: one screen, the details in export_report.json.
void print_summary(std::ostream& out, const Summary& s) {
  const fs::path scene = fs::path(s.options.output) / "scene.yaml";
  out << "ces-export: " << s.options.input << " -> " << scene.string() << "\n"
      << "CAD read in " << s.units.how << "; " << frame_text(s.annotations, s.machine) << "\n"
      << "made: " << counts_text(s.machine) << "\n\n";
  print_parts(out, s.machine);
  const Vec3 up = s.machine.rotation.row(1).transpose();
  out << "\ngravity:    " << vector_text(s.sim.model->gravity) << " m/s^2"
      << (s.made.count("gravity") ? " (ces-export's: down is the CAD's " + vector_text(-up) + ")"
                                  : std::string(" (from the annotations)"))
      << "\n";
  if (s.sim.domain)
    out << "domain:     " << vector_text(s.sim.domain->min) << " to "
        << vector_text(s.sim.domain->max) << " m"
        << (s.made.count("domain") ? " (ces-export's: the parts and a tenth of the machine around)"
                                   : " (from the annotations)")
        << "\n";
  for (const Feed& f : s.sim.feeds)
    out << "feed:       " << f.name << ": " << rate_text(f) << " out of "
        << vector_text(f.region.min) << " to " << vector_text(f.region.max) << "\n";
  for (const Collector& c : s.sim.collectors)
    out << "collector:  " << c.name << ": " << collector_text(c) << "\n";
  if (s.sim.feeds.empty()) out << "feed:       none (no feed_outlet part, no feeds key)\n";
  if (s.sim.collectors.empty())
    out << "collector:  none (no collector_plane part, no collectors key)\n";
  out << "next:       ces-sim " << scene.string();
  for (const std::string& folder : s.include_paths) out << " --include-path " << folder;
  out << "\n";
}

// ------------------------------------------------------------------ pipeline

std::string scene_header(const ExportOptions& o) {
  return "# Made by ces-export from " + o.input + " with " + o.annotations +
         ".\n# Lengths in metres. Edit the annotations and export again rather than this file.\n";
}

// The loader's findings about a domain ces-export made say what it is.
void note_domain(std::vector<scene::Diagnostic>& found, const Bounds& domain) {
  for (scene::Diagnostic& d : found)
    if (d.message.find("domain") != std::string::npos)
      d.message +=
          " (the domain is ces-export's: the parts' bounding box and a tenth of the "
          "machine around it, from " +
          vector_text(domain.min) + " to " + vector_text(domain.max) +
          " m; expected the part inside it, or domain: {box: {min: [x, y, z], max: [x, "
          "y, z]}} in the annotations)";
}

// The scene is named after its CAD: the STEP file's stem, or the folder's
// name of STL/OBJ files, however the path is written ("cad/", ".").
std::string scene_name(const std::string& input) {
  fs::path p = absolute_path(input);
  if (p.filename().empty()) p = p.parent_path();
  return p.stem().string();
}

// `warnings` gathers what the export noticed; the caller prints them
// whether it succeeds or not (a failure's cause is often among them).
void export_all(const ExportOptions& o, std::ostream& out, std::ostream& err,
                std::vector<std::string>& warnings) {
  const Annotations a = read_annotations(o.annotations);
  std::set<std::string> included = included_keys(a, o.include_paths);
  const fs::path folder = output_folder(o.output);
  check_output(folder);
  Cad cad = read_cad(o.input, a);
  const UnitChoice units = cad.units;
  const Machine m = assemble(std::move(cad.parts), a, units, warnings);
  const SceneSetup setup{scene_name(o.input), folder / "scene.yaml", std::move(included)};
  std::set<std::string> made;
  for (const char* key : {"gravity", "domain"})
    if (!a.root->find(key) && !setup.included_keys.count(key)) made.insert(key);
  const Node root = build_scene(m, a, setup, warnings);
  scene::LoadOptions check;
  check.include_paths = include_folders(a, o.include_paths, warnings);
  const std::string text = scene_header(o) + scene::to_yaml(root);

  const TempFolder temp(sibling(folder, "tmp"));
  if (std::any_of(m.parts.begin(), m.parts.end(),
                  [](const Placed& p) { return p.output == Output::Mesh; }))
    fs::create_directories(temp.path() / "meshes");
  for (const Placed& p : m.parts)
    if (p.output == Output::Mesh)
      write_binary_stl(p.mesh, temp.path() / p.mesh_file, "ces-export: " + p.name + ", metres");
  const std::string written = (temp.path() / "scene.yaml").string();
  write_text(written, text);
  const json report = report_json(o, units, m, warnings);
  write_text(temp.path() / kReport, report.dump(2) + "\n");
  Simulation sim;
  try {
    sim = scene::load(written, check);
  } catch (const scene::SceneError& e) {
    auto found = map_back(e.diagnostics(), written, text, root);
    if (made.count("domain")) note_domain(found, default_domain(m));
    throw scene::SceneError(found);
  }
  publish(temp.path(), folder, written_files(report));
  for (const std::string& w : std::exchange(warnings, {})) err << "warning: " << w << "\n";
  if (!o.quiet) print_summary(out, {o, a, units, m, sim, made, check.include_paths});
}

}  // namespace

int run_export(const ExportOptions& options, std::ostream& out, std::ostream& err) {
  std::vector<std::string> warnings;
  const auto noticed = [&] {
    for (const std::string& w : warnings) err << "warning: " << w << "\n";
  };
  try {
    export_all(options, out, err, warnings);
    return kExitOk;
  } catch (const scene::SceneError& e) {
    noticed();
    for (const scene::Diagnostic& d : e.diagnostics()) err << d.str() << "\n";
    err << "ces-export: nothing written\n";
  } catch (const InputError& e) {
    noticed();
    err << "error: " << e.what() << "\nces-export: nothing written\n";
  } catch (const fs::filesystem_error& e) {
    noticed();
    err << "error: " << e.what() << "\nces-export: nothing written\n";
  } catch (const std::exception& e) {
    noticed();
    err << "internal error: " << e.what() << "\n";
    return kExitInternal;
  }
  return kExitBadInput;
}

}  // namespace ces::exporter
