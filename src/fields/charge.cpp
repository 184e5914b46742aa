#include "fields/charge.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>

namespace ces::fields {
namespace {

constexpr double kEps0 = kVacuumPermittivity;
constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Above this Reynolds number Schiller–Naumann uses the Newton-regime Cd.
constexpr double kNewtonReynolds = 1000.0;
constexpr double kNewtonCd = 0.44;

}  // namespace

double conductor_induced_charge(double radius, double normal_field, double eps_r_medium) {
  return (2.0 / 3.0) * kPi * kPi * kPi * kEps0 * eps_r_medium * radius * radius * normal_field;
}

double conductor_lift_force(double charge, double normal_field) {
  return 0.832 * charge * normal_field;
}

double pauthenier_factor(double eps_r_particle) {
  return 3.0 * eps_r_particle / (eps_r_particle + 2.0);
}

double pauthenier_saturation_charge(double radius, double eps_r_particle, double field) {
  return 4.0 * kPi * kEps0 * radius * radius * pauthenier_factor(eps_r_particle) * std::abs(field);
}

double pauthenier_time_constant(double field, double current_density) {
  return 4.0 * kEps0 * std::abs(field) / current_density;
}

double pauthenier_charge(double saturation_charge, double time_constant, double t) {
  return saturation_charge * t / (t + time_constant);
}

double pauthenier_growth(double charge, double saturation, double tau, double dt) {
  if (saturation == 0.0 || !(tau < kInfinity) || dt <= 0.0) return charge;
  // In units of Q_s: q = t/(t + τ) gives t = τ q/(1 − q); substituting
  // t + dt back and clearing the (1 − q) denominators gives this form,
  // which stays finite as q → 1.
  const double q = charge / saturation;
  if (q >= 1.0) return charge;
  const double advanced = dt * (1.0 - q);
  return saturation * (tau * q + advanced) / (tau + advanced);
}

double pauthenier_step(double charge, double radius, double eps_r_particle, const Corona& corona,
                       double dt) {
  if (corona.current_density <= 0.0 || corona.field == 0.0) return charge;
  const double magnitude = pauthenier_saturation_charge(radius, eps_r_particle, corona.field);
  return pauthenier_growth(charge, corona.ion_sign < 0.0 ? -magnitude : magnitude,
                           pauthenier_time_constant(corona.field, corona.current_density), dt);
}

// ------------------------------------------------------------ flat flakes --

double FlatFlake::radius() const { return std::sqrt(face_area / kPi); }
double FlatFlake::thinness() const { return thickness / radius(); }

namespace {

// The axisymmetric Laplace solve of a flake (radius a, thickness t = x a)
// lying on a grounded plane in a uniform normal field E far above it
// (cells down to a/500 at the rim and the faces, domain 30 a).
// tests/flake_laplace_test.cpp solves it again at x = 0.1, 0.4 and 1 on a
// coarser grid and takes the pulls as the Maxwell stress over a surface
// round the flake: the charges agree to 4 %, the insulator's image factor
// (flake_image_factor) to 2 %; the conductor's lift is 3-6 % under the
// stress integral, and the insulator's top pull about a fifth under it, a
// part of at most 3 % of an FR-4 flake's pull (docs/physics.md, sections
// 5.1 and 5.5, give what they move). Per row, x and:
//  - insulator at Pauthenier saturation (zero normal field on the air side
//    of its top and rim, so no field line ends there): the charge over the
//    thin-plate Q_s; the pull over its thin-plate limit εr² ε0 E² a⁴/(π t²),
//    for the part of the Maxwell stress across the contact gap (∝ εr²); and
//    the part from the tangential field over the top face, in ε0 E² a²;
//  - conductor (at the plane's potential): the charge over ε0 E A and the
//    lift over ½ ε0 E² A.
struct FlakeRow {
  double x;
  double insulator_charge, insulator_gap_pull, insulator_top_pull;
  double conductor_charge, conductor_lift;
};
constexpr FlakeRow kFlakeTable[] = {
    {0.01, 1.05762, 1.09837, 2.43744, 1.04799, 1.07596},
    {0.02, 1.10014, 1.17786, 2.20654, 1.08863, 1.14059},
    {0.05, 1.20703, 1.39680, 1.89230, 1.19855, 1.31371},
    {0.10, 1.35493, 1.73934, 1.70109, 1.36710, 1.57844},
    {0.15, 1.48385, 2.07204, 1.63505, 1.52889, 1.83833},
    {0.20, 1.60132, 2.40109, 1.51073, 1.68824, 2.07737},
    {0.30, 1.81424, 3.05673, 1.51133, 2.00571, 2.60164},
    {0.40, 2.00869, 3.71913, 1.43101, 2.32628, 3.10065},
    {0.50, 2.19206, 4.39829, 1.38693, 2.65239, 3.61540},
    {0.60, 2.36904, 5.10483, 1.39345, 2.98523, 4.16894},
    {0.80, 2.71644, 6.64532, 1.36704, 3.67341, 5.28927},
    {1.00, 3.06868, 8.42740, 1.35046, 4.39310, 6.46880},
    {1.25, 3.52918, 11.10154, 1.33708, 5.33780, 8.02710},
    {1.50, 4.01677, 14.35664, 1.32825, 6.33243, 9.67739},
    {2.00, 5.06206, 22.78052, 1.31755, 8.46863, 13.24671},
};

// Column `field` of the table at thinness x, linear between rows; below
// the first row the ratios (thin-plate limit 1) run linearly to 1 at x = 0
// and the top pull stays at its first value; beyond the last row, the
// last row's value.
double flake_ratio(double x, double FlakeRow::*field, bool ratio = true) {
  const auto rows = std::size(kFlakeTable);
  const FlakeRow& first = kFlakeTable[0];
  if (x <= first.x) return ratio ? 1.0 + (first.*field - 1.0) * std::max(x, 0.0) / first.x : first.*field;
  for (std::size_t k = 1; k < rows; ++k) {
    const FlakeRow& lo = kFlakeTable[k - 1];
    const FlakeRow& hi = kFlakeTable[k];
    if (x <= hi.x) return lo.*field + (hi.*field - lo.*field) * (x - lo.x) / (hi.x - lo.x);
  }
  return kFlakeTable[rows - 1].*field;
}

}  // namespace

double thin_flake_saturation_charge(const FlatFlake& f, double eps_r_particle, double field) {
  const double a = f.radius();
  return (4.0 / 3.0) * eps_r_particle * kEps0 * std::abs(field) * a * a * a / f.thickness;
}

double flake_saturation_charge(const FlatFlake& f, double eps_r_particle, double field,
                               double gap) {
  return flake_ratio(f.thinness(), &FlakeRow::insulator_charge) *
         thin_flake_saturation_charge(f, eps_r_particle, field) /
         (1.0 + eps_r_particle * std::max(0.0, gap) / f.thickness);
}

// Per unit ε0 E² a²: the total pull P = εr² g/(π x²) + top, the charge
// q = εr (4/3) c/x; κ Q²/(2 ε0 A) + Q E = P gives κ = 2π (P − q)/q².
double flake_image_factor(const FlatFlake& f, double eps_r_particle) {
  const double x = f.thinness();
  const double q = eps_r_particle * (4.0 / 3.0) * flake_ratio(x, &FlakeRow::insulator_charge) / x;
  const double pull =
      eps_r_particle * eps_r_particle * flake_ratio(x, &FlakeRow::insulator_gap_pull) / (kPi * x * x) +
      flake_ratio(x, &FlakeRow::insulator_top_pull, false);
  return std::max(0.0, 2.0 * kPi * (pull - q) / (q * q));
}

double flat_conductor_charge(const FlatFlake& f, double normal_field, double eps_r_medium) {
  return flake_ratio(f.thinness(), &FlakeRow::conductor_charge) * kEps0 * eps_r_medium *
         normal_field * f.face_area;
}

double flat_conductor_lift(const FlatFlake& f, double normal_field, double eps_r_medium) {
  return flake_ratio(f.thinness(), &FlakeRow::conductor_lift) * 0.5 * kEps0 * eps_r_medium *
         normal_field * normal_field * f.face_area;
}

double relaxation_time(double eps_r_particle, double volume_resistivity) {
  return kEps0 * eps_r_particle * volume_resistivity;
}

double decay_step(double charge, double tau, double dt) { return charge * std::exp(-dt / tau); }

double image_force(double charge, double radius, double eps_r_medium) {
  const double separation = 2.0 * radius;  // charge at the centre, image as far behind the wall
  return charge * charge / (4.0 * kPi * kEps0 * eps_r_medium * separation * separation);
}

double flat_image_force(double charge, double face_area, double eps_r_medium, double gap,
                        double kappa) {
  if (kappa <= 0.0) return 0.0;
  // (2g)² + A/(2π κ): at g = 0, 4π ε0 εr A/(2π κ) = 2 ε0 εr A/κ.
  const double spread = 4.0 * gap * gap + face_area / (2.0 * kPi * kappa);
  return charge * charge / (4.0 * kPi * kEps0 * eps_r_medium * spread);
}

double reynolds_number(double speed, double radius, const Air& air) {
  return air.density * speed * 2.0 * radius / air.viscosity;
}

double schiller_naumann_cd(double reynolds) {
  if (reynolds >= kNewtonReynolds) return kNewtonCd;
  return 24.0 / reynolds * (1.0 + 0.15 * std::pow(reynolds, 0.687));
}

Vec3 stokes_drag(const Vec3& relative_velocity, double radius, const Air& air) {
  return -6.0 * kPi * air.viscosity * radius * relative_velocity;
}

Vec3 schiller_naumann_drag(const Vec3& relative_velocity, double radius, const Air& air) {
  const double speed = relative_velocity.norm();
  const double re = reynolds_number(speed, radius, air);
  if (re >= kNewtonReynolds) {
    return -0.5 * air.density * kNewtonCd * kPi * radius * radius * speed * relative_velocity;
  }
  // ½ ρ (24/Re) π r² |v| = 6π η r: Stokes times the correction, no 1/Re.
  return (1.0 + 0.15 * std::pow(re, 0.687)) * stokes_drag(relative_velocity, radius, air);
}

}  // namespace ces::fields
