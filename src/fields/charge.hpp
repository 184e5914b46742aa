// Particle charging laws, electric forces and air drag (docs/physics.md §5).
//
// Pure functions of SI quantities (m, s, C, V/m, A/m², N). Radii, not
// diameters, throughout, so that no law mixes the two. The caller owns the
// state (the charge) and the geometry.
#pragma once
#include "common/math.hpp"
#include "model/defaults.hpp"

namespace ces::fields {

inline constexpr double kVacuumPermittivity = 8.8541878128e-12;  // ε0, F/m

// The carrier gas (docs/physics.md §6 gives the values for air).
struct Air {
  double density = defaults::kAirDensity;                        // ρa, kg/m³
  double viscosity = defaults::kAirViscosity;                    // η, Pa·s
  double relative_permittivity = defaults::kMediumPermittivity;  // εr of the medium
};

// ----------------------------------------------------------- conductors --

// Charge induced on a conducting sphere of `radius` resting on the grounded
// drum, in the normal field `normal_field` = E·n (n: outward drum normal)
// of a medium with `eps_r_medium`: Q_c = (2/3) π³ ε0 εr r² E (docs/physics.md §5).
// Q_c has the sign of E·n. Conductors relax in ~1e-19 s, so this is the
// charge at any instant of contact; freeze it at lift-off.
double conductor_induced_charge(double radius, double normal_field, double eps_r_medium);

// Lifting force along the outward drum normal on that sphere:
// F_e = 0.832 Q_c E (docs/physics.md §5). With Q_c from the same field it is
// >= 0 whatever the polarity: metals are pulled toward the electrode.
double conductor_lift_force(double charge, double normal_field);

// --------------------------------------------------- insulators: corona --

// Pauthenier field-enhancement factor p = 3 εr / (εr + 2) of a particle.
double pauthenier_factor(double eps_r_particle);

// Saturation charge magnitude Q_s = 4π ε0 r² p |E| (docs/physics.md §5); the sign
// is that of the corona ions.
double pauthenier_saturation_charge(double radius, double eps_r_particle, double field);

// Charging time constant τ_c = 4 ε0 |E| / J (docs/physics.md §5), s.
double pauthenier_time_constant(double field, double current_density);

// Closed form Q(t) = Q_s t / (t + τ_c) for an initially neutral particle
// in a constant field.
double pauthenier_charge(double saturation_charge, double time_constant, double t);

// Charge after `dt` of Pauthenier growth toward the signed `saturation` with
// time constant `tau`, from `charge` now. Exact for a constant field: the
// law is read backwards to the time t at which a neutral particle would
// carry `charge`, then advanced to t + dt. A charge of the opposite sign is
// first neutralised (t < 0); a charge at or beyond saturation is left as it
// is (no ion reaches it). saturation = 0 or tau = ∞: no charging.
double pauthenier_growth(double charge, double saturation, double tau, double dt);

// What a particle sees inside the corona zone at one instant.
struct Corona {
  double field = 0.0;            // |E| at the particle, V/m
  double current_density = 0.0;  // ion current density J, A/m²
  double ion_sign = -1.0;        // +1 or −1: the corona wire's polarity
};

// A sphere's charge after `dt` in the corona (pauthenier_growth toward its
// Q_s with τ_c). J <= 0 or E = 0: no charging.
double pauthenier_step(double charge, double radius, double eps_r_particle, const Corona& corona,
                       double dt);

// ------------------------------------------- flat flakes lying on the drum --

// A flake lying flat on the grounded drum, as the charging laws see it: the
// disc of its face area A = π a² and its thickness t (= volume / A).
struct FlatFlake {
  double face_area = 0.0;  // A, m²
  double thickness = 0.0;  // t, m
  double radius() const;   // a = √(A/π)
  double thinness() const; // x = t / a
};

// Saturation charge magnitude of an insulating flake lying flat on the
// grounded drum in the normal field |E| (docs/physics.md §5.3): ions land
// until no field line ends on its exposed faces. Thin-plate limit
// Q_s = (4/3) εr ε0 |E| a³/t (thin_flake_saturation_charge), times the
// ratio the axisymmetric Laplace solve gives for its t/a (tabulated; 1.06
// at t/a = 0.01, 1.93 at 0.36, 3.07 at 1; the solve is in
// tests/flake_laplace_test.cpp). Sign: that of the corona ions.
// Raised by `gap` off the drum, its face still parallel to it, the flake
// and the air under it hold the face's flux in series, which divides σ by
// 1 + εr gap/t (valid for gap + t << a; for a thick flake it scales the
// Laplace solve's charge, rim included, by the same factor).
double flake_saturation_charge(const FlatFlake& flake, double eps_r_particle, double field,
                               double gap = 0.0);
double thin_flake_saturation_charge(const FlatFlake& flake, double eps_r_particle, double field);

// κ of the flat image law (flat_image_force) for an insulating flake of
// permittivity εr charged to saturation lying flat: the share of the pull
// that is its own, so that κ Q_s²/(2 ε0 A) + Q_s |E| is the total pull the
// Laplace solve gives at saturation (docs/physics.md §5.5). 9/8 in the
// thin-plate limit (σ ∝ √(a² − ρ²)); 0.85 at t/a = 0.36 and 0.68 at 1 for
// FR-4; never below 0.
double flake_image_factor(const FlatFlake& flake, double eps_r_particle);
inline constexpr double kThinFlakeImageFactor = 9.0 / 8.0;

// A conducting flake lying flat on the grounded drum in the normal field
// E·n (docs/physics.md §5.1): the charge Q_c = ε0 εr E A and the lift
// ½ ε0 εr E² A along n of the roll's own surface charge on its top face
// (Gauss's law, t << a), times the ratios the Laplace solve gives for its
// t/a (tabulated; 1.20 and 1.31 at t/a = 0.05, 2.33 and 3.10 at 0.4). Q_c
// has the sign of E·n; the lift is >= 0.
double flat_conductor_charge(const FlatFlake& flake, double normal_field, double eps_r_medium);
double flat_conductor_lift(const FlatFlake& flake, double normal_field, double eps_r_medium);

// ----------------------------------------------- insulators: relaxation --

// Charge relaxation time τ = ε0 εr ρ_v (docs/physics.md §5): ~39 s for FR-4.
double relaxation_time(double eps_r_particle, double volume_resistivity);

// Q · exp(−dt/τ): exact for any step; an infinite τ keeps the charge.
double decay_step(double charge, double tau, double dt);

// Image (pinning) force magnitude of a charged sphere on the drum, toward
// the drum: F_im = Q² / (4π ε0 εr (2r)²) (docs/physics.md §5), εr of the MEDIUM
// (air), not of the particle. Its charge is at the centre, r from the drum;
// for a sphere a gap g off the drum pass r + g (charge and image 2(r + g)
// apart).
double image_force(double charge, double radius, double eps_r_medium);

// Image (pinning) force magnitude of a flat insulating flake lying on the
// drum with its charge Q on a face of area A, toward the drum:
// F_im = κ Q² / (2 ε0 εr A) (docs/physics.md §5.5), εr of the MEDIUM. For
// a thin flake it is the Maxwell stress ∫σ²/(2ε0) dA across the thin air
// gap of the contact, where the field is σ/ε0 (all the flake's flux ends
// on the drum under it): κ = 1 for a uniform σ, 9/8 for the saturated
// σ ∝ √(a² − ρ²); flake_image_factor gives κ for a thicker flake.
// Lifted off by `gap` (a hop, or a flake riding just above the drum), the
// force is bridged to that of a point charge and its image 2·gap apart:
// F = Q² / (4π ε0 εr ((2 gap)² + A/(2π κ))) (inference: exact in both
// limits, gap = 0 and gap >> √A; 80 % of the contact value at gap =
// 0.1 √A for κ = 1). κ <= 0: no pull.
double flat_image_force(double charge, double face_area, double eps_r_medium, double gap = 0.0,
                        double kappa = kThinFlakeImageFactor);

// ----------------------------------------------------------------- drag --

// Particle Reynolds number ρa |v| d / η.
double reynolds_number(double speed, double radius, const Air& air);

// Schiller–Naumann drag coefficient: 24/Re (1 + 0.15 Re^0.687) below
// Re = 1000, 0.44 above (docs/physics.md §6). Re > 0.
double schiller_naumann_cd(double reynolds);

// Stokes drag −6π η r v on a sphere; `relative_velocity` = particle − air.
Vec3 stokes_drag(const Vec3& relative_velocity, double radius, const Air& air);

// Schiller–Naumann drag −½ ρa Cd π r² |v| v (docs/physics.md §6), finite at v = 0;
// `relative_velocity` = particle − air.
Vec3 schiller_naumann_drag(const Vec3& relative_velocity, double radius, const Air& air);

}  // namespace ces::fields
