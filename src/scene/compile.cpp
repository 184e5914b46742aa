#include "scene/compile.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "feed/shapes.hpp"
#include "fields/electrostatics.hpp"
#include "scene/diagnostics.hpp"
#include "scene/electrostatics.hpp"
#include "scene/limits.hpp"
#include "scene/resolve.hpp"
#include "scene/schema.hpp"

namespace ces::scene {
namespace {

namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();

Vec3 vec3(const Node& n) { return {n.items[0].number(), n.items[1].number(), n.items[2].number()}; }

std::string format(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

std::string metres(double x) { return format(x) + " m"; }

// A count in full ("10000000", not "1e+07") while it is short enough.
std::string whole(double x) {
  if (!(x < 1e15)) return format(x);
  std::ostringstream s;
  s << std::fixed << std::setprecision(0) << x;
  return s.str();
}

// Names declared by one section, for duplicate checks and references.
class NameTable {
 public:
  explicit NameTable(std::string what) : what_(std::move(what)) {}

  // False, with a diagnostic, when the name was declared before.
  bool declare(const std::string& name, const Mark& mark, const std::string& path, int index,
               Diagnostics& diags) {
    const auto [it, inserted] = table_.emplace(name, Declared{index, mark.line});
    if (!inserted)
      diags.error(mark, path,
                  "duplicate " + what_ + " name '" + name + "', first given at line " +
                      std::to_string(it->second.line));
    return inserted;
  }

  std::optional<int> find(const std::string& name) const {
    const auto it = table_.find(name);
    return it == table_.end() ? std::nullopt : std::optional<int>(it->second.index);
  }

  // `extra` names that are valid references without being declared ("ground").
  std::optional<int> resolve(const Node& ref, Diagnostics& diags,
                             const std::vector<std::string>& extra = {}) const {
    if (auto index = find(ref.string())) return index;
    std::vector<std::string> names = extra;
    for (const auto& [name, declared] : table_) names.push_back(name);
    std::string message = "unknown " + what_ + " '" + ref.string() + "'";
    const std::string guess = did_you_mean(ref.string(), names);
    if (!guess.empty())
      message += guess;
    else if (names.empty())
      message += ", and the scene defines none";
    else
      message += ", expected " + one_of(names);
    diags.error(ref, message);
    return std::nullopt;
  }

 private:
  struct Declared {
    int index;
    int line;
  };
  std::string what_;
  std::map<std::string, Declared> table_;
};

// Mass and inertia per unit density of the closed-form solids.
struct SolidProperties {
  double volume = 0.0;
  Vec3 unit_inertia = Vec3::Zero();  // principal inertia / mass
};

std::optional<SolidProperties> solid_properties(const geo::Shape& shape) {
  if (const auto* b = std::get_if<geo::Box>(&shape)) {
    const Vec3 s = 2.0 * b->half_extents;
    const Vec3 sq = s.cwiseProduct(s);
    return SolidProperties{s.prod(),
                           Vec3(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y()) / 12.0};
  }
  if (const auto* c = std::get_if<geo::Cylinder>(&shape)) {
    const double r2 = c->radius * c->radius;
    const double inner = c->thickness > 0.0 ? c->radius - c->thickness : 0.0;
    const double i2 = inner * inner;
    const double length = 2.0 * c->half_length;
    const double across = (3.0 * (r2 + i2) + length * length) / 12.0;
    return SolidProperties{kPi * (r2 - i2) * length, Vec3(across, across, 0.5 * (r2 + i2))};
  }
  return std::nullopt;  // planes and open meshes have no volume
}

class Compiler {
 public:
  Compiler(const Node& root, const std::string& scene_path, Diagnostics& diags)
      : root_(root),
        scene_dir_(fs::path(scene_path).parent_path()),
        diags_(diags),
        model_(std::make_shared<Model>()) {
    sim_.scene_path = scene_path;
  }

  Simulation build() {
    read_settings();
    read_materials();
    read_bodies();
    read_joints();
    read_motors();
    read_domain();
    check_bodies_in_domain();
    read_feeds();
    check_feed_counts();
    check_gravity();
    read_collectors();
    check_bin_tallies();
    read_air();
    read_electrostatics();
    read_output();
    list_components();
    sim_.model = model_;
    return std::move(sim_);
  }

 private:
  // ---------------------------------------------------------------- settings

  void read_settings() {
    sim_.name = root_.at("name").string();
    sim_.seed = root_.at("seed").scalar.get<std::uint64_t>();
    const Node& time = root_.at("time");
    model_->step = time.at("step").number();
    sim_.end_time = time.at("end").number();
    sim_.until_collected = time.at("until").string() == "collected";
    const Node& end = time.at("end");
    sim_.end_origin = Diagnostic{end.mark.file, end.mark.line, end.mark.column, end.path, ""}.str();
    sim_.end_origin.resize(sim_.end_origin.size() - 2);  // the ": " before a message
    if (model_->step > sim_.end_time)
      diags_.error(time.at("step"), "step " + format(model_->step) +
                                        " s is longer than the run (end " + format(sim_.end_time) +
                                        " s), expected step <= end");
    else if (!(sim_.end_time / model_->step <= limits::kSteps))
      diags_.error(time.at("step"), "a step of " + format(model_->step) + " s makes " +
                                        whole(sim_.end_time / model_->step) +
                                        " steps to the end (" + format(sim_.end_time) +
                                        " s), expected at most " + whole(limits::kSteps) +
                                        " (a longer step or a shorter run)");
    read_solver(root_.at("solver"));
    const Node& contact = root_.at("contact");
    model_->contact.envelope_fraction = contact.at("envelope").number();
    model_->contact.recovery_speed = contact.at("recovery_speed").number();
    model_->contact.restitution_threshold = contact.at("restitution_threshold").number();
    model_->contact_model =
        contact.at("model").string() == "dem" ? ContactModel::DEM : ContactModel::DVI;
    const Node& dem = contact.at("dem");
    model_->dem.defaults = {dem.at("youngs_modulus").number(), dem.at("poisson_ratio").number()};
    model_->dem.min_restitution = dem.at("min_restitution").number();
    const Node* gravity = root_.find("gravity");
    model_->gravity = gravity ? vec3(*gravity) : Vec3::Zero();
  }

  void read_solver(const Node& s) {
    const std::string& method = s.at("method").string();
    model_->solver.method = method == "apgd"  ? SolverMethod::APGD
                            : method == "spg" ? SolverMethod::SPG
                                              : SolverMethod::PGS;
    model_->solver.max_iterations = s.at("max_iterations").scalar.get<int>();
    model_->solver.tolerance = s.at("tolerance").number();
    model_->solver.pgs_relaxation = s.at("relaxation").number();
    model_->solver.warm_start = s.at("warm_start").boolean();
  }

  // A unit vector, or nullopt (reported) for a zero vector.
  std::optional<Vec3> direction(const Node& n) {
    const Vec3 v = vec3(n);
    if (!(v.norm() > 0.0) || !v.allFinite()) {
      diags_.error(n, "got a zero vector, expected a direction");
      return std::nullopt;
    }
    return v.normalized();
  }

  // ---------------------------------------------------------------- materials

  void read_materials() {
    std::vector<Material> list;
    if (const Node* materials = root_.find("materials")) {
      // The table below has an entry per ordered pair: past the bound the
      // load stops here, before anything refers to a material.
      if (materials->entries.size() > limits::kMaterials) {
        diags_.error(*materials, std::to_string(materials->entries.size()) +
                                     " materials, expected at most " +
                                     std::to_string(limits::kMaterials));
        diags_.raise();
      }
      for (const Entry& e : materials->entries) {
        const Node& m = e.value;
        materials_.declare(e.key, e.key_mark, m.path, int(list.size()), diags_);
        const Node* density = m.find("density");
        has_density_.push_back(density != nullptr);
        list.push_back({e.key, density ? density->number() : 0.0, m.at("friction").number(),
                        m.at("restitution").number()});
        model_->dem.materials.push_back(elastic(m));
      }
    }
    model_->materials = MaterialTable(std::move(list), read_pairs());
  }

  // A material's DEM constants: its own, else contact.dem's (read before).
  ElasticProperties elastic(const Node& m) const {
    ElasticProperties e = model_->dem.defaults;
    if (const Node* modulus = m.find("youngs_modulus")) e.youngs_modulus = modulus->number();
    if (const Node* poisson = m.find("poisson_ratio")) e.poisson_ratio = poisson->number();
    return e;
  }

  std::vector<MaterialPair> read_pairs() {
    std::vector<MaterialPair> pairs;
    const Node* list = root_.find("material_pairs");
    if (!list) return pairs;
    std::map<std::pair<int, int>, int> seen;  // -> line
    for (const Node& p : list->items) {
      const auto a = materials_.resolve(p.at("materials").items[0], diags_);
      const auto b = materials_.resolve(p.at("materials").items[1], diags_);
      if (!a || !b) continue;
      const auto [it, inserted] = seen.emplace(std::minmax(*a, *b), p.mark.line);
      if (!inserted) {
        diags_.error(p.at("materials"), "this pair was given already at line " +
                                            std::to_string(it->second) +
                                            ", expected each pair once");
        continue;
      }
      MaterialPair pair{*a, *b, std::nullopt, std::nullopt};
      if (const Node* f = p.find("friction")) pair.friction = f->number();
      if (const Node* r = p.find("restitution")) pair.restitution = r->number();
      pairs.push_back(pair);
    }
    return pairs;
  }

  // A material reference whose density the caller needs (`who` needs it).
  std::optional<int> dense_material(const Node& ref, const std::string& who) {
    const auto index = materials_.resolve(ref, diags_);
    if (index && !has_density_[std::size_t(*index)]) {
      diags_.error(ref, "material '" + ref.string() + "' has no density, which " + who +
                            " needs, expected a density in materials." + ref.string());
      return std::nullopt;
    }
    return index;
  }

  // ---------------------------------------------------------------- bodies

  void read_bodies() {
    const Node* list = root_.find("bodies");
    if (!list) return;
    for (const Node& b : list->items) {
      RigidBody body;
      body.name = b.at("name").string();
      if (body.name == "ground")
        diags_.error(b.at("name"),
                     "'ground' names the fixed world in joints, expected another name");
      bodies_.declare(body.name, b.at("name").mark, b.at("name").path, int(model_->bodies.size()),
                      diags_);
      body.material = materials_.resolve(b.at("material"), diags_).value_or(0);
      const auto shape = geometry(b.at("geometry"));
      if (shape) body.shape = *shape;
      body.pose = pose(b.at("pose"));
      read_motion(b, body, shape.has_value());
      model_->bodies.push_back(std::move(body));
    }
  }

  std::optional<geo::Shape> geometry(const Node& g) {
    const Entry& e = g.entries.front();  // the schema allows exactly one
    const Node& s = e.value;
    if (e.key == "plane") {
      const auto normal = direction(s.at("normal"));
      if (!normal) return std::nullopt;
      return geo::Plane{*normal, normal->dot(vec3(s.at("point")))};
    }
    if (e.key == "box") return geo::Box{0.5 * vec3(s.at("size"))};
    if (e.key == "cylinder") return cylinder(s);
    return mesh(s);
  }

  std::optional<geo::Shape> cylinder(const Node& s) {
    const geo::Cylinder c{s.at("radius").number(), 0.5 * s.at("length").number(),
                          s.at("thickness").number()};
    if (c.thickness >= c.radius) {
      diags_.error(s.at("thickness"), "a wall of " + metres(c.thickness) + " fills the radius (" +
                                          metres(c.radius) +
                                          "), expected less, or 0 for a solid cylinder");
      return std::nullopt;
    }
    return c;
  }

  std::optional<geo::Shape> mesh(const Node& s) {
    const Node& file = s.at("file");
    const fs::path path = scene_dir_ / file.string();
    if (const std::string why = too_large(path, limits::kDataFileBytes); !why.empty()) {
      diags_.error(file, "cannot load mesh " + path.string() + ": " + why);
      return std::nullopt;
    }
    try {
      return geo::load_mesh(path.string(), s.at("scale").number());
    } catch (const std::exception& e) {
      diags_.error(file, std::string("cannot load mesh ") + e.what());
      return std::nullopt;
    }
  }

  Pose pose(const Node& p) {
    Pose pose;
    pose.position = vec3(p.at("position"));
    const Node* axis = p.find("axis");
    const Node* rotation = p.find("rotation");
    if (axis && rotation) {
      diags_.error(*axis, "both axis and rotation given, expected one of them");
    } else if (axis) {
      if (const auto a = direction(*axis)) pose.orientation = rotation_from_z(*a);
    } else if (rotation) {
      if (const auto a = direction(rotation->at("axis")))
        pose.orientation = Quat(Eigen::AngleAxisd(rotation->at("angle").number(), *a));
    }
    return pose;
  }

  // `has_shape`: the geometry compiled, so mass can be taken from it.
  void read_motion(const Node& b, RigidBody& body, bool has_shape) {
    const Node* motion = b.find("motion");
    const Node* dynamic = b.find("dynamic");
    if (motion && dynamic) {
      diags_.error(*dynamic,
                   "a body with a prescribed motion cannot be dynamic, expected motion or dynamic");
      return;
    }
    if (motion) {
      body.kind = BodyKind::Kinematic;
      if (const Node* rotation = motion->find("rotation")) {
        body.motion.axis = direction(rotation->at("axis")).value_or(Vec3::UnitZ());
        body.motion.center = vec3(rotation->at("center"));
        body.motion.angular_speed = rotation->at("speed").number();
      }
      if (const Node* v = motion->find("velocity")) body.motion.linear_velocity = vec3(*v);
    } else if (dynamic) {
      body.kind = BodyKind::Dynamic;
      body.velocity = vec3(dynamic->at("velocity"));
      body.angular_velocity = vec3(dynamic->at("angular_velocity"));
      if (has_shape) mass_properties(b, *dynamic, body);
    }
  }

  // Given mass and inertia, or from the solid's volume and a density.
  void mass_properties(const Node& b, const Node& d, RigidBody& body) {
    const Node* mass = d.find("mass");
    const Node* inertia = d.find("inertia");
    if (inertia && !mass) return diags_.error(*inertia, "inertia without a mass, expected both");
    if (mass && inertia) {
      body.mass = mass->number();
      body.inertia = vec3(*inertia);
      return;
    }
    const auto solid = solid_properties(body.shape);
    const std::string& kind = b.at("geometry").entries.front().key;
    if (!solid)
      return diags_.error(
          d, "a " + kind + " has no volume to take a mass from, expected mass and inertia");
    if (mass) {
      body.mass = mass->number();
    } else if (const Node* density = d.find("density")) {
      body.mass = density->number() * solid->volume;
    } else if (const auto m =
                   dense_material(b.at("material"), "dynamic body '" + body.name + "'")) {
      body.mass = model_->materials.materials()[std::size_t(*m)].density * solid->volume;
    }
    body.inertia = body.mass * solid->unit_inertia;
  }

  // ---------------------------------------------------------------- joints

  void read_joints() {
    const Node* list = root_.find("joints");
    if (!list) return;
    for (const Node& j : list->items) {
      joints_.declare(j.at("name").string(), j.at("name").mark, j.at("name").path,
                      int(model_->joints.size()), diags_);
      Joint joint;
      const std::string& type = j.at("type").string();
      joint.type = type == "revolute"    ? JointType::Revolute
                   : type == "prismatic" ? JointType::Prismatic
                                         : JointType::Fixed;
      joint.point = vec3(j.at("point"));
      joint.axis = direction(j.at("axis")).value_or(Vec3::UnitZ());
      const auto a = body_ref(j.at("body_a"));
      const auto b = body_ref(j.at("body_b"));
      if (a && b) check_joint_bodies(j, *a, *b);
      joint.body_a = a.value_or(-1);
      joint.body_b = b.value_or(-1);
      model_->joints.push_back(joint);
    }
  }

  std::optional<int> body_ref(const Node& ref) {
    if (ref.string() == "ground") return -1;
    return bodies_.resolve(ref, diags_, {"ground"});
  }

  bool is_dynamic(int body) const {
    return body >= 0 && model_->bodies[std::size_t(body)].kind == BodyKind::Dynamic;
  }

  void check_joint_bodies(const Node& j, int a, int b) {
    if (a == b)
      diags_.error(j.at("body_b"),
                   "joins '" + j.at("body_a").string() + "' to itself, expected two bodies");
    else if (!is_dynamic(a) && !is_dynamic(b))
      diags_.error(j.at("body_b"),
                   "neither body is dynamic, so the joint could not move anything; expected a "
                   "dynamic body (give it 'dynamic:')");
  }

  // ---------------------------------------------------------------- motors

  void read_motors() {
    const Node* list = root_.find("motors");
    if (!list) return;
    for (const Node& m : list->items) {
      const auto index = joints_.resolve(m.at("joint"), diags_);
      if (!index) continue;
      const Joint& joint = model_->joints[std::size_t(*index)];
      if (joint.type == JointType::Fixed) {
        diags_.error(m.at("joint"), "joint '" + m.at("joint").string() +
                                        "' is fixed, expected a revolute or prismatic joint");
        continue;
      }
      if (auto motor = read_motor(m, joint.type == JointType::Revolute)) {
        motor->joint = *index;
        model_->motors.push_back(*motor);
      }
    }
  }

  std::optional<Motor> read_motor(const Node& m, bool revolute) {
    const Node* speed = m.find("speed");
    const Node* position = m.find("position");
    const Node* max_speed = m.find("max_speed");
    const Node* max_force = m.find("max_force");
    bool ok = true;
    if (!speed == !position) {
      diags_.error(m, speed ? "both speed and position given, expected one of them"
                            : "neither speed nor position given, expected one of them");
      return std::nullopt;
    }
    if (speed) ok &= check_kind(*speed, revolute ? "angular_speed" : "speed", revolute);
    if (max_force) ok &= check_kind(*max_force, revolute ? "torque" : "force", revolute);
    if (position && revolute) {
      diags_.error(*position,
                   "position motors drive prismatic joints, expected a speed for a revolute joint");
      ok = false;
    }
    if (max_speed && !position) {
      diags_.error(*max_speed, "max_speed limits position motors, expected it only with position");
      ok = false;
    }
    if (!ok) return std::nullopt;
    Motor motor;
    motor.mode = speed ? Motor::Mode::Speed : Motor::Mode::Position;
    motor.target = (speed ? speed : position)->number();
    if (max_speed) motor.max_speed = max_speed->number();
    if (max_force) motor.max_force = max_force->number();
    return motor;
  }

  // Motor values take their kind from the joint: rad/s or m/s, N m or N.
  bool check_kind(const Node& value, const std::string& kind, bool revolute) {
    if (value.dimension.empty() || value.dimension == kind) return true;
    diags_.error(value, "'" + value.text + "' does not fit a " +
                            (revolute ? "revolute" : "prismatic") + " joint, expected " +
                            (kind == "angular_speed" ? "an angular speed (rad/s)"
                             : kind == "speed"       ? "a speed (m/s)"
                             : kind == "torque"      ? "a torque (N m)"
                                                     : "a force (N)"));
    return false;
  }

  // ---------------------------------------------------------------- domain

  void read_domain() {
    const Node* domain = root_.find("domain");
    if (!domain) return;
    if (auto box = aabb(domain->at("box"))) sim_.domain = *box;
  }

  // A box with min < max on every axis.
  std::optional<geo::Aabb> aabb(const Node& box) {
    const geo::Aabb b{vec3(box.at("min")), vec3(box.at("max"))};
    if ((b.min.array() < b.max.array()).all()) return b;
    diags_.error(box.at("max"), "max is not above min on every axis, expected max > min");
    return std::nullopt;
  }

  // A body that fills the same space all run: static, or turning about an
  // axis of symmetry (a drum on its own axis). Checks of where it is hold
  // for the whole run only for these.
  static bool fixed_in_space(const RigidBody& b) {
    if (b.kind == BodyKind::Static) return true;
    if (b.kind == BodyKind::Dynamic || b.motion.linear_velocity != Vec3::Zero()) return false;
    if (b.motion.angular_speed == 0.0) return true;
    const auto* c = std::get_if<geo::Cylinder>(&b.shape);
    const Vec3 axis = b.pose.orientation * Vec3::UnitZ();
    const Vec3 offset = b.pose.position - b.motion.center;
    return c && axis.cross(b.motion.axis).norm() < 1e-9 && axis.cross(offset).norm() < 1e-9;
  }

  // The world box around a bounded body at t = 0.
  static geo::Aabb world_bounds(const RigidBody& b) {
    const geo::Aabb local = geo::local_bounds(b.shape);
    geo::Aabb box = geo::Aabb::empty();
    for (int k = 0; k < 8; ++k)
      box.grow(b.pose.apply(Vec3((k & 1) ? local.max.x() : local.min.x(),
                                 (k & 2) ? local.max.y() : local.min.y(),
                                 (k & 4) ? local.max.z() : local.min.z())));
    return box;
  }

  static Vec3 corner(const geo::Aabb& box, int k) {
    return {(k & 1) ? box.max.x() : box.min.x(), (k & 2) ? box.max.y() : box.min.y(),
            (k & 4) ? box.max.z() : box.min.z()};
  }

  // A body that stays outside the domain meets no particle: a splitter or a
  // wall placed there is a mistake. So is a plane whose solid holds the
  // whole domain.
  void check_bodies_in_domain() {
    if (!sim_.domain) return;
    const Node* list = root_.find("bodies");
    for (std::size_t i = 0; list && i < model_->bodies.size(); ++i) {
      const RigidBody& b = model_->bodies[i];
      if (!fixed_in_space(b)) continue;
      const Node& node = list->items[i].at("pose");
      if (const auto* plane = std::get_if<geo::Plane>(&b.shape)) {
        int inside = 0;
        for (int k = 0; k < 8; ++k) {
          const Vec3 local = b.pose.inverse_apply(corner(*sim_.domain, k));
          inside += plane->normal.dot(local) < plane->offset ? 1 : 0;
        }
        if (inside == 8)
          diags_.error(node, "the solid side of plane '" + b.name +
                                 "' holds the whole domain, expected a plane through domain.box");
        else if (inside == 0)
          diags_.error(node, "plane '" + b.name +
                                 "' misses the domain, so no particle can reach it; expected a "
                                 "plane through domain.box");
      } else if (!world_bounds(b).overlaps(*sim_.domain)) {
        diags_.error(node, "body '" + b.name +
                               "' lies outside the domain, so no particle can reach it; "
                               "expected a body inside domain.box");
      }
    }
  }

  bool inside_domain(const geo::Aabb& b) const {
    return !sim_.domain || ((b.min.array() >= sim_.domain->min.array()).all() &&
                            (b.max.array() <= sim_.domain->max.array()).all());
  }

  // ---------------------------------------------------------------- feeds

  void read_feeds() {
    const Node* list = root_.find("feeds");
    if (!list) return;
    NameTable names("feed");
    for (const Node& f : list->items) {
      names.declare(f.at("name").string(), f.at("name").mark, f.at("name").path,
                    int(sim_.feeds.size()), diags_);
      Feed feed;
      feed.name = f.at("name").string();
      feed.start = f.at("start").number();
      if (const Node* duration = f.find("duration"))
        feed.duration = duration->number();
      else if (sim_.until_collected)
        diags_.error(f, "feed '" + feed.name + "' has no duration, so it never stops and the run "
                        "could not end with time.until: collected; expected a duration");
      const Node& rate = f.at("rate");
      (rate.dimension == "mass_rate" ? feed.mass_rate : feed.count_rate) = rate.number();
      feed.velocity = vec3(f.at("velocity"));
      feed.velocity_spread = f.at("velocity_spread").number();
      feed.random_orientation = f.at("random_orientation").boolean();
      if (f.at("lie_flat").boolean()) {
        if (model_->gravity == Vec3::Zero())
          diags_.error(f.at("lie_flat"), "lying flat needs a down, expected gravity");
        else
          feed.lie_flat = -model_->gravity.normalized();
      }
      feed.max_attempts = f.at("max_attempts").scalar.get<int>();
      const std::vector<double> across = read_mix(f.at("mix"), feed);
      const Node& region = f.at("region");
      if (const auto box = feed_region(region)) {
        feed.region = *box;
        check_fit(region, *box, across);
        check_free(region, *box);
      }
      sim_.feeds.push_back(std::move(feed));
      feed_rates_.push_back(&rate);
    }
  }

  std::optional<geo::Aabb> feed_region(const Node& region) {
    std::optional<geo::Aabb> box;
    if (const Node* b = region.find("box")) {
      box = aabb(*b);
    } else {
      box = outlet(region.at("outlet"));
    }
    if (box && !inside_domain(*box)) {
      diags_.error(
          region,
          "the region reaches outside the domain, so particles would be lost as they appear; "
          "expected a region inside domain.box");
      return std::nullopt;
    }
    return box;
  }

  // The feed region is an axis-aligned box, so an outlet faces along an axis.
  std::optional<geo::Aabb> outlet(const Node& o) {
    const Vec3 n = vec3(o.at("normal"));
    int axis = -1;
    for (int k = 0; k < 3; ++k)
      if (n[k] != 0.0 && n[(k + 1) % 3] == 0.0 && n[(k + 2) % 3] == 0.0) axis = k;
    if (axis < 0) {
      diags_.error(o.at("normal"), "got an oblique normal, expected one along x, y or z");
      return std::nullopt;
    }
    // The size lists the two other axes in x, y, z order.
    const int u = axis == 0 ? 1 : 0;
    const int v = axis == 2 ? 1 : 2;
    Vec3 half = Vec3::Zero();
    half[u] = 0.5 * o.at("size").items[0].number();
    half[v] = 0.5 * o.at("size").items[1].number();
    const Vec3 c = vec3(o.at("center"));
    return geo::Aabb{c - half, c + half};
  }

  // Returns the bounding diameter of each component's largest particles.
  std::vector<double> read_mix(const Node& mix, Feed& feed) {
    std::vector<double> across;
    double total = 0.0;
    for (const Node& c : mix.items) {
      FeedComponent component;
      component.mass_fraction = c.at("fraction").number();
      total += component.mass_fraction;
      const auto material = dense_material(c.at("material"), "feed '" + feed.name + "'");
      if (c.find("thickness")) {
        auto drawn = drawn_shape(c);
        if (!material || !drawn) continue;
        component.material = *material;
        across.push_back(drawn_across(*drawn));
        component.drawn = std::move(*drawn);
        feed.mix.push_back(component);
        continue;
      }
      if (!c.find("size")) {
        diags_.error(c, "missing key 'size', expected a size law, or thickness with width "
                        "(flake) or length (rod)");
        continue;
      }
      const auto shape = particle_shape(c);
      const feed::Basis basis =
          c.at("by").string() == "mass" ? feed::Basis::mass : feed::Basis::number;
      const auto size = size_distribution(c.at("size"), basis);
      if (!material || !shape || !size) continue;
      component.material = *material;
      component.shape = *shape;
      component.shape_size = shape_sizes_[std::size_t(*shape)];
      component.size = *size;
      feed.mix.push_back(component);
      const double diameter = size->quantile_by_number(is_bounded(c.at("size")) ? 1.0 : 1.0 - 1e-6);
      across.push_back(2.0 * model_->shapes[std::size_t(*shape)].bounding_radius * diameter /
                       component.shape_size);
    }
    if (std::abs(total - 1.0) > 1e-9)
      diags_.error(mix, "the fractions add up to " + format(total) + ", expected 1");
    return across;
  }

  // Normal and lognormal laws without a max have no largest particle: their
  // one-in-a-million size stands in for it.
  static bool is_bounded(const Node& size) {
    const Entry& law = size.entries.front();
    return law.key == "constant" || law.key == "uniform" || law.key == "sieve" ||
           law.value.find("max");
  }

  // The largest particles against the region's extent (an outlet's
  // thickness excepted).
  void check_fit(const Node& region, const geo::Aabb& box, const std::vector<double>& across) {
    const Vec3 extent = box.max - box.min;
    const double largest = across.empty() ? 0.0 : *std::max_element(across.begin(), across.end());
    for (int k = 0; k < 3; ++k) {
      if (extent[k] == 0.0 || extent[k] >= largest) continue;
      diags_.error(region, "the region is " + metres(extent[k]) + " wide along " + "xyz"[k] +
                               " but the largest particles are " + metres(largest) +
                               " across, expected a region that holds them");
      return;
    }
  }

  // A region all inside one convex solid (a box, a solid cylinder, a
  // plane's half-space) that stays put can place no particle. Convexity
  // makes the corners enough.
  void check_free(const Node& region, const geo::Aabb& box) {
    for (const RigidBody& b : model_->bodies) {
      const auto* c = std::get_if<geo::Cylinder>(&b.shape);
      const bool convex = std::holds_alternative<geo::Plane>(b.shape) ||
                          std::holds_alternative<geo::Box>(b.shape) ||
                          (c && (c->thickness == 0.0 || c->thickness >= c->radius));
      if (!convex || !fixed_in_space(b)) continue;
      bool inside = true;
      for (int k = 0; k < 8 && inside; ++k) {
        hits_.clear();
        geo::query(b.shape, b.pose.inverse_apply(corner(box, k)), 0.0, hits_);
        inside = std::any_of(hits_.begin(), hits_.end(),
                             [](const geo::SurfaceHit& h) { return h.distance < 0.0; });
      }
      if (inside)
        return diags_.error(region, "the region lies inside body '" + b.name +
                                        "', so no particle can be placed; expected a region in "
                                        "free space");
    }
  }

  // The particles the feeds make over the run, expected from the rates:
  // all of them are held in memory at once if nothing leaves.
  void check_feed_counts() {
    double total = 0.0, largest = -1.0;
    std::size_t at = 0;
    for (std::size_t i = 0; i < sim_.feeds.size(); ++i) {
      const double n = expected_particles(sim_.feeds[i]);
      total += n;
      if (!(n <= largest)) {
        largest = n;
        at = i;
      }
    }
    if (total <= limits::kFedParticles) return;
    diags_.error(*feed_rates_[at],
                 "feed '" + sim_.feeds[at].name + "' makes about " + whole(largest) +
                     " particles over the run (all feeds " + whole(total) + "), expected at most " +
                     whole(limits::kFedParticles) + " in all (a lower rate or a shorter feed)");
  }

  double expected_particles(const Feed& f) const {
    const double time = std::max(0.0, std::min(f.duration, sim_.end_time - f.start));
    if (f.count_rate > 0.0) return f.count_rate * time;
    double per_kg = 0.0;  // particles in a kilogram of the mix
    for (const FeedComponent& c : f.mix) {
      const double density = model_->materials.materials()[std::size_t(c.material)].density;
      per_kg += c.mass_fraction / (density * mean_volume(c));
    }
    return f.mass_rate * time * per_kg;
  }

  // A drawn flake's or rod's at its median dimensions: a bound's estimate.
  double mean_volume(const FeedComponent& c) const {
    if (c.drawn)
      return c.drawn->volume(c.drawn->thickness.quantile_by_number(0.5),
                             c.drawn->extent.quantile_by_number(0.5));
    const double volume = model_->shapes[std::size_t(c.shape)].volume;
    return volume * c.size.mean_mass_per_particle_factor() /
           (c.shape_size * c.shape_size * c.shape_size);
  }

  // Without gravity, fed particles keep their feed velocity: with none,
  // they hang where they appear. A scene may mean it (gravity: [0, 0, 0]
  // says so); leaving gravity out is usually an omission.
  void check_gravity() {
    if (sim_.feeds.empty() || root_.find("gravity")) return;
    diags_.warning(root_.at("feeds"),
                   "particles are fed but the scene gives no gravity: they move only by their feed "
                   "velocity, drag and fields; expected gravity (e.g. [0, -9.81 m/s^2, 0]), or "
                   "gravity: [0, 0, 0] to say there is none");
  }

  // ---------------------------------------------------------------- drawn shapes

  // The thinnest contact geometry of a drawn flake (37 spheres) or rod (19
  // spheres), and the ratio of neighbouring aspects on the ladder.
  static constexpr double kFlakeMinAspect = 0.15;
  static constexpr double kRodMinAspect = 0.1;
  static constexpr double kLadderRatio = 1.1;

  // A flake or rod whose dimensions are drawn: its laws and the ladder of
  // contact shapes the drawn aspects reach; nullopt: reported.
  std::optional<DrawnShape> drawn_shape(const Node& c) {
    const Node* shape = c.find("shape");
    const std::string name = shape ? shape->string() : "sphere";
    if (name != "flake" && name != "rod") {
      diags_.error(shape ? *shape : c.at("thickness"),
                   "a drawn thickness needs shape: flake or rod, expected one of them");
      return std::nullopt;
    }
    const bool flake = name == "flake";
    const char* extent_key = flake ? "width" : "length";
    for (const char* key : {"size", "aspect", flake ? "length" : "width"})
      if (const Node* extra = c.find(key)) {
        diags_.error(*extra, std::string("the ") + name + "'s dimensions are drawn from thickness and " +
                                 extent_key + ", expected no " + key);
        return std::nullopt;
      }
    const Node* extent = c.find(extent_key);
    if (!extent) {
      diags_.error(c, std::string("missing key '") + extent_key + "', expected the " + name +
                          "'s " + extent_key + " law with its thickness");
      return std::nullopt;
    }
    const auto t = size_distribution(c.at("thickness"), feed::Basis::number);
    const auto e = size_distribution(*extent, feed::Basis::number);
    if (!t || !e) return std::nullopt;
    DrawnShape d;
    d.kind = flake ? DrawnShape::Kind::Flake : DrawnShape::Kind::Rod;
    d.thickness = *t;
    d.extent = *e;
    d.ladder = ladder(name, t->quantile_by_number(0.0) / e->quantile_by_number(1.0),
                      t->quantile_by_number(1.0) / e->quantile_by_number(0.0));
    return d;
  }

  // The rungs of aspect a0 1.1^k (and 1) the drawn aspects [lo, hi] reach.
  std::vector<DrawnShape::Rung> ladder(const std::string& name, double lo, double hi) {
    const double a0 = name == "flake" ? kFlakeMinAspect : kRodMinAspect;
    std::vector<double> aspects;
    for (double a = a0; a < 1.0; a *= kLadderRatio) aspects.push_back(a);
    aspects.push_back(1.0);
    std::vector<DrawnShape::Rung> out;
    for (std::size_t k = 0; k < aspects.size(); ++k) {
      const bool below = k + 1 < aspects.size() && aspects[k + 1] <= lo;
      const bool above = k > 0 && aspects[k - 1] >= hi;
      if (!below && !above) out.push_back(rung(name, aspects[k]));
    }
    return out;
  }

  DrawnShape::Rung rung(const std::string& name, double aspect) {
    const std::string key = name + "~" + format(aspect);
    const auto it = shape_index_.find(key);
    const int index = it != shape_index_.end()
                          ? *it->second
                          : add_shape(builtin_spheres(name, aspect), nullptr, name);
    shape_index_[key] = index;
    const ParticleShape& shape = model_->shapes[std::size_t(index)];
    const double extent =
        name == "flake" ? std::sqrt(4.0 * fields::footprint_area(shape) / kPi) : 1.0;
    shape_sizes_[std::size_t(index)] = extent;
    return {index, aspect, extent};
  }

  // The bounding diameter of the largest particle a drawn shape can make.
  double drawn_across(const DrawnShape& d) const {
    const double largest = d.extent.quantile_by_number(1.0);
    double across = 0.0;
    for (const DrawnShape::Rung& r : d.ladder)
      across = std::max(across, 2.0 * largest / r.extent *
                                    model_->shapes[std::size_t(r.shape)].bounding_radius);
    return across;
  }

  // ---------------------------------------------------------------- particle shapes

  // The component's shape, compiled on first use: a shapes entry (which
  // wins over a built-in of the same name), or the built-in sphere, flake
  // or rod.
  std::optional<int> particle_shape(const Node& component) {
    const Node* ref = component.find("shape");
    const std::string name = ref ? ref->string() : "sphere";
    const Node* shapes = root_.find("shapes");
    const Node* entry = shapes ? shapes->find(name) : nullptr;
    if (!entry && !is_builtin_shape(name)) {
      report_unknown_shape(*ref, shapes);
      return std::nullopt;
    }
    const auto aspect = shape_aspect(component, name, entry != nullptr);
    if (!aspect) return std::nullopt;
    const std::string key = entry ? "shapes." + name : name + "@" + format(*aspect);
    if (const auto it = shape_index_.find(key); it != shape_index_.end()) return it->second;
    if (shape_index_.size() == limits::kParticleShapes) {
      diags_.error(ref ? *ref : component,
                   "a particle shape past the first " + std::to_string(limits::kParticleShapes) +
                       " (each shapes entry fed and each flake or rod aspect is one), expected "
                       "fewer");
      return shape_index_[key] = std::nullopt;
    }
    const auto spheres = entry ? cluster_spheres(*entry) : builtin_spheres(name, *aspect);
    std::optional<int> index;
    if (spheres) index = add_shape(*spheres, entry, name);
    shape_index_[key] = index;
    return index;
  }

  static bool is_builtin_shape(const std::string& name) {
    return name == "sphere" || name == "flake" || name == "rod";
  }

  void report_unknown_shape(const Node& ref, const Node* shapes) {
    NameTable known("shape");
    if (shapes)
      for (const Entry& e : shapes->entries) known.declare(e.key, e.key_mark, "", 0, diags_);
    known.resolve(ref, diags_, {"sphere", "flake", "rod"});
  }

  // The aspect of a built-in flake or rod (given, or the schema's default
  // for the shape); 0 for shapes without one; nullopt: reported.
  std::optional<double> shape_aspect(const Node& component, const std::string& name,
                                     bool scene_entry) {
    const Node* aspect = component.find("aspect");
    const bool takes_aspect = !scene_entry && name != "sphere";
    if (aspect && !takes_aspect) {
      diags_.error(*aspect, "'" + name + "' has no aspect, expected aspect only with flake or rod");
      return std::nullopt;
    }
    if (!takes_aspect) return 0.0;
    if (aspect) return aspect->number();
    return schema()
        .at("definitions")
        .at("mix_component")
        .at("properties")
        .at("aspect")
        .at("x-default-by-shape")
        .at(name)
        .get<double>();
  }

  static feed::SphereList builtin_spheres(const std::string& name, double aspect) {
    if (name == "flake") return feed::flake_spheres(aspect);
    if (name == "rod") return feed::rod_spheres(aspect);
    return {{Vec3::Zero()}, {0.5}};
  }

  // Listed in the scene or read from a file: exactly one of the two.
  std::optional<feed::SphereList> cluster_spheres(const Node& entry) {
    const Node* spheres = entry.find("spheres");
    const Node* file = entry.find("file");
    if (!spheres == !file) {
      diags_.error(entry, spheres ? "both spheres and file given, expected one of them"
                                  : "neither spheres nor file given, expected one of them");
      return std::nullopt;
    }
    feed::SphereList list;
    if (file) {
      const fs::path path = scene_dir_ / file->string();
      try {
        if (const std::string why = too_large(path, limits::kFileBytes); !why.empty())
          throw std::runtime_error(path.string() + ": " + why);
        list = feed::read_sphere_csv(path);
      } catch (const std::exception& e) {
        diags_.error(*file, std::string("cannot read the shape: ") + e.what());
        return std::nullopt;
      }
    } else {
      for (const Node& sphere : spheres->items) {
        list.centers.push_back(vec3(sphere));
        list.radii.push_back(sphere.items[3].number());
      }
    }
    if (list.centers.size() <= limits::kShapeSpheres) return list;
    diags_.error(file ? *file : *spheres,
                 "a shape of " + std::to_string(list.centers.size()) + " spheres, expected at most " +
                     std::to_string(limits::kShapeSpheres));
    return std::nullopt;
  }

  // Size at scale 1: a scene entry's `size` or its bounding diameter; for
  // the built-in flake and rod the diameter of the sphere of equal volume,
  // so that a size law gives the same masses whatever the built-in shape
  // (the unit sphere's is exactly 1).
  int add_shape(const feed::SphereList& spheres, const Node* entry, const std::string& name) {
    const ParticleShape shape = make_particle_shape(spheres.centers, spheres.radii);
    const Node* size = entry ? entry->find("size") : nullptr;
    if (size)
      shape_sizes_.push_back(size->number());
    else if (entry)
      shape_sizes_.push_back(2.0 * shape.bounding_radius);
    else
      shape_sizes_.push_back(name == "sphere" ? 1.0 : equal_volume_diameter(shape.volume));
    model_->shapes.push_back(shape);
    sim_.shape_names.push_back(name);
    return int(model_->shapes.size()) - 1;
  }

  // ---------------------------------------------------------------- sizes

  std::optional<feed::SizeDistribution> size_distribution(const Node& size, feed::Basis basis) {
    const Entry& law = size.entries.front();  // the schema allows exactly one
    const Node& s = law.value;
    try {
      if (law.key == "constant") return feed::SizeDistribution::constant(s.number());
      if (law.key == "sieve") return sieve(s, basis);
      const double min = s.find("min") ? s.at("min").number() : 0.0;
      const double max = s.find("max") ? s.at("max").number() : kInf;
      if (!(min < max)) {
        diags_.error(s.at("max"), "max " + metres(max) + " is not above min " + metres(min) +
                                      ", expected max > min");
        return std::nullopt;
      }
      if (law.key == "uniform") return feed::SizeDistribution::uniform(min, max, basis);
      if (law.key == "normal")
        return feed::SizeDistribution::normal(s.at("mean").number(), s.at("sd").number(), min, max,
                                              basis);
      return feed::SizeDistribution::lognormal(s.at("median").number(), s.at("sigma").number(), min,
                                               max, basis);
    } catch (const std::invalid_argument& e) {
      diags_.error(size, std::string(e.what()) + ", expected a size law with particles in it");
      return std::nullopt;
    }
  }

  std::optional<feed::SizeDistribution> sieve(const Node& rows, feed::Basis basis) {
    std::vector<feed::SizeDistribution::SievePoint> table;
    for (const Node& row : rows.items) {
      const feed::SizeDistribution::SievePoint p{row.items[0].number(), row.items[1].number()};
      if (!table.empty() && !(p.size > table.back().size))
        return sieve_error(row, "sizes must increase from row to row");
      if (!table.empty() && p.passing < table.back().passing)
        return sieve_error(row, "the fraction passing must not decrease");
      table.push_back(p);
    }
    if (table.front().passing != 0.0)
      return sieve_error(rows.items.front(), "the first row must pass 0");
    if (table.back().passing != 1.0)
      return sieve_error(rows.items.back(), "the last row must pass 1");
    return feed::SizeDistribution::sieve(table, basis);
  }

  std::nullopt_t sieve_error(const Node& row, const std::string& what) {
    diags_.error(row, "invalid sieve row: " + what +
                          ", expected [size, fraction passing] rows with sizes rising "
                          "and fractions rising from 0 to 1");
    return std::nullopt;
  }

  // ---------------------------------------------------------------- collectors

  void read_collectors() {
    const Node* list = root_.find("collectors");
    if (!list) return;
    NameTable names("collector");
    for (const Node& c : list->items) {
      names.declare(c.at("name").string(), c.at("name").mark, c.at("name").path,
                    int(sim_.collectors.size()), diags_);
      Collector collector;
      collector.name = c.at("name").string();
      const Node& plane = c.at("plane");
      const Node& bins = c.at("bins");
      collector.point = vec3(plane.at("point"));
      collector.normal = direction(plane.at("normal")).value_or(Vec3::UnitY());
      collector.axis = direction(bins.at("axis")).value_or(Vec3::UnitX());
      collector.from = bins.at("from").number();
      collector.to = bins.at("to").number();
      collector.bins = bins.at("count").scalar.get<int>();
      if (check_bins(bins, collector)) read_products(c.find("products"), collector);
      check_reachable(plane, bins, collector);
      sim_.collectors.push_back(std::move(collector));
    }
  }

  // Each bin keeps a tally per material.
  void check_bin_tallies() {
    double bins = 0.0;
    for (const Collector& c : sim_.collectors) bins += c.bins;
    const double tallies = bins * double(model_->materials.materials().size());
    if (tallies > limits::kBinTallies)
      diags_.error(root_.at("collectors"),
                   whole(bins) + " bins for " +
                       std::to_string(model_->materials.materials().size()) +
                       " materials make " + whole(tallies) + " tallies, expected at most " +
                       whole(limits::kBinTallies) + " (fewer bins)");
  }

  bool check_bins(const Node& bins, const Collector& c) {
    if (std::abs(c.axis.dot(c.normal)) > 1.0 - 1e-9) {
      diags_.error(bins.at("axis"),
                   "the bin axis is along the plane's normal, so every particle would land at "
                   "the same place; expected an axis in the plane");
      return false;
    }
    if (!(c.from < c.to)) {
      diags_.error(bins.at("to"), "to " + metres(c.to) + " is not above from " + metres(c.from) +
                                      ", expected from < to");
      return false;
    }
    return true;
  }

  void read_products(const Node* products, Collector& c) {
    if (!products) return;
    std::vector<std::pair<Product, const Node*>> sorted;
    for (const Entry& e : products->entries) {
      const Product p{e.key, e.value.items[0].number(), e.value.items[1].number()};
      if (!(p.from < p.to)) {
        diags_.error(e.value, "the range is empty or reversed, expected [from, to] with from < to");
      } else if (p.from < c.from || p.to > c.to) {
        diags_.error(e.value, "the range leaves the bins [" + format(c.from) + ", " + format(c.to) +
                                  "] m, expected a range inside them");
      } else {
        sorted.emplace_back(p, &e.value);
      }
      c.products.push_back(p);
    }
    std::sort(sorted.begin(), sorted.end(),
              [](const auto& a, const auto& b) { return a.first.from < b.first.from; });
    for (std::size_t i = 1; i < sorted.size(); ++i) {
      if (sorted[i].first.from < sorted[i - 1].first.to)
        diags_.error(*sorted[i].second, "overlaps product '" + sorted[i - 1].first.name +
                                            "', expected products that do not overlap");
    }
  }

  // With a domain, the plane must cut it: particles leave the domain first
  // otherwise.
  void check_reachable(const Node& plane, const Node& bins, const Collector& c) {
    if (!sim_.domain) return;
    double lo = kInf, hi = -kInf;
    for (int k = 0; k < 8; ++k) {
      const double side = c.normal.dot(corner(*sim_.domain, k) - c.point);
      lo = std::min(lo, side);
      hi = std::max(hi, side);
    }
    if (lo >= 0.0 || hi <= 0.0)
      return diags_.error(
          plane,
          "the plane misses the domain, so no particle can reach it; expected a plane through "
          "domain.box");
    if (c.from < c.to) check_bins_in_domain(bins, c);
  }

  // The domain's extent along the bin axis bounds where a particle can
  // cross the plane.
  void check_bins_in_domain(const Node& bins, const Collector& c) {
    double lo = kInf, hi = -kInf;
    for (int k = 0; k < 8; ++k) {
      const double along = c.axis.dot(corner(*sim_.domain, k) - c.point);
      lo = std::min(lo, along);
      hi = std::max(hi, along);
    }
    if (c.to <= lo || c.from >= hi)
      diags_.error(bins, "the bins [" + format(c.from) + ", " + format(c.to) +
                             "] m lie outside the domain, which spans [" + format(lo) + ", " +
                             format(hi) + "] m along the bin axis; expected bins inside it");
  }

  // ---------------------------------------------------------------- separator physics

  void read_air() {
    const Node* air = root_.find("air");
    if (!air) return;
    fields::DragSpec drag;
    drag.air.density = air->at("density").number();
    drag.air.viscosity = air->at("viscosity").number();
    drag.law = air->at("drag").string() == "stokes" ? fields::DragLaw::Stokes
                                                    : fields::DragLaw::SchillerNaumann;
    sim_.drag = drag;
  }

  void read_electrostatics() {
    const Node* section = root_.find("electrostatics");
    if (!section) return;
    std::vector<int> fed;
    for (const Feed& f : sim_.feeds)
      for (const FeedComponent& c : f.mix) fed.push_back(c.material);
    compile_electrostatics({*section, root_.find("materials"), *model_, fed, scene_dir_,
                            [this](const Node& ref) { return bodies_.resolve(ref, diags_); }},
                           sim_, diags_);
  }

  // ---------------------------------------------------------------- output

  // A frame is written at most once a step, so a shorter interval counts as
  // the step.
  void check_frames(const Node& every_node, double every) {
    const double interval = std::max(every, model_->step);
    const double frames = sim_.end_time / interval;
    if (frames <= limits::kFrames) return;
    const std::string given = every < model_->step ? "a frame every step (" + format(interval) + " s)"
                                                   : "a frame every " + format(interval) + " s";
    diags_.error(every_node, given + " makes " + whole(frames) +
                                 " trajectory frames, expected at most " +
                                 whole(limits::kFrames) + " (a longer interval)");
  }

  void read_output() {
    const Node& out = root_.at("output");
    sim_.output.dir = out.at("dir").string();
    sim_.output.steps_csv = out.at("steps").boolean();
    sim_.output.distribution_svg = out.at("distribution").boolean();
    const Node* t = out.find("trajectories");
    if (t && t->at("format").string() != "none") {
      const std::string& kind = t->at("format").string();
      sim_.output.trajectories.every = t->at("every").number();
      check_frames(t->at("every"), sim_.output.trajectories.every);
      sim_.output.trajectories.vtk = kind != "csv";
      sim_.output.trajectories.csv = kind != "vtk";
    } else {
      sim_.output.trajectories = {0.0, false, false};
    }
    if (const Node* field = out.find("field")) read_field_picture(*field);
    if (const Node* c = out.find("checkpoint")) sim_.output.checkpoint_every = c->at("every").number();
  }

  // More samples than this would make a field.csv of hundreds of MB.
  static constexpr double kMaxFieldSamples = 4e6;

  void read_field_picture(const Node& f) {
    if (!sim_.electrostatics) {
      if (!root_.find("electrostatics"))  // else the section's own problems were reported
        diags_.error(f, "the field picture needs a field, expected an electrostatics section");
      return;
    }
    FieldPicture picture;
    picture.resolution = f.at("resolution").number();
    if (const Node* extent = f.find("extent")) {
      const Node& lo = extent->at("min");
      const Node& hi = extent->at("max");
      picture.min = Vec2(lo.items[0].number(), lo.items[1].number());
      picture.max = Vec2(hi.items[0].number(), hi.items[1].number());
      if (!(picture.min.array() < picture.max.array()).all())
        return diags_.error(hi, "max is not above min on both axes, expected max > min");
    } else {
      default_extent(picture);
    }
    const Vec2 cells = (picture.max - picture.min) / picture.resolution;
    if ((cells.x() + 1.0) * (cells.y() + 1.0) > kMaxFieldSamples)
      return diags_.error(f.at("resolution"), "a resolution of " + metres(picture.resolution) +
                                                  " needs " +
                                                  format((cells.x() + 1.0) * (cells.y() + 1.0)) +
                                                  " samples, expected a coarser one (at most " +
                                                  format(kMaxFieldSamples) + ")");
    sim_.output.field = picture;
  }

  // The drum and the electrodes, with a margin of a fifth of the drum radius.
  void default_extent(FieldPicture& p) const {
    const double r = sim_.electrostatics->drum.radius;
    p.min = Vec2(-r, -r);
    p.max = Vec2(r, r);
    for (const NamedElectrode& e : sim_.electrodes) {
      const Vec2 reach = Vec2::Constant(e.electrode.radius);
      p.min = p.min.cwiseMin(e.electrode.centre - reach);
      p.max = p.max.cwiseMax(e.electrode.centre + reach);
    }
    p.min -= Vec2::Constant(0.2 * r);
    p.max += Vec2::Constant(0.2 * r);
  }

  // What the run has to build (docs/architecture.md): absent sections cost nothing.
  void list_components() {
    const Model& m = *model_;
    const auto any_body = [&](BodyKind kind) {
      return std::any_of(m.bodies.begin(), m.bodies.end(),
                         [&](const RigidBody& b) { return b.kind == kind; });
    };
    const bool meshes = std::any_of(m.bodies.begin(), m.bodies.end(), [](const RigidBody& b) {
      return std::holds_alternative<std::shared_ptr<const geo::TriMesh>>(b.shape);
    });
    const bool clusters = std::any_of(m.shapes.begin(), m.shapes.end(),
                                      [](const ParticleShape& s) { return !s.is_sphere(); });
    const std::vector<std::pair<const char*, bool>> components = {
        {"gravity", m.gravity != Vec3::Zero()},
        {"contacts", !sim_.feeds.empty() || any_body(BodyKind::Dynamic)},
        {"kinematic_bodies", any_body(BodyKind::Kinematic)},
        {"dynamic_bodies", any_body(BodyKind::Dynamic)},
        {"joints", !m.joints.empty()},
        {"motors", !m.motors.empty()},
        {"meshes", meshes},
        {"clusters", clusters},
        {"feeds", !sim_.feeds.empty()},
        {"collectors", !sim_.collectors.empty()},
        {"domain", sim_.domain.has_value()},
        {"drag", sim_.drag.has_value()},
        {"electrostatics", sim_.electrostatics.has_value()},
        {"corona_charging", sim_.electrostatics && (!sim_.electrostatics->corona.empty() ||
                                                    !sim_.electrostatics->bands.empty())},
        {"brush", sim_.electrostatics && sim_.electrostatics->brush_body.has_value()},
        {"trajectories", sim_.output.trajectories.every > 0.0},
    };
    for (const auto& [name, on] : components)
      if (on) sim_.active_components.push_back(name);
  }

  const Node& root_;
  fs::path scene_dir_;
  Diagnostics& diags_;
  Simulation sim_;
  std::shared_ptr<Model> model_;
  NameTable materials_{"material"};
  NameTable bodies_{"body"};
  NameTable joints_{"joint"};
  std::vector<bool> has_density_;
  // "shapes.<entry>" or "<built-in>@<aspect>" -> Model::shapes index; nullopt: reported
  std::map<std::string, std::optional<int>> shape_index_;
  std::vector<double> shape_sizes_;      // per Model::shapes entry
  std::vector<const Node*> feed_rates_;  // per Simulation::feeds entry
  std::vector<geo::SurfaceHit> hits_;
};

}  // namespace

Simulation compile(const Node& root, const std::string& scene_path, Diagnostics& diags) {
  return Compiler(root, scene_path, diags).build();
}

}  // namespace ces::scene
