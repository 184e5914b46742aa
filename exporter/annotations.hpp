// annotations.yaml: what CAD does not say. Which part is the drum, the
// brush, a splitter...; their parameters; and the rest of the scene
// (materials, feeds, solver, ...) as scene keys or included fragments.
// Every value remembers its file:line:col for messages.
#pragma once
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "parts.hpp"
#include "scene/tree.hpp"

namespace ces::exporter {

enum class Role {
  Drum,
  Brush,
  Wall,
  Hopper,
  Splitter,
  Electrode,
  FeedOutlet,
  CollectorPlane,
  Ignore
};

const char* role_name(Role role);
bool is_body_role(Role role);

// The keys of a scene material (the schema's): a body's own material, made
// from its part's entry, takes any of them.
const std::vector<std::string>& material_keys();

// One entry of `parts:`: a part name or glob and what matching parts are.
struct Rule {
  std::string pattern;
  bool glob = false;
  Role role = Role::Ignore;
  const scene::Node* spec = nullptr;  // the entry's mapping
  scene::Mark mark;                   // of the pattern, for messages
};

// `frame:` moves the CAD into the scene's frame: the field models want the
// drum's axis on z through the origin and gravity along -y.
struct Frame {
  bool given = false;
  bool origin_at_drum = false;
  Vec3 origin = Vec3::Zero();  // m, CAD coordinates (after units)
  Vec3 up = Vec3::UnitY();     // the CAD direction that becomes +y
  std::optional<Vec3> axis;    // the CAD direction that becomes +z (default: the drum's axis)
  scene::Mark mark;
};

struct Annotations {
  std::string path;
  std::shared_ptr<const scene::Node> root;  // owns every Node the rest points to
  std::optional<double> unit;               // metres per CAD unit, when given
  std::string unit_name;
  double deflection = 1e-4;           // m, STEP tessellation
  double angle = 20.0 * kPi / 180.0;  // rad, STEP tessellation
  Frame frame;
  double fit_tolerance = 0.005;  // accepted cylinder-fit RMS, fraction of the radius
  std::vector<Rule> rules;       // in file order
  // Scene keys copied into the scene (include excepted), in file order.
  std::vector<const scene::Entry*> scene_entries;
  std::vector<const scene::Node*> includes;  // file names, relative to `path`
};

// Throws scene::SceneError with every problem (file:line:col: key: message).
Annotations read_annotations(const std::string& path);

// The first rule matching the part's name or instance name: exact names
// before globs, else file order. nullptr when none does.
const Rule* rule_for(const Annotations& a, const Part& part);

// "file:line:col: " of a mark, to start a message with.
std::string where(const scene::Mark& mark);

// Does `rule` match the part's name or instance name?
bool matches(const Rule& rule, const Part& part);

}  // namespace ces::exporter
