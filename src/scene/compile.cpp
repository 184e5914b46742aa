#include "scene/compile.hpp"

#include "scene/compiler.hpp"

namespace ces::scene {
namespace {

namespace fs = std::filesystem;

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


}  // namespace

void Compiler::read_settings() {
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
  model_->contact.manifold =
      contact.at("manifold").string() == "four" ? Manifold::Four : Manifold::Hold;
  model_->contact_model =
      contact.at("model").string() == "dem" ? ContactModel::DEM : ContactModel::DVI;
  model_->contact.flat_faces = contact.at("flake_faces").string() == "flat";
  if (model_->contact.flat_faces && model_->contact_model == ContactModel::DEM)
    diags_.error(contact.at("flake_faces"),
                 "flake_faces flat needs contact.model dvi: dem's forces are sphere on sphere");
  if (model_->sleep.enabled && model_->contact_model == ContactModel::DEM)
    diags_.error(root_.at("solver").at("sleep"),
                 "sleep needs contact.model dvi: it reads the contact impulses");
  const Node& dem = contact.at("dem");
  model_->dem.defaults = {dem.at("youngs_modulus").number(), dem.at("poisson_ratio").number()};
  model_->dem.min_restitution = dem.at("min_restitution").number();
  const Node* gravity = root_.find("gravity");
  model_->gravity = gravity ? vec3(*gravity) : Vec3::Zero();
}

void Compiler::read_solver(const Node& s) {
  const std::string& method = s.at("method").string();
  model_->solver.method = method == "apgd"  ? SolverMethod::APGD
                          : method == "spg" ? SolverMethod::SPG
                                            : SolverMethod::PGS;
  model_->solver.max_iterations = s.at("max_iterations").scalar.get<int>();
  model_->solver.tolerance = s.at("tolerance").number();
  model_->solver.penetration_tolerance = s.at("penetration_tolerance").number();
  model_->solver.pgs_relaxation = s.at("relaxation").number();
  model_->solver.warm_start = s.at("warm_start").boolean();
  if (const Node* sleep = s.find("sleep"))
    model_->sleep = {true, sleep->at("speed").number(), sleep->at("time").number()};
}

// A unit vector, or nullopt (reported) for a zero vector.
std::optional<Vec3> Compiler::direction(const Node& n) {
  const Vec3 v = vec3(n);
  if (!(v.norm() > 0.0) || !v.allFinite()) {
    diags_.error(n, "got a zero vector, expected a direction");
    return std::nullopt;
  }
  return v.normalized();
}

void Compiler::read_materials() {
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
      const Node* stiffness = m.find("stiffness");
      list.push_back({e.key, density ? density->number() : 0.0, m.at("friction").number(),
                      m.at("restitution").number(), stiffness ? 1.0 / stiffness->number() : 0.0});
      model_->dem.materials.push_back(elastic(m));
    }
  }
  model_->materials = MaterialTable(std::move(list), read_pairs());
}

// A material's DEM constants: its own, else contact.dem's (read before).
ElasticProperties Compiler::elastic(const Node& m) const {
  ElasticProperties e = model_->dem.defaults;
  if (const Node* modulus = m.find("youngs_modulus")) e.youngs_modulus = modulus->number();
  if (const Node* poisson = m.find("poisson_ratio")) e.poisson_ratio = poisson->number();
  return e;
}

std::vector<MaterialPair> Compiler::read_pairs() {
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
std::optional<int> Compiler::dense_material(const Node& ref, const std::string& who) {
  const auto index = materials_.resolve(ref, diags_);
  if (index && !has_density_[std::size_t(*index)]) {
    diags_.error(ref, "material '" + ref.string() + "' has no density, which " + who +
                          " needs, expected a density in materials." + ref.string());
    return std::nullopt;
  }
  return index;
}

void Compiler::read_bodies() {
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

std::optional<geo::Shape> Compiler::geometry(const Node& g) {
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

std::optional<geo::Shape> Compiler::cylinder(const Node& s) {
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

std::optional<geo::Shape> Compiler::mesh(const Node& s) {
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

Pose Compiler::pose(const Node& p) {
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
void Compiler::read_motion(const Node& b, RigidBody& body, bool has_shape) {
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
void Compiler::mass_properties(const Node& b, const Node& d, RigidBody& body) {
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

void Compiler::read_joints() {
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

std::optional<int> Compiler::body_ref(const Node& ref) {
  if (ref.string() == "ground") return -1;
  return bodies_.resolve(ref, diags_, {"ground"});
}

bool Compiler::is_dynamic(int body) const {
  return body >= 0 && model_->bodies[std::size_t(body)].kind == BodyKind::Dynamic;
}

void Compiler::check_joint_bodies(const Node& j, int a, int b) {
  if (a == b)
    diags_.error(j.at("body_b"),
                 "joins '" + j.at("body_a").string() + "' to itself, expected two bodies");
  else if (!is_dynamic(a) && !is_dynamic(b))
    diags_.error(j.at("body_b"),
                 "neither body is dynamic, so the joint could not move anything; expected a "
                 "dynamic body (give it 'dynamic:')");
}

void Compiler::read_motors() {
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

std::optional<Motor> Compiler::read_motor(const Node& m, bool revolute) {
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
bool Compiler::check_kind(const Node& value, const std::string& kind, bool revolute) {
  if (value.dimension.empty() || value.dimension == kind) return true;
  diags_.error(value, "'" + value.text + "' does not fit a " +
                          (revolute ? "revolute" : "prismatic") + " joint, expected " +
                          (kind == "angular_speed" ? "an angular speed (rad/s)"
                           : kind == "speed"       ? "a speed (m/s)"
                           : kind == "torque"      ? "a torque (N m)"
                                                   : "a force (N)"));
  return false;
}

void Compiler::read_domain() {
  const Node* domain = root_.find("domain");
  if (!domain) return;
  if (auto box = aabb(domain->at("box"))) sim_.domain = *box;
}

// A box with min < max on every axis.
std::optional<geo::Aabb> Compiler::aabb(const Node& box) {
  const geo::Aabb b{vec3(box.at("min")), vec3(box.at("max"))};
  if ((b.min.array() < b.max.array()).all()) return b;
  diags_.error(box.at("max"), "max is not above min on every axis, expected max > min");
  return std::nullopt;
}

// A body that fills the same space all run: static, or turning about an
// axis of symmetry (a drum on its own axis). Checks of where it is hold
// for the whole run only for these.
bool Compiler::fixed_in_space(const RigidBody& b) {
  if (b.kind == BodyKind::Static) return true;
  if (b.kind == BodyKind::Dynamic || b.motion.linear_velocity != Vec3::Zero()) return false;
  if (b.motion.angular_speed == 0.0) return true;
  const auto* c = std::get_if<geo::Cylinder>(&b.shape);
  const Vec3 axis = b.pose.orientation * Vec3::UnitZ();
  const Vec3 offset = b.pose.position - b.motion.center;
  return c && axis.cross(b.motion.axis).norm() < 1e-9 && axis.cross(offset).norm() < 1e-9;
}

// A body that stays outside the domain meets no particle: a splitter or a
// wall placed there is a mistake. So is a plane whose solid holds the
// whole domain.
void Compiler::check_bodies_in_domain() {
  if (!sim_.domain) return;
  const Node* list = root_.find("bodies");
  for (std::size_t i = 0; list && i < model_->bodies.size(); ++i) {
    const RigidBody& b = model_->bodies[i];
    if (!fixed_in_space(b)) continue;
    const Node& node = list->items[i].at("pose");
    if (const auto* plane = std::get_if<geo::Plane>(&b.shape)) {
      int inside = 0;
      for (int k = 0; k < 8; ++k) {
        const Vec3 local = b.pose.inverse_apply(sim_.domain->corner(k));
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

bool Compiler::inside_domain(const geo::Aabb& b) const {
  return !sim_.domain || ((b.min.array() >= sim_.domain->min.array()).all() &&
                          (b.max.array() <= sim_.domain->max.array()).all());
}

Simulation compile(const Node& root, const std::string& scene_path, Diagnostics& diags) {
  return Compiler(root, scene_path, diags).build();
}

}  // namespace ces::scene
