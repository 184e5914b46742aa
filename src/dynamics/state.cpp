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

void Particles::reserve(std::size_t n) {
  for_each_array(*this, [n](auto& v) { v.reserve(n); });
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

}  // namespace ces
