// The compiled, immutable description of a simulation: what a scene compiler
// builds and the stepper reads. Nothing here knows about YAML or files.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common/math.hpp"
#include "geometry/shapes.hpp"
#include "model/defaults.hpp"

namespace ces {

struct Material {
  std::string name;
  double density = 1000.0;     // kg/m^3
  double friction = defaults::kMaterialFriction;        // Coulomb coefficient
  double restitution = defaults::kMaterialRestitution;  // normal coefficient of restitution
  // m/N: how far a contact with this surface yields per newton of normal
  // force (a brush's bristles bend); 0, rigid. Read by the dvi contact model.
  double compliance = 0.0;
};

// Explicit values for one pair of materials; unset fields fall back to the
// combination rule (see MaterialTable).
struct MaterialPair {
  int a = 0, b = 0;
  std::optional<double> friction;
  std::optional<double> restitution;
};

// What a contact between two surfaces takes from their materials.
struct SurfacePair {
  double friction = 0.0, restitution = 0.0;
  double compliance = 0.0;  // m/N, both surfaces' in series; 0: rigid
  double damping_ratio = 0.0;  // of a yielding pair's spring (spring_damping_ratio)
};

// The damping ratio zeta of a linear spring-dashpot contact whose force
// never pulls (it ends when the force, not the overlap, comes back to 0)
// that gives restitution e (Schwager, Poeschel, Granular Matter 9(6),
// 2007): e(zeta) falls from 1 at zeta = 0 to exp(-2) at zeta = 1. Below
// that, 1: past critical damping the dashpot would hold a surface in for
// longer than it was pressed, which a bristle bed does not do.
double spring_damping_ratio(double restitution);

// Friction and restitution for every pair of materials. Combination rule for
// pairs without an override: the smaller of the two coefficients (as Chrono
// does): the less grippy / less bouncy surface governs, which keeps a slippery
// liner slippery whatever touches it. Compliances add: two yielding surfaces
// pressed together are springs in series.
class MaterialTable {
 public:
  MaterialTable() = default;
  MaterialTable(std::vector<Material> materials, const std::vector<MaterialPair>& pairs);
  const std::vector<Material>& materials() const { return materials_; }
  SurfacePair pair(int a, int b) const { return pairs_[index(a, b)]; }
  // A pair of materials as one number, which a contact stores in place of
  // its SurfacePair (collision/contacts.hpp), and the pair it stands for.
  std::uint32_t pair_index(int a, int b) const { return std::uint32_t(index(a, b)); }
  const SurfacePair& surfaces(std::uint32_t pair) const { return pairs_[pair]; }

 private:
  std::size_t index(int a, int b) const { return std::size_t(a) * materials_.size() + std::size_t(b); }
  std::vector<Material> materials_;
  std::vector<SurfacePair> pairs_;  // n x n, a's row
};

// A cluster of spheres of one radius whose centres lie in one plane (a
// flake) is a plate of that thickness: the hull of its centres swept by the
// sphere. Another particle's sphere over the hull meets the plate's face,
// one beside it the plate's rim (contact.flake_faces flat,
// collision/collide.cpp).
struct FlatFace {
  // In the shape's frame: the plane's unit normal, two unit axes in it
  // (x, y, normal right-handed) and its origin, the centres' mean.
  Vec3 normal = Vec3::Zero(), x_axis = Vec3::Zero(), y_axis = Vec3::Zero(), origin = Vec3::Zero();
  // The centres' convex hull in (x, y), counter-clockwise; empty: not flat.
  std::vector<std::array<double, 2>> hull;
  std::vector<std::uint32_t> corners;  // the sphere at each corner of the hull
  std::vector<std::uint8_t> at_corner;  // per sphere: 1 where it is one of corners
  // Past this squared distance from the origin no point is covered: most
  // points a narrowphase asks about are beyond every corner.
  double beyond = std::numeric_limits<double>::infinity();
  bool flat() const { return !hull.empty(); }
  // Whether (x, y) is in the hull or on it (to a billionth of an edge).
  bool covers(double x, double y) const;
};

// A rigid particle: one sphere or a rigid cluster of (possibly overlapping)
// spheres. Sphere centres are given in the principal frame with the centre
// of mass at the origin, so the inertia tensor is diagonal.
struct ParticleShape {
  std::vector<Vec3> centers;
  std::vector<double> radii;
  double volume = 0.0;
  Vec3 unit_inertia = Vec3::Zero();  // principal inertia / mass (m^2)
  double bounding_radius = 0.0;       // about the centre of mass
  FlatFace face;
  bool is_sphere() const { return centers.size() == 1; }
  double smallest_radius() const { return *std::min_element(radii.begin(), radii.end()); }
};

// Builds a ParticleShape from spheres given in any frame: computes the union's
// volume, centre of mass and inertia (overlaps counted once), then moves the
// spheres to the principal frame. `frame` receives the pose of the principal
// frame in the input frame.
ParticleShape make_particle_shape(const std::vector<Vec3>& centers,
                                  const std::vector<double>& radii,
                                  Pose* frame = nullptr);

// The sphere of a shape's volume V: radius (3V / 4π)^⅓ and diameter
// (6V / π)^⅓, each computed as written (the two roundings differ).
inline double equal_volume_radius(double volume) { return std::cbrt(3.0 * volume / (4.0 * kPi)); }
inline double equal_volume_diameter(double volume) { return std::cbrt(6.0 * volume / kPi); }

enum class BodyKind { Static, Kinematic, Dynamic };

// Prescribed motion of a kinematic body: rotation about an axis through
// `center` at `angular_speed` (rad/s, right-handed about `axis`), plus a
// constant translation velocity. The pose is evaluated in closed form at each
// time, so it never drifts.
struct PrescribedMotion {
  Vec3 axis = Vec3::UnitZ();
  Vec3 center = Vec3::Zero();
  double angular_speed = 0.0;
  Vec3 linear_velocity = Vec3::Zero();
  bool moves() const { return angular_speed != 0.0 || linear_velocity != Vec3::Zero(); }
};

// A machine part: drum, brush, wall, hopper, splitter. Its shape is in the
// body frame; `pose` is the body frame at t = 0 (for dynamic bodies the body
// frame origin is the centre of mass).
struct RigidBody {
  std::string name;
  BodyKind kind = BodyKind::Static;
  geo::Shape shape;
  Pose pose;
  int material = 0;
  PrescribedMotion motion;          // kinematic only
  double mass = 0.0;                // dynamic only
  Vec3 inertia = Vec3::Ones();      // dynamic only: principal, body frame
  Vec3 velocity = Vec3::Zero();     // dynamic: initial
  Vec3 angular_velocity = Vec3::Zero();
};
// The world box around a bounded body's shape at t = 0.
geo::Aabb world_bounds(const RigidBody& b);

enum class JointType { Revolute, Prismatic, Fixed };

// A bilateral joint between two rigid bodies (body_a = -1: the ground).
// `point` and `axis` are in world coordinates at t = 0.
struct Joint {
  JointType type = JointType::Fixed;
  int body_a = -1;
  int body_b = 0;
  Vec3 point = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();
};

// A motor drives a joint's free coordinate inside the same solve.
//  - Speed on a revolute joint: relative angular speed about the axis (rad/s).
//  - Speed on a prismatic joint: relative speed along the axis (m/s).
//  - Position on a prismatic joint: slide to `target` (m from the t = 0
//    position) at no more than `max_speed`.
// `max_force` bounds the motor impulse per step (force or torque).
struct Motor {
  enum class Mode { Speed, Position };
  int joint = 0;
  Mode mode = Mode::Speed;
  double target = 0.0;
  double max_speed = std::numeric_limits<double>::infinity();
  double max_force = std::numeric_limits<double>::infinity();
};

enum class SolverMethod { APGD, SPG, PGS };

struct SolverSettings {
  SolverMethod method = SolverMethod::APGD;
  int max_iterations = defaults::kSolverMaxIterations;
  double tolerance = defaults::kSolverTolerance;  // residual (m/s), see dynamics/ccp.hpp
  // The overlap a solve may leave, relative to the smaller radius: with
  // the residual, what stops it before max_iterations.
  double penetration_tolerance = defaults::kPenetrationTolerance;
  // What the solve, the guards and the manifold hold each listed contact's
  // linearised overlap to: a safety factor under the tolerance, as a step
  // size controller aims under its error bound. The overlap measured at
  // the next step is more than the linear prediction by the second-order
  // part of each clump's turn (dynamics/safeguards.cpp, limit_spin) and by
  // contacts the manifold left out as out of reach; held to the tolerance
  // itself, a run's worst overlap ends a hair over it.
  double overlap_aim() const { return kOverlapSafety * penetration_tolerance; }
  static constexpr double kOverlapSafety = 0.8;
  double pgs_relaxation = defaults::kSolverRelaxation;  // over-relaxation for projected Gauss-Seidel
  bool warm_start = defaults::kSolverWarmStart;
};

// What two particles' many contacts of one face are reduced to
// (collision/collide.cpp, reduce_manifold). Hold: the deepest, the corners
// of their hull and every member those cannot hold within the overlap aim,
// so that no contact left out can end the step overlapping past it. Four:
// the deepest and the three corners spanning the largest area with it, as
// Box2D and Jolt reduce a face; a member left out may overlap past the
// tolerance until a later step lists it. For scenes whose cost decides.
// A particle's contacts with a body are held whatever the choice.
enum class Manifold { Hold, Four };

struct ContactSettings {
  // Pairs closer than envelope_fraction * (smaller radius) + |v_rel| * step
  // become contacts before they touch (the |v| h term stops tunnelling).
  double envelope_fraction = defaults::kContactEnvelope;
  double recovery_speed = defaults::kRecoverySpeed;  // m/s: cap on the speed of pushing out overlaps
  double restitution_threshold = defaults::kRestitutionThreshold;  // m/s: slower impacts are plastic
  Manifold manifold = Manifold::Hold;
  // A flake meets other particles as the plate its spheres make
  // (FlatFace), face and rim, not with its spheres: flakes stack at their
  // thickness, not nested in each other's hollows, one face's contacts
  // share its normal, so that four of them hold it, and flakes side by
  // side meet at their nearest corners.
  bool flat_faces = false;
};

// Particles carried at rest by a turning body sleep (dynamics/sleep.hpp):
// a flake pinned to the drum rides it out of the solve until the forces on
// it, a neighbour's push or another body near it wake it. Off unless the
// scene's solver.sleep sets it.
struct SleepSettings {
  bool enabled = false;
  double speed = 0.0;  // m/s: slower than this in the body's frame counts as at rest
  double time = 0.0;   // s: at rest this long on the body, a particle sleeps
};

// Contact law: DVI (impulses from the cone complementarity problem, the
// default) or DEM (penalty forces, explicit integration; dynamics/dem.hpp), a
// baseline for the work-precision comparison. Collision detection is shared.
enum class ContactModel { DVI, DEM };

struct ElasticProperties {
  double youngs_modulus = defaults::kDemYoungsModulus;  // Pa; DEM codes soften real moduli to afford the step
  double poisson_ratio = defaults::kDemPoissonRatio;
};

// Hertz-Mindlin settings. Elastic constants are per material (index as in
// MaterialTable; materials past the end use `defaults`), so a steel wall and
// a plastic grain give the right effective modulus E*. Friction and
// restitution come from the MaterialTable, as for DVI, so both models see
// the same pair coefficients.
struct DemSettings {
  ElasticProperties defaults;
  std::vector<ElasticProperties> materials;
  // e -> 0 needs unbounded damping, which no explicit step resolves: lower
  // restitutions (the material default is 0) are raised to this.
  double min_restitution = ces::defaults::kDemMinRestitution;
  const ElasticProperties& elastic(int material) const {
    return std::size_t(material) < materials.size() ? materials[std::size_t(material)] : defaults;
  }
};

struct Model;
// Mass of a particle of `shape` at `scale` made of `material` (kg).
double particle_mass(const Model& model, int shape, double scale, int material);

struct Model {
  double step = 1e-3;  // s
  Vec3 gravity = Vec3(0, -9.81, 0);
  MaterialTable materials;
  std::vector<ParticleShape> shapes;
  std::vector<RigidBody> bodies;
  std::vector<Joint> joints;
  std::vector<Motor> motors;
  SolverSettings solver;
  ContactSettings contact;
  SleepSettings sleep;
  ContactModel contact_model = ContactModel::DVI;
  DemSettings dem;
  int threads = 0;  // 0: OpenMP default
  // Every this many steps the particles are sorted along a Morton curve, so
  // neighbours sit near each other in memory (0: never); only from
  // reorder_min_particles on, where the arrays outgrow the caches.
  int reorder_interval = 64;
  std::size_t reorder_min_particles = 4096;
};

}  // namespace ces
