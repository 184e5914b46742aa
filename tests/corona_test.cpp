// The corona wire's laws (Peek, Townsend, Gallo and Lama, Deutsch), the
// charging of flat flakes and their pull, the decay of charge, and the
// measured flake population a feed draws, each against its closed form or
// an independent computation (docs/physics.md §4, §5, §7.1).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "feed/feed.hpp"
#include "fields/charge.hpp"
#include "fields/corona.hpp"
#include "fields/electric.hpp"
#include "scene/scene.hpp"

namespace ces::fields {
namespace {

constexpr double kEps0 = kVacuumPermittivity;
constexpr double kMobility = 2.1e-4;  // negative ions in air, m²/(V s)

// ------------------------------------------------------------------ corona

// Peek's law written out: a = 0.1 mm gives 12.65 MV/m at δ = 1; δ scales
// the field and the radius term together.
TEST(Corona, PeekOnsetField) {
  EXPECT_NEAR(peek_onset_field(1e-4), 3.1e6 * (1.0 + 3.08), 1e-9 * 12.65e6);
  EXPECT_NEAR(peek_onset_field(1e-4) / 1e6, 12.65, 0.01);
  EXPECT_NEAR(peek_onset_field(1e-4, 0.9), 3.1e6 * 0.9 * (1.0 + 0.0308 / std::sqrt(0.9e-4)),
              1.0);
}

// Townsend's I' = 8π ε0 μ U(U − V0)/(Rc² ln(Rc/a)), Rc = 2H: 0.570 mA/m at
// 35 kV with V0 = 10.9 kV, H = 50 mm, a = 0.1 mm (docs/physics.md §4.3),
// 0.2 % (written out, 1e-12); none at or below the onset, either polarity.
TEST(Corona, TownsendCurrent) {
  const double rc = 0.1, written_out = 8.0 * kPi * kEps0 * kMobility * 35e3 * (35e3 - 10.9e3) /
                                       (rc * rc * std::log(rc / 1e-4));
  EXPECT_NEAR(townsend_current(35e3, 10.9e3, 1e-4, 0.05, kMobility), written_out, 1e-12 * written_out);
  EXPECT_NEAR(written_out, 0.570e-3, 2e-3 * 0.570e-3);
  EXPECT_EQ(townsend_current(10.9e3, 10.9e3, 1e-4, 0.05, kMobility), 0.0);
  EXPECT_EQ(townsend_current(5e3, 10.9e3, 1e-4, 0.05, kMobility), 0.0);
  EXPECT_DOUBLE_EQ(townsend_current(-35e3, -10.9e3, 1e-4, 0.05, kMobility),
                   townsend_current(35e3, 10.9e3, 1e-4, 0.05, kMobility));
}

// Gallo and Lama's band: J falls to half at s = ±0.7 S (full width at half
// maximum 1.4 S, 1e-12), and its integral across the roll (trapezoids out to
// ±2000 S, where the tail left out is below 1e-5) is the current per unit
// length it was built from (1e-4).
TEST(Corona, BandWidthAndCurrent) {
  const double height = 0.05, current = 0.57e-3;
  const double j0 = band_peak_current_density(current, height);
  EXPECT_NEAR(band_current_density(j0, height, 0.7 * height), 0.5 * j0, 1e-12 * j0);
  EXPECT_NEAR(band_current_density(j0, height, -0.7 * height), 0.5 * j0, 1e-12 * j0);
  const double reach = 2000.0 * height, ds = height / 200.0;
  double sum = 0.0;
  for (double s = -reach; s < reach; s += ds)
    sum += 0.5 * ds * (band_current_density(j0, height, s) + band_current_density(j0, height, s + ds));
  EXPECT_NEAR(sum, current, 1e-4 * current);
  // J0 = I'/(1.761 S) (docs/physics.md §4.4, with m rounded to 3.47: 0.2 %).
  EXPECT_NEAR(band_width_factor(), 1.761, 0.002 * 1.761);
  EXPECT_NEAR(band_exponent(), 3.47, 0.01);
}

// Deutsch's far field E_sc = √(I'/(2π ε0 μ)): 2.21 kV/cm at 0.570 mA/m.
TEST(Corona, SpaceChargeField) {
  EXPECT_NEAR(space_charge_field(0.570e-3, kMobility), 2.209e5, 1e-3 * 2.209e5);
  EXPECT_NEAR(space_charge_field(4.0 * 0.570e-3, kMobility),
              2.0 * space_charge_field(0.570e-3, kMobility), 1e-9);
}

// A wire 50 mm over a roll so large it is a plane: the Laplace field at its
// surface is U/(a ln(2H/a)), so its onset voltage is Peek's field times
// a ln(2H/a) (2 %: the roll's curvature and the 32 surface samples); the
// band's current and space charge are the laws' at that onset; below it
// the band is refused.
TEST(Corona, BandOfAWireOverAWideRoll) {
  const Drum drum{10.0, 0.15};
  const double a = 1e-4, h = 0.05;
  const Electrode wire = Electrode::at_polar(drum.radius + h, kPi / 2.0, a, -35e3);
  const LineChargeField field(drum, {wire});
  const CoronaBand band = corona_band(drum, field, {wire, kMobility, 1.0});
  const double v0 = peek_onset_field(a) * a * std::log(2.0 * h / a);
  EXPECT_NEAR(band.onset_voltage, v0, 0.02 * v0);
  EXPECT_NEAR(band.height, h, 1e-12);
  EXPECT_EQ(band.ion_sign, -1.0);
  const double current = townsend_current(35e3, band.onset_voltage, a, h, kMobility);
  EXPECT_NEAR(band.current, current, 1e-12 * current);
  EXPECT_NEAR(band.space_charge, space_charge_field(band.current, kMobility), 1e-6);
  // Under the wire: J0 and E_sc; 0.7 S along the roll: J0/2 and E_sc/√2.
  const Vec3 foot(0.0, drum.radius + 1e-3, 0.0);
  EXPECT_NEAR(band.current_density(foot), band.peak_current_density, 1e-6 * band.peak_current_density);
  const double turn = 0.7 * h / drum.radius;
  const Vec3 aside = (drum.radius + 1e-3) * Vec3(std::sin(turn), std::cos(turn), 0.0);
  EXPECT_NEAR(band.current_density(aside), 0.5 * band.peak_current_density,
              1e-6 * band.peak_current_density);
  EXPECT_NEAR(band.space_charge_field(aside), band.space_charge / std::sqrt(2.0), 1e-6 * band.space_charge);
  EXPECT_FALSE(band.covers(Vec3(0.0, drum.radius + 2.0 * h, 0.0)));
  EXPECT_EQ(band.current_density(-foot), 0.0);
  const Electrode weak = Electrode::at_polar(drum.radius + h, kPi / 2.0, a, -0.5 * v0);
  EXPECT_THROW(corona_band(drum, LineChargeField(drum, {weak}), {weak, kMobility, 1.0}),
               std::invalid_argument);
}

// ------------------------------------------------------------------ charging

// Pauthenier growth toward a flake's saturation charge, stepped: equal to
// Q_s t/(t + τ) at every step (1e-12), whatever the step; τ = 4 ε0 E/J.
TEST(FlakeCharging, PauthenierGrowthIsExactForAnyStep) {
  const FlatFlake flake{kPi * 1.6e-3 * 1.6e-3, 0.5e-3};
  const double e = 4.1e5, j = 6.5e-3;
  const double qs = -flake_saturation_charge(flake, 4.4, e);
  const double tau = pauthenier_time_constant(e, j);
  EXPECT_NEAR(tau, 4.0 * kEps0 * e / j, 1e-15);
  for (const double dt : {1e-5, 5e-4, 3e-3}) {
    double q = 0.0;
    for (int n = 1; n <= 40; ++n) {
      q = pauthenier_growth(q, qs, tau, dt);
      EXPECT_NEAR(q, pauthenier_charge(qs, tau, n * dt), 1e-12 * std::abs(qs));
    }
  }
  EXPECT_EQ(pauthenier_growth(0.3 * qs, qs, std::numeric_limits<double>::infinity(), 1e-3), 0.3 * qs);
}

// The thin-plate saturation charge (4/3) εr ε0 E a³/t, written out; the
// tabulated Laplace ratio tends to 1 as t/a → 0 (the thin-plate limit: at
// t/a = 1e-6 within 1e-4) and grows with the thickness (more field lines
// end on a thick flake's rim).
TEST(FlakeCharging, SaturationChargeThinPlateLimit) {
  const double a = 1.66e-3, t = 0.60e-3, e = 4.1e5;
  const FlatFlake flake{kPi * a * a, t};
  EXPECT_NEAR(flake.radius(), a, 1e-15);
  const double thin = 4.0 / 3.0 * 4.4 * kEps0 * e * a * a * a / t;
  EXPECT_NEAR(thin_flake_saturation_charge(flake, 4.4, e), thin, 1e-12 * thin);
  // docs/physics.md §5.3's median FR-4 flake: 0.16 nC in the thin-plate limit.
  EXPECT_NEAR(thin, 0.16e-9, 0.01e-9);
  const FlatFlake sheet{kPi * a * a, 1e-6 * a};
  EXPECT_NEAR(flake_saturation_charge(sheet, 4.4, e) / thin_flake_saturation_charge(sheet, 4.4, e),
              1.0, 1e-4);
  double last = 1.0;
  for (const double x : {0.05, 0.2, 0.5, 1.0, 1.33}) {
    const FlatFlake f{kPi * a * a, x * a};
    const double ratio = flake_saturation_charge(f, 4.4, e) / thin_flake_saturation_charge(f, 4.4, e);
    EXPECT_GT(ratio, last);
    last = ratio;
  }
}

// The saturated charge density of a thin flake, σ ∝ √(a² − ρ²), pulls with
// ∫σ²/(2ε0) dA = κ Q²/(2 ε0 A), κ = 9/8: the integrals by the midpoint rule
// (1e-4), and the image factor of a thin flake tends to it (1 %).
TEST(FlakeCharging, ImageFactorOfTheSaturatedDensity) {
  const double a = 1.0;
  const int n = 200000;
  double q = 0.0, pull = 0.0;
  for (int k = 0; k < n; ++k) {
    const double rho = (k + 0.5) * a / n, sigma = std::sqrt(a * a - rho * rho);
    q += sigma * 2.0 * kPi * rho * a / n;
    pull += sigma * sigma * 2.0 * kPi * rho * a / n;
  }
  const double area = kPi * a * a;
  EXPECT_NEAR(pull / (q * q / area), 9.0 / 8.0, 1e-4);
  EXPECT_DOUBLE_EQ(kThinFlakeImageFactor, 9.0 / 8.0);
  EXPECT_NEAR(flake_image_factor({area, 1e-3 * a}, 4.4), 9.0 / 8.0, 0.01 * 9.0 / 8.0);
  // Thicker flakes hold a smaller share of their pull as their own image:
  // docs/physics.md §5.5 gives 0.85 at t/a = 0.36 and 0.68 at 1 for FR-4
  // (printed to two decimals: 0.01).
  EXPECT_NEAR(flake_image_factor({area, 0.36 * a}, 4.4), 0.85, 0.01);
  EXPECT_NEAR(flake_image_factor({area, 1.0 * a}, 4.4), 0.68, 0.01);
}

// A conducting flake lying flat is part of the drum's surface: Q = ε0 E A,
// F = ½ ε0 E² A in the thin limit (Gauss's law; 1 % at t/a = 1e-3), the
// sign of Q that of E·n, the lift always outward. A thicker flake gathers
// more field on its rim: at t/a = 0.4, 2.33 times the charge and 3.10
// times the lift (docs/physics.md §5.1, printed to three digits: 0.5 %).
TEST(FlakeCharging, ConductingFlakeTakesTheDrumsSurfaceCharge) {
  const double area = 7.3e-6, e = 3.29e5;
  const FlatFlake sheet{area, 1e-3 * std::sqrt(area / kPi)};
  EXPECT_NEAR(flat_conductor_charge(sheet, e, 1.0), kEps0 * e * area, 0.01 * kEps0 * e * area);
  EXPECT_NEAR(flat_conductor_charge(sheet, -e, 1.0), -kEps0 * e * area, 0.01 * kEps0 * e * area);
  const double lift = 0.5 * kEps0 * e * e * area;
  EXPECT_NEAR(flat_conductor_lift(sheet, e, 1.0), lift, 0.01 * lift);
  EXPECT_DOUBLE_EQ(flat_conductor_lift(sheet, -e, 1.0), flat_conductor_lift(sheet, e, 1.0));
  const FlatFlake thick{area, 0.4 * std::sqrt(area / kPi)};
  EXPECT_NEAR(flat_conductor_charge(thick, e, 1.0), 2.33 * kEps0 * e * area,
              0.005 * 2.33 * kEps0 * e * area);
  EXPECT_NEAR(flat_conductor_lift(thick, e, 1.0), 3.10 * lift, 0.005 * 3.10 * lift);
}

// Decay on the grounded roll: Q0 exp(−t/τ) stepped (1e-12), τ = ε0 εr ρ_v =
// 39 s for FR-4 at 1e12 Ω m and 0.39 s at the 1e10 Ω m limit.
TEST(FlakeCharging, ChargeDecaysExponentially) {
  const double tau = relaxation_time(4.4, 1e12);
  EXPECT_NEAR(tau, 38.96, 0.01);
  EXPECT_NEAR(relaxation_time(4.4, 1e10), 0.3896, 1e-4);
  double q = 1e-10;
  for (int n = 1; n <= 1000; ++n) {
    q = decay_step(q, 0.3896, 1e-3);
    EXPECT_NEAR(q, 1e-10 * std::exp(-n * 1e-3 / 0.3896), 1e-12 * 1e-10);
  }
}

// A charge Q at the centre of a sphere of radius r resting on a grounded
// plane meets its image 2r away: F = Q²/(4π ε0 (2r)²) (1e-12).
TEST(FlakeCharging, ImageForceOfAChargedSphere) {
  const double q = 2e-11, r = 1e-3;
  const double f = q * q / (4.0 * kPi * kEps0 * 4.0 * r * r);
  EXPECT_NEAR(image_force(q, r, 1.0), f, 1e-12 * f);
  EXPECT_NEAR(image_force(-q, 2.0 * r, 1.0), f / 4.0, 1e-12 * f);
}

}  // namespace
}  // namespace ces::fields

// ------------------------------------------------------------ drawn flakes
namespace ces {
namespace {

// The standard normal CDF, and the quantile p of a lognormal (median m,
// σ) truncated to [lo, hi], by bisection.
double phi(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }
double truncated_lognormal_quantile(double m, double s, double lo, double hi, double p) {
  const auto cdf = [&](double x) { return phi(std::log(x / m) / s); };
  const double target = cdf(lo) + p * (cdf(hi) - cdf(lo));
  double a = lo, b = hi;
  for (int k = 0; k < 200; ++k) {
    const double c = 0.5 * (a + b);
    (cdf(c) < target ? a : b) = c;
  }
  return 0.5 * (a + b);
}
// E[x^k] of that truncated lognormal, by the midpoint rule in ln x.
double truncated_lognormal_moment(double m, double s, double lo, double hi, int k) {
  const int n = 20000;
  const double u0 = std::log(lo), u1 = std::log(hi), du = (u1 - u0) / n;
  double w = 0.0, sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double u = u0 + (i + 0.5) * du, z = (u - std::log(m)) / s;
    const double density = std::exp(-0.5 * z * z);
    w += density;
    sum += density * std::exp(k * u);
  }
  return sum / w;
}

double sample_quantile(std::vector<double> x, double p) {
  std::sort(x.begin(), x.end());
  return x[std::size_t(p * double(x.size() - 1))];
}

struct Law {
  double median, sigma, lo, hi;
};

// scenes/ces_pcb.yaml feeds the measured flakes: 10 000 draws of each
// component's thickness and width reproduce the 10/50/90 % points of the
// truncated lognormals (2 %), and the mean mass ρ π w² t/4 the laws give
// (4 standard errors); that mean is within 10 % of the measured flakes'
// (46.7 mg copper, 9.3 mg FR-4; docs/physics.md §7.1). Each draw picks the
// ladder rung nearest its aspect, never thinner than 0.15.
TEST(DrawnFlakes, ReferenceFeedReproducesTheMeasuredPopulation) {
  scene::LoadOptions options;
  options.threads = 1;
  const Simulation sim = scene::load(std::string(CES_SOURCE_DIR) + "/scenes/ces_pcb.yaml", options);
  const std::vector<FeedComponent>& mix = sim.feeds.at(0).mix;
  ASSERT_EQ(mix.size(), 2u);
  const Law thickness[] = {{0.61e-3, 0.61, 0.16e-3, 1.27e-3}, {0.52e-3, 0.67, 0.09e-3, 1.31e-3}};
  const Law width[] = {{3.09e-3, 0.17, 1.68e-3, 4.82e-3}, {3.38e-3, 0.16, 2.38e-3, 5.15e-3}};
  const double density[] = {8960.0, 1850.0}, measured_mg[] = {46.7, 9.3};
  std::mt19937_64 rng(7);
  for (std::size_t c = 0; c < 2; ++c) {
    ASSERT_TRUE(mix[c].drawn.has_value());
    const DrawnShape& d = *mix[c].drawn;
    std::vector<double> t, w, mass;
    for (int k = 0; k < 10000; ++k) {
      t.push_back(d.thickness.sample(rng));
      w.push_back(d.extent.sample(rng));
      mass.push_back(density[c] * d.volume(t.back(), w.back()));
      const DrawnShape::Rung& rung = d.rung(t.back(), w.back());
      EXPECT_GE(rung.aspect, 0.15 - 1e-12);
      for (const DrawnShape::Rung& other : d.ladder)
        EXPECT_LE(std::abs(std::log(rung.aspect * w.back() / t.back())),
                  std::abs(std::log(other.aspect * w.back() / t.back())) + 1e-12);
    }
    for (const double p : {0.1, 0.5, 0.9}) {
      const Law& lt = thickness[c];
      const Law& lw = width[c];
      const double et = truncated_lognormal_quantile(lt.median, lt.sigma, lt.lo, lt.hi, p);
      const double ew = truncated_lognormal_quantile(lw.median, lw.sigma, lw.lo, lw.hi, p);
      EXPECT_NEAR(sample_quantile(t, p), et, 0.02 * et) << c << " " << p;
      EXPECT_NEAR(sample_quantile(w, p), ew, 0.02 * ew) << c << " " << p;
    }
    double mean = 0.0, sq = 0.0;
    for (const double m : mass) mean += m / double(mass.size());
    for (const double m : mass) sq += (m - mean) * (m - mean);
    const double se = std::sqrt(sq / double(mass.size() - 1) / double(mass.size()));
    const Law& lt = thickness[c];
    const Law& lw = width[c];
    const double expected = density[c] * kPi / 4.0 *
                            truncated_lognormal_moment(lw.median, lw.sigma, lw.lo, lw.hi, 2) *
                            truncated_lognormal_moment(lt.median, lt.sigma, lt.lo, lt.hi, 1);
    EXPECT_NEAR(mean, expected, 4.0 * se) << c;
    EXPECT_NEAR(mean * 1e6, measured_mg[c], 0.10 * measured_mg[c]) << c;
  }
}

// The drawn disc's volume and inertia: π w² t/4; w²/8 per unit mass about
// its normal (the shape's axis of largest inertia), w²/16 + t²/12 across.
TEST(DrawnFlakes, DiscVolumeAndInertia) {
  DrawnShape d;
  const double t = 0.5e-3, w = 3e-3;
  EXPECT_NEAR(d.volume(t, w), kPi * w * w * t / 4.0, 1e-18);
  const Vec3 i = d.unit_inertia(t, w, Vec3(1.0, 3.0, 1.0));
  EXPECT_NEAR(i[1], w * w / 8.0, 1e-15);
  EXPECT_NEAR(i[0], w * w / 16.0 + t * t / 12.0, 1e-15);
  EXPECT_NEAR(i[2], i[0], 1e-18);
}

}  // namespace
}  // namespace ces
