#include "fields/charge.hpp"

#include <cmath>

namespace ces::fields {
namespace {

constexpr double kEps0 = kVacuumPermittivity;

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

double pauthenier_step(double charge, double radius, double eps_r_particle, const Corona& corona,
                       double dt) {
  if (corona.current_density <= 0.0 || corona.field == 0.0 || dt <= 0.0) return charge;
  const double magnitude = pauthenier_saturation_charge(radius, eps_r_particle, corona.field);
  const double saturation = corona.ion_sign < 0.0 ? -magnitude : magnitude;
  const double tau = pauthenier_time_constant(corona.field, corona.current_density);
  // In units of Q_s: q = t/(t + τ) gives t = τ q/(1 − q); substituting
  // t + dt back and clearing the (1 − q) denominators gives this form,
  // which stays finite as q → 1.
  const double q = charge / saturation;
  if (q >= 1.0) return charge;
  const double advanced = dt * (1.0 - q);
  return saturation * (tau * q + advanced) / (tau + advanced);
}

double relaxation_time(double eps_r_particle, double volume_resistivity) {
  return kEps0 * eps_r_particle * volume_resistivity;
}

double decay_step(double charge, double tau, double dt) { return charge * std::exp(-dt / tau); }

double image_force(double charge, double radius, double eps_r_medium) {
  const double separation = 2.0 * radius;  // charge at the centre, image as far behind the wall
  return charge * charge / (4.0 * kPi * kEps0 * eps_r_medium * separation * separation);
}

double flat_image_force(double charge, double face_area, double eps_r_medium, double gap) {
  // (2g)² + A/2π: at g = 0, 4π ε0 εr A/2π = 2 ε0 εr A.
  const double spread = 4.0 * gap * gap + face_area / (2.0 * kPi);
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
