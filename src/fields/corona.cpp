#include "fields/corona.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "fields/charge.hpp"

namespace ces::fields {
namespace {

// The band reaches 3 S from the foot, where J is 1.8 % of J0.
constexpr double kBandReach = 3.0;
// Points on the wire surface at which its field is sampled for the onset.
constexpr int kSurfacePoints = 32;

std::string kilovolts(double v) {
  std::ostringstream s;
  s.precision(3);
  s << v / 1e3 << " kV";
  return s.str();
}

// Largest Laplace field on the wire's surface.
double wire_surface_field(const LineChargeField& field, const Electrode& wire) {
  double largest = 0.0;
  for (int k = 0; k < kSurfacePoints; ++k) {
    const double phi = 2.0 * kPi * k / kSurfacePoints;
    const Vec2 p = wire.centre + wire.radius * Vec2(std::cos(phi), std::sin(phi));
    largest = std::max(largest, field.field(Vec3(p.x(), p.y(), 0.0)).norm());
  }
  return largest;
}

}  // namespace

double peek_onset_field(double wire_radius, double air_density) {
  return 3.1e6 * air_density * (1.0 + 0.0308 / std::sqrt(air_density * wire_radius));
}

double townsend_current(double voltage, double onset_voltage, double wire_radius, double height,
                        double mobility) {
  const double u = std::abs(voltage), u0 = std::abs(onset_voltage);
  if (u <= u0) return 0.0;
  const double rc = 2.0 * height;
  return 8.0 * kPi * kVacuumPermittivity * mobility * u * (u - u0) /
         (rc * rc * std::log(rc / wire_radius));
}

double band_exponent() { return 2.0 * std::log(2.0) / std::log(1.0 + 0.7 * 0.7); }

double band_width_factor() {
  const double m = band_exponent();
  return std::sqrt(kPi) * std::tgamma(0.5 * (m - 1.0)) / std::tgamma(0.5 * m);
}

double band_current_density(double peak, double height, double s) {
  const double h2 = height * height;
  return peak * std::pow(h2 / (h2 + s * s), 0.5 * band_exponent());
}

double band_peak_current_density(double current, double height) {
  return current / (band_width_factor() * height);
}

double space_charge_field(double current, double mobility) {
  return std::sqrt(current / (2.0 * kPi * kVacuumPermittivity * mobility));
}

bool CoronaBand::covers(const Vec3& x) const {
  const double r = std::hypot(x.x(), x.y());
  if (r - drum_radius > height) return false;
  const double turn = std::remainder(std::atan2(x.y(), x.x()) - foot_angle, 2.0 * kPi);
  return std::abs(turn) * drum_radius <= kBandReach * height;
}

double CoronaBand::current_density(const Vec3& x) const {
  if (!covers(x)) return 0.0;
  const double s = std::remainder(std::atan2(x.y(), x.x()) - foot_angle, 2.0 * kPi) * drum_radius;
  return band_current_density(peak_current_density, height, s);
}

double CoronaBand::space_charge_field(const Vec3& x) const {
  if (peak_current_density <= 0.0) return 0.0;
  return space_charge * std::sqrt(current_density(x) / peak_current_density);
}

CoronaBand corona_band(const Drum& drum, const LineChargeField& field, const CoronaWire& wire) {
  const Electrode& e = wire.electrode;
  if (!(wire.mobility > 0.0)) throw std::invalid_argument("the ion mobility must be positive");
  if (!(wire.air_density > 0.0))
    throw std::invalid_argument("the relative air density must be positive");
  CoronaBand b;
  b.drum_radius = drum.radius;
  b.foot_angle = std::atan2(e.centre.y(), e.centre.x());
  b.height = e.centre.norm() - drum.radius;
  b.onset_field = peek_onset_field(e.radius, wire.air_density);
  b.surface_field = wire_surface_field(field, e);
  b.onset_voltage = std::abs(e.potential) * b.onset_field / b.surface_field;
  if (!(std::abs(e.potential) > b.onset_voltage))
    throw std::invalid_argument("at " + kilovolts(std::abs(e.potential)) +
                                " the wire is below its corona onset of " +
                                kilovolts(b.onset_voltage) + " (Peek's " +
                                kilovolts(b.onset_field / 1e2) + "/cm at its surface)");
  b.current = townsend_current(e.potential, b.onset_voltage, e.radius, b.height, wire.mobility);
  b.peak_current_density = band_peak_current_density(b.current, b.height);
  b.space_charge = fields::space_charge_field(b.current, wire.mobility);
  b.ion_sign = e.potential < 0.0 ? -1.0 : 1.0;
  return b;
}

}  // namespace ces::fields
