// The stepper: state arrays advanced by a fixed pipeline of stages
//   pre-step hooks (feeds) -> collide -> force stages (fields) -> assemble
//   -> solve CCP -> integrate -> post-step hooks (collectors, observers).
// Under ContactModel::DEM, "assemble" also computes the penalty contact
// forces (dynamics/dem.hpp) and the CCP keeps only the joints' rows.
#pragma once
#include <Eigen/Core>
#include <functional>
#include <memory>
#include <vector>

#include "collision/collide.hpp"
#include "collision/contacts.hpp"
#include "dynamics/ccp.hpp"
#include "dynamics/dem.hpp"
#include "dynamics/joints.hpp"
#include "dynamics/model.hpp"
#include "dynamics/state.hpp"

namespace ces {

struct StageTimes {
  double hooks = 0, broadphase = 0, narrowphase = 0, forces = 0, assemble = 0, solve = 0,
         integrate = 0;
  StageTimes& operator+=(const StageTimes& o);
  double total() const;
};

struct StepStats {
  std::uint64_t step = 0;
  double time = 0.0;  // at the end of the step
  std::size_t particles = 0;
  std::size_t contacts = 0;
  SolveStats solver;
  double max_penetration = 0.0;           // m, at the start of the step
  double max_penetration_relative = 0.0;  // / radius of the smaller sphere
  // The same over contacts with walls only (static and kinematic bodies):
  // above 1, a sphere's centre is past a wall's surface (into the drum,
  // through a plate).
  double max_wall_penetration_relative = 0.0;
  double joint_drift = 0.0;               // m, at the start of the step
  // World::make_safe: when the solve stopped at its cap, the factor its
  // contact impulses were scaled by so as not to create energy (1: kept);
  // on every step, the wall rows left violated that the wall guard finished.
  double impulse_scale = 1.0;
  std::size_t wall_corrections = 0;
  // Bodies whose wall rows the guard's first sweeps left violated and whose
  // sweeps went on, body by body, until they held (CcpProblem::guard_walls);
  // and of them, those still violated after the sweeps' cap.
  std::size_t walls_finished = 0, walls_unfinished = 0;
  // Bodies whose wall impulses were scaled down to take the relaxed cone's
  // lift back (every step; CcpProblem::release_sliding_walls).
  std::size_t sliding_releases = 0;
  // Clumps in contact whose spin was limited (World::limit_spin).
  std::size_t spin_limited = 0;
  // DEM only: the smallest particle's Rayleigh time (s; 0 under DVI), and
  // whether the step exceeds 20 % of it (explicit contact is then unreliable).
  double rayleigh_time = 0.0;
  bool step_above_rayleigh_limit = false;
  StageTimes seconds;
};

class World {
 public:
  using Hook = std::function<void(World&)>;
  // A force stage adds to particles().force / torque and bodies' force /
  // torque; it may read this step's contacts.
  using ForceStage = std::function<void(World&, const Contacts&)>;

  explicit World(std::shared_ptr<const Model> model);

  const Model& model() const { return *model_; }
  Particles& particles() { return particles_; }
  const Particles& particles() const { return particles_; }
  Bodies& bodies() { return bodies_; }
  const Bodies& bodies() const { return bodies_; }
  double time() const { return time_; }
  std::uint64_t step_count() const { return stats_.step; }
  const StepStats& last_step() const { return stats_; }
  const Contacts& contacts() const { return contacts_; }
  // Last step's impulses: 3 per contact (normal, t1, t2), then bilateral rows.
  ConstSpan impulses() const { return gamma_; }

  // Mass and inertia from the shape's volume and the material's density.
  std::uint64_t add_particle(int shape, double scale, int material, const Vec3& position,
                             const Quat& orientation = Quat::Identity(),
                             const Vec3& velocity = Vec3::Zero(),
                             const Vec3& angular_velocity = Vec3::Zero());
  void remove_particle(std::size_t index) { particles_.swap_remove(index); }

  void add_pre_step(Hook h) { pre_.push_back(std::move(h)); }
  void add_force_stage(ForceStage f) { forces_.push_back(std::move(f)); }
  void add_post_step(Hook h) { post_.push_back(std::move(h)); }

  const StepStats& step();

  // Pose and velocity of a kinematic body at time t, in closed form.
  static void prescribed_state(const RigidBody& body, double t, Pose& pose, Vec3& v, Vec3& w);

 private:
  void set_body_motion(double t);
  void build_solver_bodies();
  void dem_contacts(StepStats& stats);
  void make_safe(StepStats& stats);
  void limit_spin(StepStats& stats);
  void guard_walls(StepStats& stats, const std::vector<std::uint8_t>* locked = nullptr);
  double guard_tolerance() const;  // m/s
  void release_sliding(StepStats& stats);
  void integrate(double h);
  void remember_impulses();
  void reorder_in_space();

  std::shared_ptr<const Model> model_;
  Particles particles_;
  Bodies bodies_;
  std::vector<JointFrame> joint_frames_;
  std::vector<double> max_turn_;        // per shape: rad per step in contact (limit_spin)
  std::vector<std::uint8_t> touching_;  // per particle: has a contact this step
  std::vector<std::uint8_t> capped_;    // per solver body: spin capped this step
  std::vector<std::uint8_t> locked_;    // per solver body: guarded in translation only
  bool has_clumps_ = false;
  double time_ = 0.0;
  std::uint64_t next_id_ = 0;
  std::vector<Hook> pre_, post_;
  std::vector<ForceStage> forces_;

  Collider collider_;
  Contacts contacts_;
  SolverBodies solver_bodies_;
  CcpProblem problem_;
  std::vector<BilateralRow> rows_;
  SolverWorkspace workspace_;
  std::vector<double> gamma_;
  // Warm start: last step's contact impulses as world vectors, by key, and
  // its bilateral rows' impulses.
  ContactMemory prev_impulses_;
  std::vector<double> prev_rows_;
  std::vector<Vec3> impulse_scratch_;
  std::vector<Vec3> base_v_, base_w_;  // make_safe: the velocities of the joints' impulses
  DemContacts dem_;
  Particles reorder_scratch_;
  std::vector<std::uint32_t> order_;
  struct SortKey {
    std::uint64_t cell, id;
    std::uint32_t index;
  };
  std::vector<SortKey> sort_keys_;
  StepStats stats_;
};

}  // namespace ces
