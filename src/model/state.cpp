#include "model/state.hpp"

#include <cmath>
#include <string>

namespace ces {

void Particles::push(std::uint64_t new_id, int shape_index, double size_scale,
                     int material_index, double m, const Vec3& inertia, const Vec3& x,
                     const Quat& q, const Vec3& v, const Vec3& w, double birth_time) {
  id.push_back(new_id);
  shape.push_back(shape_index);
  scale.push_back(size_scale);
  material.push_back(material_index);
  position.push_back(x);
  orientation.push_back(q.normalized());
  velocity.push_back(v);
  angular_velocity.push_back(w);
  mass.push_back(m);
  inv_mass.push_back(1.0 / m);
  inv_inertia.push_back(inertia.cwiseInverse());
  force.push_back(Vec3::Zero());
  torque.push_back(Vec3::Zero());
  charge.push_back(0.0);
  metal_charge.push_back(0.0);
  birth.push_back(birth_time);
  carrier.push_back(kAwake);
  at_rest.push_back(0.0);
}

namespace {
template <class F>
void for_each_array(Particles& p, F&& f) {
  std::apply([&](auto... member) { (f(p.*member), ...); }, kParticleArrays);
}
}  // namespace

void Particles::swap_remove(std::size_t i) {
  for_each_array(*this, [i](auto& v) {
    v[i] = v.back();
    v.pop_back();
  });
}

void Particles::permute(const std::vector<std::uint32_t>& order, Particles& scratch) {
  std::apply(
      [&](auto... member) {
        auto gather = [&](auto& from, auto& to) {
          to.resize(order.size());
          for (std::size_t j = 0; j < order.size(); ++j) to[j] = from[order[j]];
          from.swap(to);
        };
        (gather(this->*member, scratch.*member), ...);
      },
      kParticleArrays);
}

namespace {

void save(ByteWriter& out, const ContactMemory& m) {
  out.values(m.keys());
  out.values(m.values());
}

void load(ByteReader& in, ContactMemory& m) {
  std::vector<ContactKey> keys;
  std::vector<Vec3> values;
  in.values(keys);
  in.values(values);
  if (keys.size() != values.size()) throw CorruptData("a contact memory's keys and values differ");
  m.assign(keys, values);
}

}  // namespace

void save(ByteWriter& out, const State& s) {
  std::apply([&](auto... member) { (out.values(s.particles.*member), ...); }, kParticleArrays);
  const Bodies& b = s.bodies;
  for (const auto* v : {&b.velocity, &b.angular_velocity, &b.force, &b.torque}) out.values(*v);
  out.values(b.pose);
  out.value(s.time);
  out.value(s.steps);
  out.value(s.next_id);
  save(out, s.impulses);
  out.values(s.row_impulses);
  save(out, s.springs);
}

void load(ByteReader& in, State& s) {
  std::apply([&](auto... member) { (in.values(s.particles.*member), ...); }, kParticleArrays);
  const std::size_t n = s.particles.size();
  std::apply([&](auto... member) {
    if ((((s.particles.*member).size() != n) || ...))
      throw CorruptData("the particle arrays differ in length");
  }, kParticleArrays);
  Bodies& b = s.bodies;
  for (auto* v : {&b.velocity, &b.angular_velocity, &b.force, &b.torque}) in.values(*v);
  in.values(b.pose);
  in.value(s.time);
  in.value(s.steps);
  in.value(s.next_id);
  load(in, s.impulses);
  in.values(s.row_impulses);
  load(in, s.springs);
}

namespace {

// What is wrong with particle i of a state read back, or null.
const char* unlike_model(const Model& model, const Particles& p, std::size_t i) {
  if (p.shape[i] < 0 || std::size_t(p.shape[i]) >= model.shapes.size()) return "its shape";
  if (p.material[i] < 0 || std::size_t(p.material[i]) >= model.materials.materials().size())
    return "its material";
  if (p.carrier[i] != Particles::kAwake &&
      (p.carrier[i] < 0 || std::size_t(p.carrier[i]) >= model.bodies.size()))
    return "the body carrying it";
  if (!p.position[i].allFinite() || !p.velocity[i].allFinite() ||
      !p.angular_velocity[i].allFinite() || !p.orientation[i].coeffs().allFinite() ||
      std::abs(p.orientation[i].norm() - 1.0) > 1e-6)
    return "its motion";
  if (!(p.mass[i] > 0.0) || !std::isfinite(p.mass[i]) || !(p.scale[i] > 0.0) ||
      !std::isfinite(p.scale[i]))
    return "its mass or size";
  return nullptr;
}

}  // namespace

void check_loaded(const Model& model, const State& state) {
  const Particles& p = state.particles;
  for (std::size_t i = 0; i < p.size(); ++i)
    if (const char* what = unlike_model(model, p, i))
      throw CorruptData("particle " + std::to_string(p.id[i]) + ": " + what +
                        " is not one this scene can have");
  if (state.bodies.pose.size() != model.bodies.size())
    throw CorruptData("the machine's bodies have changed");
}

void init_state(const Model& model, State& state) {
  const std::size_t nb = model.bodies.size();
  Bodies& b = state.bodies;
  b.pose.resize(nb);
  b.velocity.resize(nb);
  b.angular_velocity.resize(nb);
  b.force.assign(nb, Vec3::Zero());
  b.torque.assign(nb, Vec3::Zero());
  for (std::size_t i = 0; i < nb; ++i) {
    const RigidBody& body = model.bodies[i];
    const bool dynamic = body.kind == BodyKind::Dynamic;
    b.pose[i] = body.pose;
    b.velocity[i] = dynamic ? body.velocity : Vec3::Zero();
    b.angular_velocity[i] = dynamic ? body.angular_velocity : Vec3::Zero();
  }
  set_body_motion(model, 0.0, b);
}

std::uint64_t add_particle(const Model& model, State& state, int shape, double scale,
                           int material, const Vec3& position, const Quat& orientation,
                           const Vec3& velocity, const Vec3& angular_velocity) {
  const ParticleShape& s = model.shapes[std::size_t(shape)];
  const double mass = particle_mass(model, shape, scale, material);
  return add_particle(state, shape, scale, material, mass, mass * scale * scale * s.unit_inertia,
                      position, orientation, velocity, angular_velocity);
}

std::uint64_t add_particle(State& state, int shape, double scale, int material, double mass,
                           const Vec3& inertia, const Vec3& position, const Quat& orientation,
                           const Vec3& velocity, const Vec3& angular_velocity) {
  const std::uint64_t id = state.next_id++;
  state.particles.push(id, shape, scale, material, mass, inertia, position, orientation,
                       velocity, angular_velocity, state.time);
  return id;
}

namespace {

void prescribed_state(const RigidBody& b, double t, Pose& pose, Vec3& v, Vec3& w) {
  const PrescribedMotion& m = b.motion;
  const Vec3 axis = m.axis.normalized();
  const Quat turn(Eigen::AngleAxisd(m.angular_speed * t, axis));
  const Vec3 centre = m.center + m.linear_velocity * t;
  pose.position = centre + turn * (b.pose.position - m.center);
  pose.orientation = turn * b.pose.orientation;
  w = m.angular_speed * axis;
  v = m.linear_velocity + w.cross(pose.position - centre);
}

}  // namespace

void set_body_motion(const Model& model, double t, Bodies& bodies) {
  for (std::size_t i = 0; i < model.bodies.size(); ++i) {
    const RigidBody& b = model.bodies[i];
    if (b.kind == BodyKind::Kinematic)
      prescribed_state(b, t, bodies.pose[i], bodies.velocity[i], bodies.angular_velocity[i]);
  }
}

}  // namespace ces
