#include "sim/world.hpp"

#include <omp.h>

#include <algorithm>
#include <utility>

#include "common/clock.hpp"

namespace ces {
namespace {

// Runs one stage: its wall time into stats, then the observer, whose time
// is the output stage's.
template <class F>
void run_stage(Stage stage, StepStats& stats, StepObserver* observer, const World& world,
               F&& body) {
  const auto t0 = Clock::now();
  body();
  const auto t1 = Clock::now();
  stats.seconds[stage] += std::chrono::duration<double>(t1 - t0).count();
  if (observer == nullptr) return;
  observer->after(stage, world);
  stats.seconds[Stage::Output] += seconds_since(t1);
}

const Bodies& initial_bodies(const Model& model, State& state) {
  init_state(model, state);
  return state.bodies;
}

}  // namespace

World::World(std::shared_ptr<const Model> model)
    : model_(std::move(model)), dynamics_(*model_, initial_bodies(*model_, state_)) {
  if (model_->threads > 0) omp_set_num_threads(model_->threads);
}

World::World(const Simulation& sim) : World(sim.model) {
  for (const Feed& f : sim.feeds) add_feed(f, sim.seed);
  if (sim.drag) set_drag(*sim.drag);
  if (sim.electrostatics) set_electrostatics(*sim.electrostatics);
  set_collection(sim.collectors, sim.domain, shape_sizes(sim));
}

void World::add_feed(const Feed& feed, std::uint64_t seed) {
  feeders_.emplace_back(feed, seed, *model_);
}

void World::set_drag(const fields::DragSpec& spec) { drag_.emplace(spec, *model_); }

void World::set_electrostatics(fields::ElectrostaticsSpec spec) {
  electrostatics_.emplace(std::move(spec), *model_);
}

void World::set_collection(std::vector<Collector> collectors, std::optional<geo::Aabb> domain,
                           std::vector<double> shape_size) {
  collection_.emplace(std::move(collectors), domain, model_->materials.materials().size(),
                      std::move(shape_size));
}

std::uint64_t World::add_particle(int shape, double scale, int material, const Vec3& position,
                                  const Quat& orientation, const Vec3& velocity,
                                  const Vec3& angular_velocity) {
  return ces::add_particle(*model_, state_, shape, scale, material, position, orientation,
                           velocity, angular_velocity);
}

const StepStats& World::step(StepObserver* observer) {
  const Model& m = *model_;
  StepStats stats;
  stats.step = state_.steps + 1;
  auto stage = [&](Stage s, auto&& body) { run_stage(s, stats, observer, *this, body); };
  stage(Stage::Feed, [&] { feed(); });
  stage(Stage::Broadphase, [&] { broadphase(); });
  stage(Stage::Narrowphase, [&] { narrowphase(); });
  stage(Stage::Forces, [&] { forces(stats); });
  stage(Stage::Assemble, [&] { dynamics_.assemble(m, state_, contacts_, stats); });
  stage(Stage::Solve, [&] { dynamics_.solve(m, stats); });
  stage(Stage::Safeguards,
        [&] { dynamics_.safeguard(m, state_, collider_.envelopes(), stats); });
  stage(Stage::Integrate, [&] {
    integrate(stats);
    stats.time = state_.time;
    stats.particles = state_.particles.size();
    stats.contacts = contacts_.size();
  });
  stage(Stage::Collect, [&] { collect(); });
  stats_ = stats;
  const auto t0 = Clock::now();
  if (observer != nullptr) observer->end_of_step(*this);
  stats_.seconds[Stage::Output] += seconds_since(t0);
  return stats_;
}

void World::save(ByteWriter& out) const {
  ces::save(out, state_);
  for (const feed::Feeder& f : feeders_) f.save(out);
  if (collection_) collection_->save(out);
}

void World::load(ByteReader& in) {
  ces::load(in, state_);
  check_loaded(*model_, state_);
  for (feed::Feeder& f : feeders_) f.load(in);
  if (collection_) collection_->load(in);
}

void World::feed() {
  for (feed::Feeder& f : feeders_) f.feed(state_);
}

void World::broadphase() {
  const Model& m = *model_;
  if (m.reorder_interval > 0 && state_.steps % std::uint64_t(m.reorder_interval) == 0)
    spatial_order_.apply(m, state_.particles);
  if (m.sleep.enabled) sleep_.wake_near_bodies(m, state_.bodies, state_.particles);
  collider_.broadphase(m, state_.particles, state_.bodies);
}

void World::narrowphase() {
  collider_.narrowphase(*model_, state_.particles, state_.bodies, contacts_);
}

// The force stages add to the particles' and bodies' forces, cleared first.
void World::forces(StepStats& stats) {
  Particles& p = state_.particles;
  Bodies& b = state_.bodies;
  std::fill(p.force.begin(), p.force.end(), Vec3::Zero());
  std::fill(p.torque.begin(), p.torque.end(), Vec3::Zero());
  std::fill(b.force.begin(), b.force.end(), Vec3::Zero());
  std::fill(b.torque.begin(), b.torque.end(), Vec3::Zero());
  if (drag_) stats.drag_held = drag_->apply(p, model_->step);
  if (electrostatics_) electrostatics_->apply(*model_, contacts_, b, p);
}

void World::integrate(StepStats& stats) {
  const Model& m = *model_;
  if (m.sleep.enabled) poses_before_ = state_.bodies.pose;
  dynamics_.integrate(m, state_, contacts_);
  state_.time += m.step;
  ++state_.steps;
  set_body_motion(m, state_.time, state_.bodies);
  if (!m.sleep.enabled) return;
  Sleep::carry(poses_before_, state_.bodies, state_.particles);
  // The warm-start memory holds this step's impulses in contact order.
  stats.asleep = sleep_.update(m, state_.bodies, contacts_, state_.impulses.values(),
                               state_.particles);
}

void World::collect() {
  if (collection_) collection_->collect(state_.time, model_->step, state_.particles);
}

}  // namespace ces
