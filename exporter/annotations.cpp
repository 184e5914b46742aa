#include "annotations.hpp"

#include <fnmatch.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <sstream>

#include "scene/diagnostics.hpp"
#include "scene/schema.hpp"
#include "scene/units.hpp"

namespace ces::exporter {
namespace {

using scene::Diagnostics;
using scene::Entry;
using scene::Node;

const std::vector<std::string> kExporterKeys = {"units", "tessellation", "frame", "fit_tolerance",
                                                "parts"};

const std::map<std::string, Role> kRoles = {{"drum", Role::Drum},
                                            {"brush", Role::Brush},
                                            {"wall", Role::Wall},
                                            {"hopper", Role::Hopper},
                                            {"splitter", Role::Splitter},
                                            {"electrode", Role::Electrode},
                                            {"feed_outlet", Role::FeedOutlet},
                                            {"collector_plane", Role::CollectorPlane},
                                            {"ignore", Role::Ignore}};

// "a drum", "an electrode": the role as messages name it.
std::string a_role(const std::string& name) {
  return (name.find_first_of("aeiou") == 0 ? "an " : "a ") + name;
}

// The keys a part entry may have, by role.
std::vector<std::string> part_keys(Role role) {
  std::vector<std::string> keys = {"role", "name"};
  const auto add = [&](std::initializer_list<const char*> more) {
    keys.insert(keys.end(), more.begin(), more.end());
  };
  if (is_body_role(role)) {
    add({"material"});
    keys.insert(keys.end(), material_keys().begin(), material_keys().end());
  }
  switch (role) {
    case Role::Drum:
    case Role::Brush:
      add({"speed", "rpm", "rotation_axis", "shape", "thickness", "joint"});
      break;
    case Role::Splitter:
      add({"shape", "joint"});
      break;
    case Role::Electrode:
      add({"voltage", "type", "mobility", "air_density", "material"});
      break;
    case Role::FeedOutlet:
      add({"normal", "feed"});
      break;
    case Role::CollectorPlane:
      add({"normal", "collector"});
      break;
    default:
      break;
  }
  return keys;
}

std::vector<std::string> joint_keys(Role role) {
  if (role == Role::Splitter) return {"axis", "position", "max_speed", "max_force", "mass"};
  return {"mass", "max_force"};
}

std::vector<std::string> scene_keys() {
  std::vector<std::string> keys;
  for (const auto& [key, value] : scene::schema().at("properties").items()) keys.push_back(key);
  return keys;
}

std::vector<std::string> role_names() {
  std::vector<std::string> names;
  for (const auto& [name, role] : kRoles) names.push_back(name);
  return names;
}

// Reports keys of `map` not in `allowed`, with a suggestion.
void check_keys(const Node& map, const std::vector<std::string>& allowed, const std::string& what,
                Diagnostics& diags) {
  for (const Entry& e : map.entries)
    if (std::find(allowed.begin(), allowed.end(), e.key) == allowed.end())
      diags.error(e.key_mark, e.value.path,
                  "unknown key '" + e.key + "' for " + what + scene::did_you_mean(e.key, allowed) +
                      ", expected " + scene::one_of(allowed));
}

bool expect_map(const Node& n, const std::string& what, Diagnostics& diags) {
  if (n.is_map()) return true;
  diags.error(n, "got " + scene::describe(n) + ", expected " + what);
  return false;
}

// A quantity of the given kind ("length"), in SI.
std::optional<double> quantity(const Node& n, std::string_view kind, Diagnostics& diags) {
  const scene::units::Kind* k = scene::units::find_kind(kind);
  if (n.is_number()) return n.number();
  if (n.is_string()) {
    const auto q = scene::units::parse(n.string());
    if (const auto* ok = std::get_if<scene::units::Quantity>(&q);
        ok && ok->dimension == k->dimension)
      return ok->value;
  }
  diags.error(n, "got " + scene::describe(n) + ", expected " + std::string(k->label) +
                     " such as '" + std::string(k->example) + "'");
  return std::nullopt;
}

// Quantities the exporter passes on where a bare SI number is a likely
// slip: "voltage: -30" meant as kV is 30 V, "speed: 44.8" meant as rpm is
// 428 rpm, "mobility: 2.1" meant as cm^2/V/s is 10 000 times too much. They
// need their unit.
std::optional<double> with_unit(const Node& n, std::string_view kind, Diagnostics& diags) {
  if (!n.is_number()) return quantity(n, kind, diags);
  const scene::units::Kind* k = scene::units::find_kind(kind);
  const std::string si(k->si);
  diags.error(n, "got " + scene::describe(n) + ", a number without a unit, expected " +
                     std::string(k->label) + " with its unit such as '" + std::string(k->example) +
                     "' ('" + n.text + " " + si + "' if " + si + " are meant)");
  return std::nullopt;
}

void check_with_unit(const Node& n, std::string_view kind, Diagnostics& diags) {
  (void)with_unit(n, kind, diags);
}

std::optional<Vec3> direction(const Node& n, Diagnostics& diags) {
  const bool ok =
      n.is_sequence() && n.items.size() == 3 &&
      std::all_of(n.items.begin(), n.items.end(), [](const Node& i) { return i.is_number(); }) &&
      std::any_of(n.items.begin(), n.items.end(), [](const Node& i) { return i.number() != 0.0; });
  if (ok) return Vec3(n.items[0].number(), n.items[1].number(), n.items[2].number()).normalized();
  diags.error(n, "got " + scene::describe(n) + ", expected a non-zero vector [x, y, z]");
  return std::nullopt;
}

void check_direction(const Node& n, Diagnostics& diags) { (void)direction(n, diags); }

std::optional<Vec3> position(const Node& n, Diagnostics& diags) {
  if (!n.is_sequence() || n.items.size() != 3) {
    diags.error(n, "got " + scene::describe(n) + ", expected a point [x, y, z]");
    return std::nullopt;
  }
  Vec3 p;
  for (int k = 0; k < 3; ++k) {
    const auto v = quantity(n.items[std::size_t(k)], "length", diags);
    if (!v) return std::nullopt;
    p[k] = *v;
  }
  return p;
}

void check_enum(const Node& n, const std::vector<std::string>& values, Diagnostics& diags) {
  if (n.is_string() && std::find(values.begin(), values.end(), n.string()) != values.end()) return;
  diags.error(n, "got " + scene::describe(n) + ", expected " + scene::one_of(values));
}

void check_number(const Node& n, Diagnostics& diags) {
  if (!n.is_number() || n.number() < 0.0)
    diags.error(n, "got " + scene::describe(n) + ", expected a number >= 0");
}

// A body's material: a materials entry, or keys of its own (friction at
// least) that make a material of the part's name.
void check_material(const Node& spec, Role role, Diagnostics& diags) {
  const auto own = std::find_if(material_keys().begin(), material_keys().end(),
                                [&](const std::string& k) { return spec.find(k) != nullptr; });
  if (spec.find("material") && own != material_keys().end())
    diags.error(*spec.find(*own), "both material and " + *own +
                                      " given, expected a material (a materials entry), or "
                                      "material keys for a material of this part alone");
  else if (!spec.find("material") && !spec.find("friction"))
    diags.error(spec, a_role(role_name(role)) +
                          " needs a material (a materials entry) or a friction coefficient");
}

// A corona wire's keys: the mobility of its ions and the relative density
// of the air, each checked where a slip is still at its line.
void check_corona_keys(const Node& spec, Diagnostics& diags) {
  if (const Node* n = spec.find("mobility")) {
    const auto v = with_unit(*n, "mobility", diags);
    if (v && *v <= 0.0)
      diags.error(*n, "got " + scene::describe(*n) +
                          ", expected a positive ion mobility such as '2.1 cm^2/V/s'");
  }
  if (const Node* n = spec.find("air_density"); n && !(n->is_number() && n->number() > 0.0))
    diags.error(*n, "got " + scene::describe(*n) +
                        ", expected a relative air density > 0 such as 1 (1 at 20 degC and 1 atm)");
}

// An electrode: its voltage, its type, and the corona keys, which only a
// corona wire takes.
void check_electrode(const Node& spec, Diagnostics& diags) {
  if (!spec.find("voltage"))
    diags.error(spec, "an electrode needs a voltage, such as voltage: -35 kV");
  const Node* type = spec.find("type");
  if (type) check_enum(*type, {"static", "corona"}, diags);
  check_corona_keys(spec, diags);
  if (type && !(type->is_string() && type->string() == "static")) return;
  const std::string is = type ? "type: static" : "static (the default type)";
  for (const char* key : {"mobility", "air_density"})
    if (const Node* n = spec.find(key))
      diags.error(*n, std::string(key) + " is a corona wire's, but this electrode is " + is +
                          ", expected type: corona with it");
}

// The values the exporter reads itself; the rest goes into the scene, whose
// schema checks it there.
void check_part_values(const Node& spec, Role role, Diagnostics& diags) {
  for (const char* key : {"rotation_axis", "normal"})
    if (const Node* n = spec.find(key)) check_direction(*n, diags);
  for (const char* key : {"rpm", "friction", "restitution"})
    if (const Node* n = spec.find(key)) check_number(*n, diags);
  if (const Node* n = spec.find("voltage")) check_with_unit(*n, "voltage", diags);
  if (const Node* n = spec.find("speed")) check_with_unit(*n, "angular_speed", diags);
  for (const char* key : {"feed", "collector"})
    if (const Node* n = spec.find(key)) expect_map(*n, "a mapping of scene keys", diags);
  if (const Node* n = spec.find("shape"))
    check_enum(*n,
               role == Role::Splitter ? std::vector<std::string>{"box", "mesh"}
                                      : std::vector<std::string>{"cylinder", "mesh"},
               diags);
  if (const Node* n = spec.find("name"); n && !(n->is_string() && !n->string().empty()))
    diags.error(*n, "got " + scene::describe(*n) + ", expected a body name");
  if (spec.find("speed") && spec.find("rpm"))
    diags.error(*spec.find("rpm"), "both speed and rpm given, expected one of them");
  if (role == Role::Electrode) check_electrode(spec, diags);
  if (is_body_role(role)) check_material(spec, role, diags);
  if (const Node* j = spec.find("joint");
      j && expect_map(*j, "a mapping of joint settings", diags)) {
    check_keys(*j, joint_keys(role), "the joint of " + a_role(role_name(role)), diags);
    if (const Node* axis = j->find("axis")) check_direction(*axis, diags);
  }
}

std::optional<Rule> read_rule(const Entry& e, Diagnostics& diags) {
  if (!expect_map(e.value, "a mapping with a role", diags)) return std::nullopt;
  const Node* role = e.value.find("role");
  if (!role) {
    diags.error(e.key_mark, e.value.path,
                "missing role, expected one of " + scene::one_of(role_names()));
    return std::nullopt;
  }
  const auto it = role->is_string() ? kRoles.find(role->string()) : kRoles.end();
  if (it == kRoles.end()) {
    const std::string word = role->is_string() ? role->string() : role->text;
    diags.error(*role, "unknown role " + scene::describe(*role) +
                           scene::did_you_mean(word, role_names()) + ", expected " +
                           scene::one_of(role_names()));
    return std::nullopt;
  }
  check_keys(e.value, part_keys(it->second), a_role(it->first), diags);
  check_part_values(e.value, it->second, diags);
  const bool glob = e.key.find_first_of("*?[") != std::string::npos;
  return Rule{e.key, glob, it->second, &e.value, e.key_mark};
}

void read_units(Annotations& a, const Node& n, Diagnostics& diags) {
  const std::vector<std::string> names = {"mm", "cm", "m", "in"};
  if (n.is_string() && std::find(names.begin(), names.end(), n.string()) != names.end()) {
    a.unit = unit_scale(n.string());
    a.unit_name = n.string();
  } else {
    diags.error(n, "got " + scene::describe(n) + ", expected mm, cm, m or in");
  }
}

void read_tessellation(Annotations& a, const Node& n, Diagnostics& diags) {
  if (!expect_map(n, "a mapping with deflection and angle", diags)) return;
  check_keys(n, {"deflection", "angle"}, "tessellation", diags);
  if (const Node* d = n.find("deflection"))
    if (const auto v = quantity(*d, "length", diags); v && *v > 0.0) a.deflection = *v;
  if (const Node* d = n.find("angle"))
    if (const auto v = quantity(*d, "angle", diags); v && *v > 0.0) a.angle = *v;
}

void read_frame(Annotations& a, const Node& n, Diagnostics& diags) {
  if (!expect_map(n, "a mapping with origin, up and axis", diags)) return;
  check_keys(n, {"origin", "up", "axis"}, "frame", diags);
  a.frame.given = true;
  a.frame.mark = n.mark;
  if (const Node* o = n.find("origin")) {
    if (o->is_string() && o->string() == "drum")
      a.frame.origin_at_drum = true;
    else if (o->is_sequence())
      a.frame.origin = position(*o, diags).value_or(Vec3::Zero());
    else
      diags.error(*o, "got " + scene::describe(*o) + ", expected drum or a point [x, y, z]");
  }
  if (const Node* u = n.find("up")) a.frame.up = direction(*u, diags).value_or(Vec3::UnitY());
  if (const Node* x = n.find("axis")) a.frame.axis = direction(*x, diags);
}

void read_includes(Annotations& a, const Node& n, Diagnostics& diags) {
  const auto add = [&](const Node& item) {
    if (item.is_string())
      a.includes.push_back(&item);
    else
      diags.error(item, "got " + scene::describe(item) + ", expected a file name");
  };
  if (!n.is_sequence()) return add(n);
  for (const Node& item : n.items) add(item);
}

void read_top(Annotations& a, const Entry& e, Diagnostics& diags) {
  const Node& v = e.value;
  if (e.key == "units") {
    read_units(a, v, diags);
  } else if (e.key == "tessellation") {
    read_tessellation(a, v, diags);
  } else if (e.key == "frame") {
    read_frame(a, v, diags);
  } else if (e.key == "fit_tolerance") {
    if (v.is_number() && v.number() > 0.0 && v.number() < 1.0)
      a.fit_tolerance = v.number();
    else
      diags.error(
          v, "got " + scene::describe(v) + ", expected a fraction of the radius such as 0.005");
  } else if (e.key == "parts") {
    if (!expect_map(v, "a mapping from part names or globs to roles", diags)) return;
    for (const Entry& p : v.entries)
      if (auto r = read_rule(p, diags)) a.rules.push_back(*r);
  } else if (e.key == "include") {
    read_includes(a, v, diags);
  } else {
    a.scene_entries.push_back(&e);
  }
}

std::optional<Node> parse_file(const std::string& path, Diagnostics& diags) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    diags.error({path, 0, 0}, "", "cannot read the annotations: no such file or not readable");
    return std::nullopt;
  }
  std::ostringstream text;
  text << in.rdbuf();
  scene::Budget budget;
  auto root = scene::parse(text.str(), path, false, budget, diags);
  if (root && !root->is_map()) {
    diags.error({path, 1, 1}, "",
                "got " + scene::describe(*root) + ", expected a mapping with parts");
    return std::nullopt;
  }
  return root;
}

}  // namespace

const std::vector<std::string>& material_keys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const auto& [key, value] :
         scene::schema().at("definitions").at("material").at("properties").items())
      k.push_back(key);
    return k;
  }();
  return keys;
}

const char* role_name(Role role) {
  for (const auto& [name, r] : kRoles)
    if (r == role) return name.c_str();
  return "?";
}

bool is_body_role(Role role) {
  return role == Role::Drum || role == Role::Brush || role == Role::Wall || role == Role::Hopper ||
         role == Role::Splitter;
}

Annotations read_annotations(const std::string& path) {
  Diagnostics diags;
  auto root = parse_file(path, diags);
  if (!root) diags.raise();
  scene::assign_paths(*root);
  Annotations a;
  a.path = path;
  a.root = std::make_shared<const Node>(std::move(*root));
  std::vector<std::string> allowed = kExporterKeys;
  for (const std::string& k : scene_keys()) allowed.push_back(k);
  check_keys(*a.root, allowed, "annotations (exporter settings or scene keys)", diags);
  for (const Entry& e : a.root->entries)
    if (std::find(allowed.begin(), allowed.end(), e.key) != allowed.end()) read_top(a, e, diags);
  if (!a.root->find("parts"))
    diags.error({path, 1, 1}, "", "missing parts, expected a mapping from part names to roles");
  if (!diags.empty()) diags.raise();
  return a;
}

std::string where(const scene::Mark& m) {
  return m.file + ":" + std::to_string(m.line) + ":" + std::to_string(m.column) + ": ";
}

bool matches(const Rule& rule, const Part& part) {
  const auto match = [&](const std::string& name) {
    if (name.empty()) return false;
    return rule.glob ? fnmatch(rule.pattern.c_str(), name.c_str(), 0) == 0 : rule.pattern == name;
  };
  return match(part.name) || match(part.instance);
}

const Rule* rule_for(const Annotations& a, const Part& part) {
  const Rule* found = nullptr;
  for (const Rule& r : a.rules)
    if (matches(r, part) && (!found || (found->glob && !r.glob))) found = &r;
  return found;
}

}  // namespace ces::exporter
