#pragma once
// Helpers shared by the separator tests (separator_*_test.cpp): the
// reference machine's constants and drum, its field, models and
// electrostatics specs to build worlds on, the closed forms of
// docs/physics.md §5 written out, and probes of the step.
//
// Frame: drum axis = z through the origin, gravity −y. The drum turns
// clockwise seen from +z, so its top moves toward +x, where the electrode
// is (docs/physics.md §2); θ is measured from the top in the direction of rotation.
#include <omp.h>

#include <memory>
#include <vector>

#include "fields/electrostatics.hpp"
#include "sim/world.hpp"

namespace ces::fields::test {

inline constexpr double kG = 9.81;
inline constexpr double kDeg = kPi / 180.0;
inline constexpr double kEps0 = 8.8541878128e-12;
inline constexpr double kEpsAir = 1.0006;
inline constexpr double kDrumRadius = 0.16;  // docs/physics.md §2
inline constexpr double kHalfWidth = 0.15;
inline constexpr double kCopper = 8960.0;  // docs/physics.md §7
inline constexpr double kFr4 = 1850.0;
inline constexpr double kFr4Permittivity = 4.4;

inline double rpm(double n) { return n * 2.0 * kPi / 60.0; }

// Materials: 0 is the drum's steel, the rest are particle materials.
struct MaterialSpec {
  double density;
  double friction;
  ElectricalMaterial electrical;
};

inline constexpr int kSphere = 0;
inline constexpr int kPair = 1;  // two touching unit spheres

std::shared_ptr<Model> make_model(double step, const std::vector<MaterialSpec>& particles,
                                  double drum_friction = 0.5);

std::vector<ElectricalMaterial> electrical(const std::vector<MaterialSpec>& particles);

// The drum, turning at `omega` (rad/s) with its top moving toward +x.
RigidBody drum(double omega);

// Reference machine of docs/physics.md §3.1: static electrode Ø 38 mm, axis 0.267 m
// from the drum axis at 30° above horizontal, −35 kV.
ElectricField reference_field();

// A field that is zero everywhere: isolates the charge-only forces.
ElectricField no_field();

ElectrostaticsSpec electrostatics(ElectricField field, const std::vector<MaterialSpec>& particles);

// Point at distance `rho` from the drum axis, θ from the top toward +x.
Vec3 on_drum(double rho, double theta, double z = 0.0);

// Velocity and spin of a particle carried rigidly by the drum at `x`.
Vec3 carried_velocity(double omega, const Vec3& x);
Vec3 carried_spin(double omega);

double theta_of(const Vec3& x);

// Normal impulse the drum (body 0) passed to particle i in the last step.
double drum_load(const World& w, std::size_t i);

// Conductor sphere on the grounded drum: induced charge and lift force,
// written out from docs/physics.md §5 (not through fields/charge.hpp).
double induced_charge(double r, double en);
double lift_force(double r, double en);
double image_pull(double q, double r);

// The seed's corona zone, within 10° of the top (80-100° counter-clockwise
// from +x) and 5 mm deep, charging to saturation at once in 4.13 kV/cm
// (docs/physics.md §5.5's table).
CoronaZone saturation_zone();

// A one-particle world gains nothing from threads, and the collider's
// parallel regions (no size threshold) make every step wait at barriers,
// which on a loaded machine makes these runs hundreds of times slower.
// Results do not
// depend on the thread count (see the Determinism test).
class SingleThread {
 public:
  SingleThread() { omp_set_num_threads(1); }
  ~SingleThread() { omp_set_num_threads(saved_); }
  SingleThread(const SingleThread&) = delete;
  SingleThread& operator=(const SingleThread&) = delete;

 private:
  int saved_ = omp_get_max_threads();
};

// The forces of this step and where the particles were, read after the
// forces stage.
struct ForceProbe : StepObserver {
  std::vector<Vec3> force, position;
  void after(Stage stage, const World& world) override {
    if (stage != Stage::Forces) return;
    force = world.particles().force;
    position = world.particles().position;
  }
};

}  // namespace ces::fields::test
