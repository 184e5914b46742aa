// The state of a run, laid out for the hot loops: one array per field.
// Everything that lives from one step to the next is here (or in a stage's
// own record: a feed's random stream, the collectors' tallies), so a step
// is a function of the state and the model.
#pragma once
#include <cstdint>
#include <memory>
#include <tuple>
#include <vector>

#include "common/math.hpp"
#include "common/serial.hpp"
#include "model/contact_memory.hpp"
#include "model/model.hpp"

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
  // C: a mixed particle's induced charge on its metal part (its insulating
  // part's is `charge`); 0 for everything else.
  std::vector<double> metal_charge;
  // s: the time it was added at (a feed's particle: the start of the step
  // that fed it).
  std::vector<double> birth;
  // Sleep (dynamics/sleep.hpp): the body that carries a sleeping particle,
  // or kAwake; and how long an awake one has been at rest on a body (s).
  std::vector<std::int32_t> carrier;
  std::vector<double> at_rest;
  static constexpr std::int32_t kAwake = -1;

  bool asleep(std::size_t i) const { return carrier[i] != kAwake; }
  std::size_t size() const { return id.size(); }
  // The velocity of particle i's material point at x.
  Vec3 velocity_at(std::size_t i, const Vec3& x) const {
    return velocity[i] + angular_velocity[i].cross(x - position[i]);
  }
  void push(std::uint64_t new_id, int shape_index, double size_scale, int material_index,
            double m, const Vec3& inertia, const Vec3& x, const Quat& q, const Vec3& v,
            const Vec3& w, double birth_time);
  void swap_remove(std::size_t i);
  // New index j takes old index order[j]. The arrays swap with `scratch`'s,
  // so once both have grown, reordering allocates nothing.
  void permute(const std::vector<std::uint32_t>& order, Particles& scratch);
};

// Particle i's bounding radius (about its centre of mass), at its scale.
inline double bounding_radius(const Model& model, const Particles& p, std::size_t i) {
  return model.shapes[std::size_t(p.shape[i])].bounding_radius * p.scale[i];
}

// Particle i's size as the outputs give it: shape_size[s] is the diameter
// of shape s at scale 1 (shape_sizes, spec/simulation.hpp).
inline double particle_diameter(const std::vector<double>& shape_size, const Particles& p,
                                std::size_t i) {
  return p.scale[i] * shape_size[std::size_t(p.shape[i])];
}

// Particle i's charge as the outputs give it: a mixed particle's two
// parts together.
inline double particle_charge(const Particles& p, std::size_t i) {
  return p.charge[i] + p.metal_charge[i];
}

// Every per-particle array, listed once for the operations on all of them.
inline constexpr auto kParticleArrays = std::tuple{
    &Particles::id,       &Particles::shape,    &Particles::scale,       &Particles::material,
    &Particles::position, &Particles::orientation, &Particles::velocity, &Particles::angular_velocity,
    &Particles::mass,     &Particles::inv_mass, &Particles::inv_inertia, &Particles::force,
    &Particles::torque,   &Particles::charge,   &Particles::metal_charge, &Particles::birth,
    &Particles::carrier,  &Particles::at_rest};

// Machine bodies: the Model's rigid bodies, in the same order.
struct Bodies {
  std::vector<Pose> pose;
  std::vector<Vec3> velocity;          // of the body-frame origin
  std::vector<Vec3> angular_velocity;  // world frame
  std::vector<Vec3> force;             // external, dynamic bodies only
  std::vector<Vec3> torque;

  // The velocity of body k's material point at x.
  Vec3 velocity_at(std::size_t k, const Vec3& x) const {
    return velocity[k] + angular_velocity[k].cross(x - pose[k].position);
  }
};

// Whether body k's surface moves by its turn alone this step: the solve
// does not move it (it is not dynamic) and it does not translate. Particles
// sleep on such a body, and it holds them as a wall all step where it was.
inline bool turns_in_place(const Model& model, const Bodies& bodies, std::size_t k) {
  return model.bodies[k].kind != BodyKind::Dynamic && bodies.velocity[k] == Vec3::Zero();
}

// Everything a step reads and writes, but the stages' scratch.
struct State {
  Particles particles;
  Bodies bodies;
  double time = 0.0;          // s
  std::uint64_t steps = 0;    // steps taken
  std::uint64_t next_id = 0;  // the id of the next particle added
  // The warm start: last step's contact impulses as world vectors, by
  // contact key, and its bilateral rows' impulses.
  ContactMemory impulses;
  std::vector<double> row_impulses;
  // DEM: each contact's accumulated tangential displacement, by key.
  ContactMemory springs;
};

// The whole state as bytes (checkpoints), and back: a state read back
// steps on to the same bits as the one written.
void save(ByteWriter& out, const State& state);
void load(ByteReader& in, State& state);
// Throws CorruptData where a state read back cannot be this model's: an
// index past its shapes, materials or bodies, a particle not finite or
// without mass. A checksum does not stop a file edited on purpose, and
// the step would read past an array.
void check_loaded(const Model& model, const State& state);

// The state at t = 0: the bodies at their initial pose and velocity, no
// particles.
void init_state(const Model& model, State& state);

// Adds a particle with mass and inertia from its shape's volume and its
// material's density, born at state.time; returns its id.
std::uint64_t add_particle(const Model& model, State& state, int shape, double scale,
                           int material, const Vec3& position,
                           const Quat& orientation = Quat::Identity(),
                           const Vec3& velocity = Vec3::Zero(),
                           const Vec3& angular_velocity = Vec3::Zero());
// The same with its own mass and principal inertia (a drawn flake's, which
// its contact shape does not have).
std::uint64_t add_particle(State& state, int shape, double scale, int material, double mass,
                           const Vec3& inertia, const Vec3& position, const Quat& orientation,
                           const Vec3& velocity, const Vec3& angular_velocity = Vec3::Zero());

// Every kinematic body's pose and velocity at time t, in closed form.
void set_body_motion(const Model& model, double t, Bodies& bodies);

}  // namespace ces
