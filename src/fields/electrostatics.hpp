// Charging and electric forces: a force stage (sim/world.hpp runs it after
// this step's collision and before its solve), so charges and forces come
// from this step's positions and contacts, never the previous step's.
//
// Plain data in, a stage out: a scene compiler fills the specs. Frame as in
// fields/electric.hpp: drum axis = z through the origin, gravity −y.
//
// Particles take the laws of spheres (the sphere of their volume, from
// their mass and density), except that a flat shape lying flat over the
// drum charges, is pinned and is lifted as a flake (ShapeElectrics below).
// Forces act at the centre of mass (no torque). Every particle is updated by its own loop
// iteration, so charges and forces are bitwise the same for any thread count.
#pragma once
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include "collision/contacts.hpp"
#include "fields/charge.hpp"
#include "fields/corona.hpp"
#include "fields/electric.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces::fields {

// How a particle shape lies on the drum, at scale 1 (lengths scale with
// Particles::scale, areas with its square).
//
// Compact shapes (spheres, grains, rods, most clusters) take the laws of
// the sphere of their volume, r = (3V/4π)^⅓ with V = mass / density:
// Pauthenier's Q_s = 4π ε0 r² p E, the image force Q² / (4π ε0 εr (2r)²)
// of a charge at the centre, Lebedev and Skal'skaya's induced charge and
// lift (docs/physics.md §5).
//
// Flat shapes (the built-in flake up to aspect 0.6; any cluster at least
// 1.5 times as wide as thick both ways across its thinnest principal axis,
// so t/a <= 1.33, inside the Laplace table of fields/charge.hpp) lying flat
// over the drum, tilted by less than the angle at which the rim lifts off
// by the shape's thickness (sin α = t/W), take the laws of a flat flake
// (FlatFlake) of face area A and thickness t = V/A:
//  - face_area A: the shadow of its spheres on the plane across that axis,
//    the face that lies on the drum (0.60 for the unit flake of aspect 0.2,
//    2.10 d² in its equal-volume diameter d);
//  - an insulator charges to flake_saturation_charge at the gap under it
//    (or the sphere's, where that is more) and is pulled by
//    flat_image_force with flake_image_factor;
//  - a conductor takes flat_conductor_charge and flat_conductor_lift.
// The volume comes from the particle's mass, not from its shape: a feed
// that draws flake dimensions gives a thin flake the contact geometry of a
// thicker one (feed/feed.hpp) but its own mass, and so its own thickness.
struct ShapeElectrics {
  double face_area = 0.0;            // A (m² at scale 1); 0: a compact shape
  Vec3 face_normal = Vec3::UnitZ();  // flat shapes: normal of the face, principal frame
  double flat_cos = 1.0;             // lying flat when |face_normal · n_drum| >= flat_cos
};

ShapeElectrics shape_electrics(const ParticleShape& shape);

// The area of a shape's shadow on the plane across its thinnest principal
// axis (the union of its spheres' discs, counted on a 512 x 512 grid:
// within 0.1 % for a disc), at scale 1.
double footprint_area(const ParticleShape& shape);

inline constexpr double kNoDecay = std::numeric_limits<double>::infinity();

// Electrical behaviour of one material. The metal fraction w makes the kind:
// w = 1 a conductor (induced charge on the drum), w = 0 an insulator (corona
// charge, decay, brush), in between a mixed particle (e.g. a PCB fragment)
// that carries both charges and feels the w-weighted average of the two
// forces (docs/physics.md §5).
struct ElectricalMaterial {
  double metal_fraction = 0.0;         // w in [0, 1]
  double relative_permittivity = 1.0;  // εr of the insulating part (Pauthenier)
  double decay_time = kNoDecay;        // τ of the insulating charge, s; 0 or ∞: none

  static ElectricalMaterial conductor() { return {1.0, 1.0, kNoDecay}; }
  static ElectricalMaterial insulator(double eps_r, double tau = kNoDecay) {
    return {0.0, eps_r, tau};
  }
  static ElectricalMaterial mixed(double w, double eps_r, double tau = kNoDecay) {
    return {w, eps_r, tau};
  }
};

enum class CoronaCharging {
  Saturation,  // the seed's model: the charge jumps to Q_s on entry
  Pauthenier,  // Q(t) = Q_s t / (t + τ_c), advanced exactly each step
};

// Where insulating material takes corona charge: the polar sector from
// angle_begin counter-clockwise to angle_end (rad, from +x about the drum
// axis, as Electrode::at_polar), no farther than `depth` above the drum
// surface, within the drum's width.
struct CoronaZone {
  double angle_begin = 0.0;  // rad
  double angle_end = 0.0;    // rad, angle_begin < angle_end <= angle_begin + 2π
  double depth = 0.0;        // m above the drum surface
  CoronaCharging mode = CoronaCharging::Pauthenier;
  // |E| that charges the particle, V/m; unset: the field model's |E| at the
  // particle (the static-electrode field has no corona space charge).
  std::optional<double> field;
  double current_density = 0.0;   // J, A/m² (Pauthenier only; a scene must give it)
  double ion_sign = -1.0;         // polarity of the corona ions: ±1
};

// Charging and electric forces (docs/physics.md §4-5). Per particle and step:
//  - the field E: the field model's at the particle's centre; inside the
//    band of a corona wire, scaled up to √(E_L² + E_sc²) along the same
//    direction by the space charge of its ions (Deutsch's assumption).
//  - metal part: while touching the grounded drum, its induced charge and
//    lift along n (the contact normal out of the drum) follow E·n (flat
//    flake or sphere laws); off the drum, the last charge is kept and the
//    force is Q E.
//  - insulating part: decays by exp(−h/τ), charges in a corona zone or band
//    (Pauthenier growth toward the flat-flake or sphere saturation charge in
//    |E|, τ_c = 4 ε0 |E| / J; flat over the nearest drum surface, at the
//    gap under it), is zeroed by a touch of the brush; the force
//    is Q E, plus the image force along −n of the drum surface nearest it
//    (from the geometry, gap g, within one drum radius: nearest_drum):
//    the sphere law with its charge r + g from the drum, or for a flake
//    lying flat over the drum the face law bridged to a point charge far
//    off (flat_image_force). The image force does not wait for a touch
//    because the relaxed contact model makes a particle that lands sliding
//    hop by a fraction of a millimetre, while its charge keeps pulling it
//    back.
// "Touching" is decided from this step's contacts: a gap below 1 % of the
// sphere radius, plus the chord sag a particle carried by a turning body
// shows at the start of a step, plus the lift 2 μ |v_t| h the relaxed cone
// complementarity gives a contact sliding at v_t (see electrostatics.cpp). E is zero where
// |z| > drum.half_width whatever the field model returns: no corona
// charging and no electric force there (a conductor touching the drum
// there discharges). Decay and the brush act everywhere.
//
// Where the charges live: Particles::charge holds a conductor's induced
// charge and an insulator's or mixed particle's insulating charge (a scene
// may preset it); Particles::metal_charge the induced charge of a mixed
// particle's metal part.
struct ElectrostaticsSpec {
  // The field model has no default, so it is the one constructor argument.
  explicit ElectrostaticsSpec(ElectricField model) : field(std::move(model)) {}

  ElectricField field;
  Drum drum;                       // radius (corona depth) and half-width (forces off beyond)
  int drum_body = 0;               // Model::bodies index of the grounded drum
  std::optional<int> brush_body;   // Model::bodies index of the brush
  std::vector<CoronaZone> corona;  // sectors set by hand; may be empty
  std::vector<CoronaBand> bands;   // the corona wires' bands; may be empty
  std::vector<ElectricalMaterial> materials;  // one per Model material, same order
  double medium_relative_permittivity = Air{}.relative_permittivity;
};

// The drum surface nearest a particle: the gap of its closest sphere and
// the outward normal there; none found beyond one drum radius.
struct DrumGap {
  Vec3 normal = Vec3::Zero();
  double gap = std::numeric_limits<double>::infinity();
  bool found() const { return gap < std::numeric_limits<double>::infinity(); }
};

// The stage: reads this step's contacts, the bodies' motion and the
// particles' position, orientation, velocity, shape, scale and material;
// writes their charge, metal_charge and force.
class ElectrostaticsStage {
 public:
  // Throws std::invalid_argument naming the offending field when the spec
  // does not fit the model (body indices, material count, ranges).
  ElectrostaticsStage(ElectrostaticsSpec spec, const Model& model);
  void apply(const Model& model, const Contacts& contacts, const Bodies& bodies,
             Particles& particles);

 private:
  // Where one particle is this step, as its charges see it (electrostatics.cpp).
  struct Site;

  void find_touches(const Model& model, const Contacts& c, const Bodies& bodies,
                    const Particles& p);
  void touch(const Model& model, const Contacts& c, std::size_t k, bool on_drum,
             const Bodies& bodies, const Particles& p);
  const ElectricalMaterial& material(const Particles& p, std::size_t i) const;
  DrumGap nearest_drum(const ParticleShape& s, const Particles& p, std::size_t i) const;
  Site site(const Model& model, const Particles& p, std::size_t i, const Contacts& c) const;
  void update(const Model& model, Particles& p, std::size_t i, const Contacts& c,
              double h) const;
  Vec3 field_at(const Vec3& x, double& current_density) const;
  double saturation_charge(const Site& at, double eps_r, double field) const;
  Vec3 metal_part(double& charge, const Site& at) const;
  Vec3 insulating_part(double& charge, const ElectricalMaterial& m, const Site& at,
                       double h) const;

  ElectrostaticsSpec spec_;
  std::vector<ShapeElectrics> shapes_;      // per Model shape
  std::vector<double> density_;             // per Model material
  std::vector<std::int32_t> drum_contact_;  // per particle: touching drum contact, or -1
  std::vector<std::uint8_t> brush_touch_;   // per particle
  std::vector<DrumGap> carried_;            // per particle asleep on the drum: its nearest drum
};

}  // namespace ces::fields
