#include "dynamics/state.hpp"

namespace ces {

void Particles::push(std::uint64_t new_id, int shape_index, double size_scale,
                     int material_index, double m, const Vec3& inertia, const Vec3& x,
                     const Quat& q, const Vec3& v, const Vec3& w) {
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
}

namespace {
template <class T>
void swap_out(std::vector<T>& v, std::size_t i) {
  v[i] = v.back();
  v.pop_back();
}
}  // namespace

void Particles::swap_remove(std::size_t i) {
  swap_out(id, i);
  swap_out(shape, i);
  swap_out(scale, i);
  swap_out(material, i);
  swap_out(position, i);
  swap_out(orientation, i);
  swap_out(velocity, i);
  swap_out(angular_velocity, i);
  swap_out(mass, i);
  swap_out(inv_mass, i);
  swap_out(inv_inertia, i);
  swap_out(force, i);
  swap_out(torque, i);
  swap_out(charge, i);
}

void Particles::reserve(std::size_t n) {
  id.reserve(n);
  shape.reserve(n);
  scale.reserve(n);
  material.reserve(n);
  position.reserve(n);
  orientation.reserve(n);
  velocity.reserve(n);
  angular_velocity.reserve(n);
  mass.reserve(n);
  inv_mass.reserve(n);
  inv_inertia.reserve(n);
  force.reserve(n);
  torque.reserve(n);
  charge.reserve(n);
}

}  // namespace ces
