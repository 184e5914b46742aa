// The corona wire of a roll separator as an ion source (docs/physics.md §4):
// its onset (Peek), its current per unit length (Townsend), the band of
// current density it lays on the roll (Gallo & Lama) and the field of the
// ion space charge there (Deutsch). Pure functions of SI quantities (m, V,
// A, m²/(V s)), and the band a scene's wire makes over the drum.
#pragma once
#include "common/math.hpp"
#include "fields/electric.hpp"

namespace ces::fields {

// Peek's onset field at the surface of a smooth round wire of radius a in
// air of relative density δ (1 at 20 °C and 1 atm):
// E_c = 3.1e6 δ (1 + 0.0308/√(δ a)) V/m, a in m (docs/physics.md §4.2).
double peek_onset_field(double wire_radius, double air_density = 1.0);

// Townsend's current per unit wire length I' = 8π ε0 μ U (U − V0) /
// (Rc² ln(Rc/a)) for a wire at |U| above its onset |V0| (0 below), with
// the coaxial radius Rc = 2H of a wire a height H above a grounded surface
// (docs/physics.md §4.3), A/m.
double townsend_current(double voltage, double onset_voltage, double wire_radius, double height,
                        double mobility);

// Gallo & Lama's band: the current density on the grounded surface a
// distance s from the foot of a wire at height S is J0 [S²/(S² + s²)]^(m/2),
// m = 2 ln 2 / ln(1 + 0.7²) so that its full width at half maximum is 1.4 S
// (docs/physics.md §4.4).
double band_exponent();
// ∫ J ds over the band, per unit J0 and S: √π Γ((m − 1)/2) / Γ(m/2).
double band_width_factor();
double band_current_density(double peak, double height, double s);
// J0 of a band carrying `current` per unit length.
double band_peak_current_density(double current, double height);

// Deutsch's space-charge field far from the wire, E_sc = √(I' / (2π ε0 μ))
// (docs/physics.md §4.5), V/m.
double space_charge_field(double current, double mobility);

// A corona wire as a scene states it: one of the line-charge field's
// electrodes, the mobility of its ions, the relative air density.
struct CoronaWire {
  Electrode electrode;
  double mobility = 0.0;      // μ, m²/(V s)
  double air_density = 1.0;   // δ
};

// What the wire lays on the drum (docs/physics.md §4): derived once from
// the wire and the field of all the electrodes at their voltages.
struct CoronaBand {
  double foot_angle = 0.0;      // polar angle of the wire's foot on the drum, rad
  double height = 0.0;          // S = H: wire axis to drum surface, m
  double onset_field = 0.0;     // Peek's E_c, V/m
  double surface_field = 0.0;   // Laplace field at the wire surface (its largest), V/m
  double onset_voltage = 0.0;   // |V0|: all electrodes scaled together until E = E_c, V
  double current = 0.0;         // I', A/m
  double peak_current_density = 0.0;  // J0, A/m²
  double space_charge = 0.0;    // E_sc at the foot, V/m
  double ion_sign = -1.0;       // the wire's polarity
  double drum_radius = 0.0;     // m

  // The band covers the drum within 3 S of the foot along its surface
  // (where J has fallen to 1.8 % of J0) and up to S above it.
  bool covers(const Vec3& x) const;
  // J and E_sc at x (E_sc² follows J, as Deutsch's E² = J r/(ε0 μ) along a
  // field line); zero outside the band.
  double current_density(const Vec3& x) const;
  double space_charge_field(const Vec3& x) const;
};

// The band of `wire` over `drum` in `field` (the line-charge field of all
// the electrodes, the wire among them). Throws std::invalid_argument for a
// wire that does not ionise (|U| <= V0) or a non-positive mobility.
CoronaBand corona_band(const Drum& drum, const LineChargeField& field, const CoronaWire& wire);

}  // namespace ces::fields
