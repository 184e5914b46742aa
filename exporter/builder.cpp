#include "builder.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "format.hpp"
#include "scene/resolve.hpp"
#include "scene/schema.hpp"

namespace ces::exporter {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;
using scene::Entry;
using scene::Mark;
using scene::Node;

constexpr int kDefaultBins = 50;

// 12 significant digits, and 0 below 1e-12: CAD coordinates pass through
// unit conversions and frames, and 0.21299999999999997 or 1e-17 would read
// as real offsets. 12 digits keep 1e-12 relative, far below any tolerance,
// and give back the decimal the CAD was drawn with (0.213 m from 213 mm).
double tidy(double v) {
  if (std::abs(v) < 1e-12) return 0.0;
  char s[32];
  std::snprintf(s, sizeof s, "%.12g", v);
  return std::strtod(s, nullptr);
}
double micrometres(double v) { return tidy(std::round(v * 1e6) / 1e6); }
json vec(const Vec3& v) { return json::array({tidy(v.x()), tidy(v.y()), tidy(v.z())}); }
std::string degrees(double radians) { return json(tidy(radians * 180.0 / kPi)).dump() + " deg"; }

Node make(Node::Kind kind, const Mark& m) {
  Node n;
  n.kind = kind;
  n.mark = m;
  return n;
}

void put(Node& map, const std::string& key, Node value) {
  const Mark m = value.mark;
  map.entries.push_back({key, m, std::move(value)});
}

void put(Node& map, const std::string& key, const json& value, const Mark& m) {
  put(map, key, scene::from_json(value, m));
}

void put_copy(Node& map, const std::string& key, const Node* value) {
  if (value) put(map, key, *value);
}

// The include rule of scenes: maps merge key by key, lists join (`into`'s
// items first), any other value of `from` wins.
void merge(Node& into, const Node& from) {
  if (into.is_map() && from.is_map()) {
    for (const Entry& e : from.entries) {
      Node* same = into.find(e.key);
      if (same)
        merge(*same, e.value);
      else
        into.entries.push_back(e);
    }
  } else if (into.is_sequence() && from.is_sequence()) {
    into.items.insert(into.items.end(), from.items.begin(), from.items.end());
  } else {
    into = from;
  }
}

// The absolute folder of a file ("" is the working directory).
fs::path folder_of(const fs::path& file) {
  const fs::path parent = file.parent_path();
  return fs::absolute(parent.empty() ? fs::path(".") : parent).lexically_normal();
}

Vec3 read_direction(const Node& n) {
  return Vec3(n.items[0].number(), n.items[1].number(), n.items[2].number()).normalized();
}

// The axis a direction lies along (x, y or z), or -1.
int axis_index(const Vec3& n) {
  for (int k = 0; k < 3; ++k)
    if (std::abs(n[k]) > 1.0 - 1e-9) return k;
  return -1;
}

class Builder {
 public:
  Builder(const Machine& m, const Annotations& a, const SceneSetup& s, std::vector<std::string>& w)
      : m_(m), a_(a), setup_(s), warnings_(w), root_mark_{a.path, 1, 1} {}

  Node build() {
    root_ = make(Node::Kind::Map, root_mark_);
    put(root_, "ces_sim", 1, root_mark_);
    put(root_, "name", setup_.name, root_mark_);
    add_includes();
    for (const Placed& p : m_.parts) add(p);
    add_electrostatics();
    add_gravity();
    add_domain();
    merge(root_, user_keys());
    order_keys();
    return root_;
  }

 private:
  // ------------------------------------------------------------ root

  bool user_has(const std::string& key) const {
    return a_.root->find(key) || setup_.included_keys.count(key);
  }

  Node& section(const std::string& key, Node::Kind kind) {
    if (Node* n = root_.find(key)) return *n;
    put(root_, key, make(kind, root_mark_));
    return root_.entries.back().value;
  }

  // The annotations' scene keys, their paths made relative to the scene.
  Node user_keys() const {
    Node user = make(Node::Kind::Map, root_mark_);
    for (const Entry* e : a_.scene_entries) user.entries.push_back(*e);
    scene::rebase_paths(user, setup_.scene_path.string());
    return user;
  }

  void add_includes() {
    if (a_.includes.empty()) return;
    const fs::path from = folder_of(a_.path);
    const fs::path scene_dir = folder_of(setup_.scene_path);
    Node list = make(Node::Kind::Sequence, a_.includes.front()->mark);
    for (const Node* inc : a_.includes) {
      Node item = *inc;
      item.scalar = item.text =
          (from / inc->string()).lexically_normal().lexically_relative(scene_dir).generic_string();
      list.items.push_back(std::move(item));
    }
    put(root_, "include", std::move(list));
  }

  // The schema's order: version, include, name, time, solver, ... bodies,
  // feeds, collectors, domain, output.
  void order_keys() {
    std::vector<std::string> order;
    for (const auto& [key, value] : scene::schema().at("properties").items()) order.push_back(key);
    const auto rank = [&](const Entry& e) {
      return std::find(order.begin(), order.end(), e.key) - order.begin();
    };
    std::stable_sort(root_.entries.begin(), root_.entries.end(),
                     [&](const Entry& x, const Entry& y) { return rank(x) < rank(y); });
  }

  void add(const Placed& p) {
    switch (p.output) {
      case Output::Electrode:
        add_electrode(p);
        break;
      case Output::Feed:
        add_feed(p);
        break;
      case Output::Collector:
        add_collector(p);
        break;
      default:
        add_body(p);
        break;
    }
  }

  // ------------------------------------------------------------ bodies

  void add_body(const Placed& p) {
    const Mark& m = p.rule->mark;
    Node body = make(Node::Kind::Map, m);
    put(body, "name", p.name, m);
    put(body, "geometry", geometry(p));
    if (const auto pose = pose_of(p)) put(body, "pose", *pose);
    put(body, "material", material(p));
    if (p.rule->role == Role::Drum || p.rule->role == Role::Brush) add_rotation(p, body);
    if (p.rule->role == Role::Splitter && p.rule->spec->find("joint")) add_slide(p, body);
    section("bodies", Node::Kind::Sequence).items.push_back(std::move(body));
  }

  Node geometry(const Placed& p) const {
    const Mark& m = p.rule->mark;
    Node g = make(Node::Kind::Map, m);
    if (p.output == Output::Box) {
      put(g, "box", json{{"size", vec(p.box->size)}}, m);
    } else if (p.cylinder) {
      Node c = scene::from_json(
          json{{"radius", tidy(p.cylinder->radius)}, {"length", tidy(p.cylinder->length)}}, m);
      put_copy(c, "thickness", p.rule->spec->find("thickness"));
      put(g, "cylinder", std::move(c));
    } else {
      put(g, "mesh", json{{"file", p.mesh_file}}, m);
    }
    return g;
  }

  std::optional<Node> pose_of(const Placed& p) const {
    const Mark& m = p.rule->mark;
    if (p.output == Output::Box) {
      json pose{{"position", vec(p.box->center)}};
      const Eigen::AngleAxisd r(p.box->frame);
      if (r.angle() > 1e-12)
        pose["rotation"] = {{"axis", vec(r.axis())}, {"angle", degrees(r.angle())}};
      return scene::from_json(pose, m);
    }
    if (p.cylinder)
      return scene::from_json(
          json{{"position", vec(p.cylinder->center)}, {"axis", vec(p.cylinder->axis)}}, m);
    return std::nullopt;
  }

  // The named material, or one made for this part from its material keys.
  Node material(const Placed& p) {
    const Node& spec = *p.rule->spec;
    if (const Node* m = spec.find("material")) return *m;
    const Node* user = a_.root->find("materials");
    if (user && user->find(p.name))
      throw InputError(where(p.rule->mark) + "the material made for " + label(p) +
                       " from its material keys would be called '" + p.name +
                       "', but materials has one of that name; expected a material: reference");
    Node made = make(Node::Kind::Map, p.rule->mark);
    for (const std::string& key : material_keys()) put_copy(made, key, spec.find(key));
    put(section("materials", Node::Kind::Map), p.name, std::move(made));
    return scene::from_json(p.name, p.rule->mark);
  }

  // ------------------------------------------------------------ motion

  // The turning axis: the cylinder's, signed by rotation_axis.
  Vec3 spin_axis(const Placed& p) {
    const Node* given = p.rule->spec->find("rotation_axis");
    const std::optional<Vec3> dir =
        given ? std::optional<Vec3>(m_.rotation * read_direction(*given)) : std::nullopt;
    if (!p.cylinder) {
      if (!dir)
        throw InputError(where(p.rule->mark) + label(p) +
                         " is kept as a mesh, so its turning axis must be "
                         "given: expected rotation_axis");
      return *dir;
    }
    const Vec3& a = p.cylinder->axis;
    if (!dir) {
      warnings_.push_back(label(p) + ": no rotation_axis given, so it turns right-handed about " +
                          vector_text(a) + " (scene frame)");
      return a;
    }
    if (dir->cross(a).norm() > 1e-3)
      throw InputError(where(given->mark) + "rotation_axis " + vector_text(*dir) +
                       " (scene frame) is not along " + label(p) + "'s axis " + vector_text(a) +
                       ", expected a direction along it");
    return dir->dot(a) < 0.0 ? Vec3(-a) : a;
  }

  void add_rotation(const Placed& p, Node& body) {
    const Node& spec = *p.rule->spec;
    const Node* speed = spec.find("speed");
    const Node* rpm = spec.find("rpm");
    if (!speed && !rpm) {
      if (p.rule->role == Role::Drum)
        warnings_.push_back(label(p) + " has no speed, so it stands still");
      return;
    }
    const Node turning = speed ? *speed : scene::from_json(rpm->text + " rpm", rpm->mark);
    const Vec3 axis = spin_axis(p);
    const Vec3 center = p.cylinder ? p.cylinder->center : p.quality.bounds.center();
    const Mark& m = p.rule->mark;
    const Node* joint = spec.find("joint");
    if (!joint) {
      Node rotation = scene::from_json(json{{"axis", vec(axis)}, {"center", vec(center)}}, m);
      put(rotation, "speed", turning);
      Node motion = make(Node::Kind::Map, m);
      put(motion, "rotation", std::move(rotation));
      put(body, "motion", std::move(motion));
      return;
    }
    add_joint(p, body, "revolute", "_hinge", center, axis);
    Node motor =
        scene::from_json(json{{"name", p.name + "_motor"}, {"joint", p.name + "_hinge"}}, m);
    put(motor, "speed", turning);
    put_copy(motor, "max_force", joint->find("max_force"));
    section("motors", Node::Kind::Sequence).items.push_back(std::move(motor));
  }

  // A dynamic body held by a joint to the ground.
  void add_joint(const Placed& p, Node& body, const char* type, const char* suffix,
                 const Vec3& point, const Vec3& axis) {
    const Mark& m = p.rule->mark;
    Node dynamic = make(Node::Kind::Map, m);
    put_copy(dynamic, "mass", p.rule->spec->find("joint")->find("mass"));
    put(body, "dynamic", std::move(dynamic));
    section("joints", Node::Kind::Sequence)
        .items.push_back(scene::from_json(json{{"name", p.name + suffix},
                                               {"type", type},
                                               {"body_b", p.name},
                                               {"point", vec(point)},
                                               {"axis", vec(axis)}},
                                          m));
  }

  // A splitter on a prismatic joint, across its plate unless told otherwise,
  // driven to a position when one is given.
  void add_slide(const Placed& p, Node& body) {
    const Node& joint = *p.rule->spec->find("joint");
    Eigen::Index thin = 0;
    p.box->size.minCoeff(&thin);
    const Node* given = joint.find("axis");
    const Vec3 axis =
        given ? Vec3(m_.rotation * read_direction(*given)) : Vec3(p.box->frame.col(thin));
    add_joint(p, body, "prismatic", "_slide", p.box->center, axis);
    const Node* position = joint.find("position");
    if (!position) return;
    Node motor = scene::from_json(json{{"name", p.name + "_drive"}, {"joint", p.name + "_slide"}},
                                  p.rule->mark);
    put(motor, "position", *position);
    put_copy(motor, "max_speed", joint.find("max_speed"));
    put_copy(motor, "max_force", joint.find("max_force"));
    section("motors", Node::Kind::Sequence).items.push_back(std::move(motor));
  }

  // ------------------------------------------------------------ electrostatics

  // Its entry waits for the drum's frame check (add_electrostatics): an
  // electrode off z is most often a whole machine drawn in another frame.
  void add_electrode(const Placed& p) {
    electrode_parts_.push_back(&p);
    if (p.rule->spec->find("material")) add_body(p);
  }

  Node electrode(const Placed& p, const Placed& drum) const {
    const Cylinder& c = *p.cylinder;
    if (std::abs(c.axis.z()) < 1.0 - 1e-9)
      throw InputError(where(p.rule->mark) + label(p) + " lies along " + vector_text(c.axis) +
                       " (scene frame), across " + label(drum) +
                       ", whose axis is z; expected an electrode parallel to the drum");
    // Polar, as separator drawings give it: the distance from the drum axis
    // and the angle from +x.
    const double angle = std::atan2(c.center.y(), c.center.x());
    const json polar{{"distance", tidy(c.center.head<2>().norm())}, {"angle", degrees(angle)}};
    Node e = scene::from_json(json{{"name", p.name}, {"polar", polar}, {"radius", tidy(c.radius)}},
                              p.rule->mark);
    put(e, "voltage", *p.rule->spec->find("voltage"));
    for (const char* key : {"type", "mobility", "air_density"})
      put_copy(e, key, p.rule->spec->find(key));
    return e;
  }

  const Placed* first(Role role) const {
    for (const Placed& p : m_.parts)
      if (p.rule->role == role) return &p;
    return nullptr;
  }

  // The frame that puts a drum lying along `axis` (a CAD direction) on z
  // with y up: the annotations' up, else z (y for a drum along z), the up
  // of most CAD.
  std::string frame_hint(const Vec3& axis) const {
    const Vec3 up = a_.frame.given             ? a_.frame.up
                    : std::abs(axis.z()) < 0.5 ? Vec3(Vec3::UnitZ())
                                               : Vec3(Vec3::UnitY());
    return "frame: {origin: drum, up: " + vector_text(up) +
           "} in the annotations (up: the CAD direction that points up; the drum's axis "
           "becomes z)";
  }

  // The field models' frame: the drum's axis is z through the origin.
  void check_drum_frame(const Placed* drum) const {
    if (!drum)
      throw InputError("the machine has electrodes but no drum, expected a part with role drum");
    if (drum->output != Output::Cylinder)
      throw InputError(where(drum->rule->mark) + label(*drum) +
                       " is not a cylinder, but the field models need a cylindrical drum; "
                       "expected a drum the exporter recovers as a cylinder (see the warning)");
    const Cylinder& c = *drum->cylinder;
    if (c.center.norm() < 1e-9 && std::abs(c.axis.z()) > 1.0 - 1e-9) return;
    const Vec3 cad_axis = m_.rotation.transpose() * c.axis;
    throw InputError(where(drum->rule->mark) + label(*drum) + " is centred at " +
                     vector_text(c.center) + " along " + vector_text(c.axis) +
                     " (scene frame), but the field models need the drum's axis on z through "
                     "the origin; expected " +
                     frame_hint(cad_axis));
  }

  void add_electrostatics() {
    // Without electrode parts, the annotations' own electrostatics (or an
    // include's) may name a drum this export does not make.
    const Node* user = a_.root->find("electrostatics");
    if (electrode_parts_.empty() && (!user || user->find("drum"))) return;
    const Placed* drum = first(Role::Drum);
    check_drum_frame(drum);
    Node es = make(Node::Kind::Map, drum->rule->mark);
    put(es, "drum", drum->name, drum->rule->mark);
    if (const Placed* brush = first(Role::Brush)) put(es, "brush", brush->name, brush->rule->mark);
    if (!electrode_parts_.empty()) {
      Node list = make(Node::Kind::Sequence, electrode_parts_.front()->rule->mark);
      for (const Placed* p : electrode_parts_) list.items.push_back(electrode(*p, *drum));
      put(es, "electrodes", std::move(list));
    }
    put(root_, "electrostatics", std::move(es));
  }

  // ------------------------------------------------------------ feeds, collectors

  // The part's normal axis and sign: `normal` (along x, y or z of the
  // scene), else the part's thinnest extent, pointing `y_sign` along y.
  std::pair<int, double> facing(const Placed& p, double y_sign) const {
    if (const Node* given = p.rule->spec->find("normal")) {
      const Vec3 n = m_.rotation * read_direction(*given);
      const int k = axis_index(n);
      if (k < 0)
        throw InputError(where(given->mark) + "normal " + vector_text(n) +
                         " (scene frame) is oblique, expected one along x, y or z");
      return {k, n[k] > 0.0 ? 1.0 : -1.0};
    }
    Eigen::Index k = 0;
    p.quality.bounds.size().minCoeff(&k);
    return {int(k), k == 1 ? y_sign : 1.0};
  }

  void add_feed(const Placed& p) {
    const auto [k, sign] = facing(p, -1.0);
    const Bounds& b = p.quality.bounds;
    const int u = k == 0 ? 1 : 0;
    const int v = k == 2 ? 1 : 2;
    Vec3 normal = Vec3::Zero();
    normal[k] = sign;
    const json outlet{{"center", vec(b.center())},
                      {"size", json::array({tidy(b.size()[u]), tidy(b.size()[v])})},
                      {"normal", vec(normal)}};
    Node feed =
        scene::from_json(json{{"name", p.name}, {"region", {{"outlet", outlet}}}}, p.rule->mark);
    if (const Node* more = p.rule->spec->find("feed")) merge(feed, *more);
    section("feeds", Node::Kind::Sequence).items.push_back(std::move(feed));
  }

  // Bins default to the plate's longer side, their ends on a micrometre
  // grid: from STL the plate's ends carry float noise (1e-8 m), and products
  // given up to the ends would leave bins that end a hair short of them.
  void add_collector(const Placed& p) {
    const auto [k, sign] = facing(p, 1.0);
    const Bounds& b = p.quality.bounds;
    Vec3 normal = Vec3::Zero(), along = Vec3::Zero();
    normal[k] = sign;
    const int u = k == 0 ? 1 : 0;
    const int v = k == 2 ? 1 : 2;
    const int j = b.size()[u] >= b.size()[v] ? u : v;
    along[j] = 1.0;
    const json collector{{"name", p.name},
                         {"plane", {{"point", vec(b.center())}, {"normal", vec(normal)}}},
                         {"bins",
                          {{"axis", vec(along)},
                           {"from", micrometres(b.min[j])},
                           {"to", micrometres(b.max[j])},
                           {"count", kDefaultBins}}}};
    Node c = scene::from_json(collector, p.rule->mark);
    if (const Node* more = p.rule->spec->find("collector")) merge(c, *more);
    section("collectors", Node::Kind::Sequence).items.push_back(std::move(c));
  }

  // Without gravity a feed hangs where it appears. It acts along -y of the
  // scene, which `frame: up` makes the CAD's down.
  void add_gravity() {
    if (user_has("gravity")) return;
    put(root_, "gravity", json::array({0, kGravity, 0}), root_mark_);
  }

  void add_domain() {
    if (user_has("domain")) return;
    const Bounds d = default_domain(m_);
    put(root_, "domain", json{{"box", {{"min", vec(d.min)}, {"max", vec(d.max)}}}}, root_mark_);
  }

  const Machine& m_;
  const Annotations& a_;
  const SceneSetup& setup_;
  std::vector<std::string>& warnings_;
  const Mark root_mark_;
  Node root_;
  std::vector<const Placed*> electrode_parts_;
};

}  // namespace

Bounds default_domain(const Machine& machine) {
  Bounds all;
  for (const Placed& p : machine.parts) all.add(p.quality.bounds);
  const Vec3 margin = Vec3::Constant(0.1 * all.size().maxCoeff());
  all.min -= margin;
  all.max += margin;
  return all;
}

scene::Node build_scene(const Machine& machine, const Annotations& annotations,
                        const SceneSetup& setup, std::vector<std::string>& warnings) {
  return Builder(machine, annotations, setup, warnings).build();
}

}  // namespace ces::exporter
