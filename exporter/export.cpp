#include "export.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "annotations.hpp"
#include "builder.hpp"
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

Cad read_cad(const std::string& input, const Annotations& a) {
  if (is_step(input)) {
    std::string declared;
    auto parts = read_step(input, {a.deflection, a.angle, a.unit}, declared);
    if (a.unit)
      return {
          std::move(parts),
          {*a.unit, a.unit_name + " (units in the annotations; the file says " + declared + ")"}};
    return {std::move(parts),
            {unit_scale(declared).value_or(1.0), declared + " (the STEP file's unit)"}};
  }
  const double scale = a.unit.value_or(1e-3);
  return {read_mesh_files(input, scale),
          {scale,
           a.unit ? a.unit_name + " (units in the annotations)" : "mm (the default for STL/OBJ)"}};
}

// The top-level keys the annotations' includes define (they decide, for
// example, whether the exporter makes a domain).
std::set<std::string> included_keys(const Annotations& a) {
  std::set<std::string> keys;
  scene::Diagnostics diags;
  scene::Budget budget;
  for (const Node* inc : a.includes) {
    const fs::path p = fs::path(a.path).parent_path() / inc->string();
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) {
      diags.error(inc->mark, "include", "cannot read '" + p.string() + "': no such file");
      continue;
    }
    if (const auto tree = scene::load_tree(p.string(), {}, budget, diags))
      for (const scene::Entry& e : tree->entries) keys.insert(e.key);
  }
  if (!diags.empty()) diags.raise();
  return keys;
}

// The folders of the annotations' includes: the scene includes them where
// they are, so ces-sim must be told it may read them (--include-path).
std::vector<std::string> include_folders(const Annotations& a, std::vector<std::string>& warnings) {
  std::set<std::string> folders;
  for (const Node* inc : a.includes) {
    std::error_code ec;
    const fs::path p = fs::absolute(fs::path(a.path).parent_path() / inc->string(), ec);
    folders.insert(fs::weakly_canonical(p, ec).parent_path().string());
  }
  for (const std::string& f : folders)
    warnings.push_back("the scene includes fragments from " + f + ": run it with --include-path " +
                       f);
  return {folders.begin(), folders.end()};
}

// ------------------------------------------------------------------ the folder

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
  if (!fs::is_empty(out, ec) && !fs::exists(out / "export_report.json", ec))
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

void publish(const fs::path& temp, const fs::path& out) {
  std::error_code ec;
  if (!fs::exists(out, ec)) return fs::rename(temp, out);
  const fs::path old = sibling(out, "old");
  fs::rename(out, old);
  fs::rename(temp, out);
  fs::remove_all(old);
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

json vec_json(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

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
  if (p.box) j["box"] = {{"center", vec_json(p.box->center)}, {"size", vec_json(p.box->size)}};
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

std::string summary(const Placed& p) {
  if (p.cylinder) {
    std::string s = "radius " + metres(p.cylinder->radius) + ", length " +
                    metres(p.cylinder->length) + ", axis " + vector_text(p.cylinder->axis) +
                    ", centre " + vector_text(p.cylinder->center);
    if (p.cylinder_source == "step") return s + " (exact STEP surface)";
    return s + " (fitted, RMS " + metres(p.fit->rms) + " = " +
           percent(p.fit->rms / p.fit->cylinder.radius) + " of the radius)";
  }
  if (p.box) return "size " + vector_text(p.box->size) + ", centre " + vector_text(p.box->center);
  if (!p.mesh_file.empty()) return p.mesh_file;
  return "from " + vector_text(p.quality.bounds.min) + " to " + vector_text(p.quality.bounds.max);
}

void print_report(std::ostream& out, const ExportOptions& o, const UnitChoice& units,
                  const Machine& m) {
  out << "ces-export: " << o.input << " -> " << (fs::path(o.output) / "scene.yaml").string() << "\n"
      << "CAD read in " << units.how << "\n\n";
  char line[512];
  for (const Placed& p : m.parts) {
    std::snprintf(line, sizeof line, "  %-16s %-15s %-15s ", p.name.c_str(),
                  role_name(p.rule->role), output_name(p.output));
    out << line << summary(p) << "\n";
  }
  out << "\nmesh quality (after welding, removing degenerate triangles and orienting):\n";
  std::snprintf(line, sizeof line, "  %-16s %9s %8s %6s %12s %10s %7s %7s  %s\n", "part",
                "triangles", "vertices", "open", "non-manifold", "degenerate", "flipped", "closed",
                "bounding box (m)");
  out << line;
  for (const Placed& p : m.parts) {
    const MeshQuality& q = p.quality;
    const std::string closed = std::to_string(q.closed_pieces) + "/" + std::to_string(q.pieces);
    std::snprintf(line, sizeof line, "  %-16s %9zu %8zu %6zu %12zu %10zu %7zu %7s  ",
                  p.name.c_str(), q.triangles, q.vertices, q.open_edges, q.non_manifold_edges,
                  q.degenerate_triangles, q.flipped_triangles, closed.c_str());
    out << line << vector_text(q.bounds.min) << " .. " << vector_text(q.bounds.max) << "\n";
  }
}

// ------------------------------------------------------------------ pipeline

std::string scene_header(const ExportOptions& o) {
  return "# Made by ces-export from " + o.input + " with " + o.annotations +
         ".\n# Lengths in metres. Edit the annotations and export again rather than this file.\n";
}

void export_all(const ExportOptions& o, std::ostream& out, std::ostream& err) {
  const Annotations a = read_annotations(o.annotations);
  const fs::path folder = output_folder(o.output);
  check_output(folder);
  Cad cad = read_cad(o.input, a);
  const UnitChoice units = cad.units;
  const Machine m = assemble(std::move(cad.parts), a, units);
  std::vector<std::string> warnings = m.warnings;
  const SceneSetup setup{fs::path(o.input).stem().string(), folder / "scene.yaml",
                         included_keys(a)};
  const Node root = build_scene(m, a, setup, warnings);
  scene::LoadOptions check;
  check.include_paths = include_folders(a, warnings);
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
  write_text(temp.path() / "export_report.json", report_json(o, units, m, warnings).dump(2) + "\n");
  try {
    (void)scene::load(written, check);
  } catch (const scene::SceneError& e) {
    throw scene::SceneError(map_back(e.diagnostics(), written, text, root));
  }
  publish(temp.path(), folder);
  for (const std::string& w : warnings) err << "warning: " << w << "\n";
  if (!o.quiet) print_report(out, o, units, m);
}

}  // namespace

int run_export(const ExportOptions& options, std::ostream& out, std::ostream& err) {
  try {
    export_all(options, out, err);
    return kExitOk;
  } catch (const scene::SceneError& e) {
    for (const scene::Diagnostic& d : e.diagnostics()) err << d.str() << "\n";
    err << "ces-export: nothing written\n";
  } catch (const InputError& e) {
    err << "error: " << e.what() << "\nces-export: nothing written\n";
  } catch (const fs::filesystem_error& e) {
    err << "error: " << e.what() << "\nces-export: nothing written\n";
  } catch (const std::exception& e) {
    err << "internal error: " << e.what() << "\n";
    return kExitInternal;
  }
  return kExitBadInput;
}

}  // namespace ces::exporter
