// Mutable simulation state, laid out for the hot loops: one array per field.
#pragma once
#include <cstdint>
#include <tuple>
#include <vector>

#include "common/math.hpp"

namespace ces {

// Free particles (spheres and sphere clusters). Removal swaps the last
// particle into the hole, so indices are not stable across steps; `id` is.
struct Particles {
  std::vector<std::uint64_t> id;
  std::vector<std::int32_t> shape;     // index into Model::shapes
  std::vector<double> scale;           // size of this particle / its shape's unit size
  std::vector<std::int32_t> material;  // index into Model::materials
  std::vector<Vec3> position;          // centre of mass
  std::vector<Quat> orientation;       // principal frame -> world
  std::vector<Vec3> velocity;
  std::vector<Vec3> angular_velocity;  // world frame
  std::vector<double> mass;
  std::vector<double> inv_mass;
  std::vector<Vec3> inv_inertia;       // principal frame, 1 / I
  std::vector<Vec3> force;             // external, cleared every step
  std::vector<Vec3> torque;
  std::vector<double> charge;          // C; stays 0 unless a scene has electrodes

  std::size_t size() const { return id.size(); }
  void push(std::uint64_t new_id, int shape_index, double size_scale, int material_index,
            double m, const Vec3& inertia, const Vec3& x, const Quat& q, const Vec3& v,
            const Vec3& w);
  void swap_remove(std::size_t i);
  void reserve(std::size_t n);
  // New index j takes old index order[j]. The arrays swap with `scratch`'s,
  // so once both have grown, reordering allocates nothing.
  void permute(const std::vector<std::uint32_t>& order, Particles& scratch);
};

// Every per-particle array, listed once for the operations on all of them.
inline constexpr auto kParticleArrays = std::tuple{
    &Particles::id,       &Particles::shape,    &Particles::scale,       &Particles::material,
    &Particles::position, &Particles::orientation, &Particles::velocity, &Particles::angular_velocity,
    &Particles::mass,     &Particles::inv_mass, &Particles::inv_inertia, &Particles::force,
    &Particles::torque,   &Particles::charge};

// Machine bodies: the Model's rigid bodies, in the same order.
struct Bodies {
  std::vector<Pose> pose;
  std::vector<Vec3> velocity;          // of the body-frame origin
  std::vector<Vec3> angular_velocity;  // world frame
  std::vector<Vec3> force;             // external, dynamic bodies only
  std::vector<Vec3> torque;
};

}  // namespace ces
