// The step. A World holds the state of a run and the stages that advance
// it; World::step runs them in this order, each reading and writing named
// parts of the state:
//
//   stage        reads                                  writes
//   feed         time, particles, body poses            new particles
//   broadphase   particle positions, velocities,        particle order (every
//                forces (last step's), shapes, body     reorder_interval steps),
//                poses                                  sleepers woken near a
//                                                       body, candidate pairs
//   narrowphase  candidate pairs, particles, bodies      contacts
//   forces       contacts, particles, body motion       particle forces, charges
//   assemble     particles, bodies, contacts, forces,   the step's problem,
//                the warm-start memory                  penetration statistics
//   solve        the problem                            impulses
//   safeguards   impulses, contacts, particle shapes    impulses, velocities
//   integrate    velocities, contacts, impulses,        particle and body motion,
//                forces                                 time, warm-start memory,
//                                                       who sleeps
//   collect      particle positions and velocities      removes collected and lost
//                                                       particles, their records
//   output       everything                             nothing (observers)
//
// An observer (StepObserver) is called after each stage and at the output
// stage; it only reads. Each stage's wall time goes into the step's
// statistics (StepStats::seconds).
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "collect/collection.hpp"
#include "collision/collide.hpp"
#include "collision/contacts.hpp"
#include "collision/spatial_order.hpp"
#include "dynamics/contact_dynamics.hpp"
#include "dynamics/sleep.hpp"
#include "feed/feeder.hpp"
#include "fields/drag.hpp"
#include "fields/electrostatics.hpp"
#include "model/model.hpp"
#include "model/state.hpp"
#include "model/stats.hpp"
#include "spec/simulation.hpp"

namespace ces {

class World;

// Reads the world as a step goes; may not change it.
class StepObserver {
 public:
  virtual ~StepObserver() = default;
  // After each stage but the output stage.
  virtual void after(Stage /*stage*/, const World& /*world*/) {}
  // The output stage: the step is done.
  virtual void end_of_step(const World& /*world*/) {}
};

class World {
 public:
  // The contact dynamics alone: nothing fed, no fields, nothing collected.
  explicit World(std::shared_ptr<const Model> model);
  // Every stage the compiled scene asks for.
  explicit World(const Simulation& sim);

  // The stages a scene may add: feeds (in order), drag, electrostatics (the
  // forces stage runs drag first), the collectors and the domain.
  void add_feed(const Feed& feed, std::uint64_t seed);
  void set_drag(const fields::DragSpec& spec);
  void set_electrostatics(fields::ElectrostaticsSpec spec);
  void set_collection(std::vector<Collector> collectors, std::optional<geo::Aabb> domain,
                      std::vector<double> shape_size);

  const Model& model() const { return *model_; }
  const State& state() const { return state_; }
  // Particles and bodies may be set up before the first step.
  Particles& particles() { return state_.particles; }
  const Particles& particles() const { return state_.particles; }
  Bodies& bodies() { return state_.bodies; }
  const Bodies& bodies() const { return state_.bodies; }
  double time() const { return state_.time; }
  std::uint64_t step_count() const { return state_.steps; }
  const StepStats& last_step() const { return stats_; }
  const Contacts& contacts() const { return contacts_; }
  // Last step's impulses: 3 per contact (normal, t1, t2), then bilateral rows.
  ConstSpan impulses() const { return dynamics_.impulses(); }
  const std::vector<feed::Feeder>& feeders() const { return feeders_; }
  const collect::Collection* collection() const { return collection_ ? &*collection_ : nullptr; }

  // Mass and inertia from the shape's volume and the material's density.
  std::uint64_t add_particle(int shape, double scale, int material, const Vec3& position,
                             const Quat& orientation = Quat::Identity(),
                             const Vec3& velocity = Vec3::Zero(),
                             const Vec3& angular_velocity = Vec3::Zero());
  // Between steps: the last particle takes index i.
  void remove_particle(std::size_t i) { state_.particles.swap_remove(i); }

  const StepStats& step(StepObserver* observer = nullptr);

  // Everything that carries from one step to the next: the state, the
  // feeds' streams and tallies, the collectors' records. A world built from
  // the same scene and loaded steps on to the same bits as the one saved.
  void save(ByteWriter& out) const;
  void load(ByteReader& in);

 private:
  void feed();
  void broadphase();
  void narrowphase();
  void forces(StepStats& stats);
  void integrate(StepStats& stats);
  void collect();

  std::shared_ptr<const Model> model_;
  State state_;
  // The stages and their scratch.
  std::vector<feed::Feeder> feeders_;
  SpatialOrder spatial_order_;
  Collider collider_;
  Contacts contacts_;
  std::optional<fields::DragStage> drag_;
  std::optional<fields::ElectrostaticsStage> electrostatics_;
  ContactDynamics dynamics_;
  Sleep sleep_;
  std::vector<Pose> poses_before_;  // the bodies' at the start of integrate
  std::optional<collect::Collection> collection_;
  StepStats stats_;
};

}  // namespace ces
