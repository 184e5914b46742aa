// Particle charging laws, electric forces and air drag (docs/physics.md §5).
//
// Pure functions of SI quantities (m, s, C, V/m, A/m², N). Radii, not
// diameters, throughout: a √3·r radius slip, once in the seed code's bipolar field, must not
// come back. The caller owns the state (the charge) and the geometry.
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

// What a particle sees inside the corona zone at one instant.
struct Corona {
  double field = 0.0;            // |E| at the particle, V/m
  double current_density = 0.0;  // ion current density J, A/m²
  double ion_sign = -1.0;        // +1 or −1: the corona wire's polarity
};

// Charge after `dt` in the corona, from `charge` now. Exact for a constant
// field: the law is read backwards to the time t at which a neutral
// particle would carry `charge`, then advanced to t + dt. A charge of the
// opposite sign is first neutralised (t < 0); a charge at or beyond
// saturation is left as it is (no ion reaches it). J <= 0 or E = 0: no
// charging.
double pauthenier_step(double charge, double radius, double eps_r_particle, const Corona& corona,
                       double dt);

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
// drum with its charge Q spread over a face of area A, toward the drum:
// F_im = Q² / (2 ε0 εr A) (docs/physics.md §5.5), εr of the
// MEDIUM. It is the pull between a sheet of charge σ = Q/A and its image
// across the thin air gap of the contact, σ² A / (2 ε0): the parallel-plate
// limit, good when the flake is much wider than thick (its charge's field
// lines then nearly all end on the drum under it, whichever face of the
// flake the charge sits on, so it holds for ions on the top face too).
// Lifted off by `gap` (a hop, or a flake riding just above the drum), the
// force is bridged to that of a point charge and its image 2·gap apart:
// F = Q² / (4π ε0 εr ((2 gap)² + A/(2π))) (inference: exact in both
// limits, gap = 0 and gap >> √A; 80 % of the contact value at gap = 0.1 √A).
double flat_image_force(double charge, double face_area, double eps_r_medium, double gap = 0.0);

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
