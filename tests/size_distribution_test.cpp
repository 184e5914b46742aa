// Feed size distributions: the tabulated laws against closed forms, and
// 1e5 number draws against the laws' own means and quantiles.
#include "feed/size_distribution.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace ces::feed {
namespace {

constexpr double kMm = 1e-3;

// Standard normal CDF and its inverse (bisection: slow, obviously right).
double phi(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }
double phi_inverse(double p) {
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (phi(mid) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Quantile of a normal(μ, σ) truncated to [a, b].
double truncated_normal_quantile(double mu, double sd, double a, double b, double q) {
  const double pa = phi((a - mu) / sd), pb = phi((b - mu) / sd);
  return mu + sd * phi_inverse(pa + q * (pb - pa));
}

// Composite Simpson integral, for moments without a closed form.
double simpson(const std::function<double(double)>& f, double a, double b, int n = 200000) {
  const double h = (b - a) / n;
  double sum = f(a) + f(b);
  for (int i = 1; i < n; ++i) sum += f(a + i * h) * (i % 2 ? 4.0 : 2.0);
  return sum * h / 3.0;
}

void expect_rel(double actual, double expected, double tolerance, const std::string& what) {
  EXPECT_NEAR(actual, expected, tolerance * std::abs(expected)) << what;
}

// ------------------------------------------------------ closed forms --
// Tolerance on quantiles: 1e-9 relative where the density is piecewise
// constant (the tabulation is exact there), 1e-7 for smooth densities
// (2048 grid intervals per piece, linear density inside: an error of the
// interval's square, well under it).

TEST(SizeDistribution, ConstantIsDegenerate) {
  const auto s = SizeDistribution::constant(0.8 * kMm);
  std::mt19937_64 rng(3);
  for (int n = 0; n < 100; ++n) EXPECT_EQ(s.sample(rng), 0.8 * kMm);
  EXPECT_EQ(s.mean_by_number(), 0.8 * kMm);
  EXPECT_DOUBLE_EQ(s.mean_mass_per_particle_factor(), std::pow(0.8 * kMm, 3));
  for (double q : {0.0, 0.1, 0.5, 1.0}) {
    EXPECT_EQ(s.quantile_by_number(q), 0.8 * kMm);
    EXPECT_EQ(s.quantile_by_mass(q), 0.8 * kMm);
  }
}

TEST(SizeDistribution, UniformByNumberClosedForm) {
  const double a = 0.6 * kMm, b = 1.2 * kMm;
  const auto s = SizeDistribution::uniform(a, b, Basis::number);
  expect_rel(s.mean_by_number(), 0.5 * (a + b), 1e-12, "mean");
  expect_rel(s.mean_mass_per_particle_factor(), (std::pow(b, 4) - std::pow(a, 4)) / (4 * (b - a)),
             1e-12, "E[d3]");
  for (double q : {0.1, 0.5, 0.9}) expect_rel(s.quantile_by_number(q), a + q * (b - a), 1e-9, "q");
}

// Mass-uniform: number density ∝ d⁻³ on [a, b].
TEST(SizeDistribution, UniformByMassClosedForm) {
  const double a = 0.5 * kMm, b = 2.0 * kMm;
  const auto s = SizeDistribution::uniform(a, b, Basis::mass);
  const double norm = 0.5 * (1 / (a * a) - 1 / (b * b));  // ∫ d⁻³
  expect_rel(s.mean_by_number(), (1 / a - 1 / b) / norm, 1e-9, "mean");
  expect_rel(s.mean_mass_per_particle_factor(), (b - a) / norm, 1e-9, "E[d3]");
  for (double q : {0.1, 0.5, 0.9}) {
    expect_rel(s.quantile_by_mass(q), a + q * (b - a), 1e-9, "mass q");
    expect_rel(s.quantile_by_number(q), 1 / std::sqrt(1 / (a * a) - 2 * q * norm), 1e-7, "q");
  }
}

TEST(SizeDistribution, TruncatedNormalByNumberClosedForm) {
  const double mu = 1.0 * kMm, sd = 0.2 * kMm, a = 0.5 * kMm, b = 1.8 * kMm;
  const auto s = SizeDistribution::normal(mu, sd, a, b, Basis::number);
  const double alpha = (a - mu) / sd, beta = (b - mu) / sd;
  const auto pdf = [](double z) {
    return std::exp(-0.5 * z * z) / std::sqrt(2 * std::numbers::pi);
  };
  expect_rel(s.mean_by_number(), mu + sd * (pdf(alpha) - pdf(beta)) / (phi(beta) - phi(alpha)),
             1e-9, "mean");
  for (double q : {0.1, 0.5, 0.9}) {
    expect_rel(s.quantile_by_number(q), truncated_normal_quantile(mu, sd, a, b, q), 1e-7, "q");
  }
}

TEST(SizeDistribution, TruncatedNormalByMassMatchesQuadrature) {
  const double mu = 1.0 * kMm, sd = 0.25 * kMm, a = 0.3 * kMm, b = 2.0 * kMm;
  const auto s = SizeDistribution::normal(mu, sd, a, b, Basis::mass);
  for (double q : {0.1, 0.5, 0.9}) {
    expect_rel(s.quantile_by_mass(q), truncated_normal_quantile(mu, sd, a, b, q), 1e-7, "mass q");
  }
  const auto mass_pdf = [&](double d) { return std::exp(-0.5 * std::pow((d - mu) / sd, 2)); };
  const double count = simpson([&](double d) { return mass_pdf(d) / (d * d * d); }, a, b);
  expect_rel(s.mean_by_number(),
             simpson([&](double d) { return mass_pdf(d) / (d * d); }, a, b) / count, 1e-9, "mean");
  expect_rel(s.mean_mass_per_particle_factor(), simpson(mass_pdf, a, b) / count, 1e-9, "E[d3]");
}

// Unclipped in effect: [min, max] lies beyond the 12 σ cut.
TEST(SizeDistribution, LognormalByNumberClosedForm) {
  const double m = 0.9 * kMm, sigma = 0.3;
  const auto s = SizeDistribution::lognormal(m, sigma, 1e-6, 1.0, Basis::number);
  expect_rel(s.mean_by_number(), m * std::exp(0.5 * sigma * sigma), 1e-9, "mean");
  expect_rel(s.mean_mass_per_particle_factor(), std::pow(m, 3) * std::exp(4.5 * sigma * sigma),
             1e-9, "E[d3]");
  for (double q : {0.1, 0.5, 0.9}) {
    const double z = phi_inverse(q);
    expect_rel(s.quantile_by_number(q), m * std::exp(sigma * z), 1e-7, "q");
    // Hatch–Choate: the mass median is exp(3σ²) above the count median.
    expect_rel(s.quantile_by_mass(q), m * std::exp(3 * sigma * sigma + sigma * z), 1e-7, "mass q");
  }
}

TEST(SizeDistribution, LognormalByMassClosedForm) {
  const double m = 1.0 * kMm, sigma = 0.4;
  const auto s = SizeDistribution::lognormal(m, sigma, 1e-6, 1.0, Basis::mass);
  const double count_median = m * std::exp(-3 * sigma * sigma);
  expect_rel(s.mean_by_number(), count_median * std::exp(0.5 * sigma * sigma), 1e-9, "mean");
  for (double q : {0.1, 0.5, 0.9}) {
    const double z = phi_inverse(q);
    expect_rel(s.quantile_by_number(q), count_median * std::exp(sigma * z), 1e-7, "q");
    expect_rel(s.quantile_by_mass(q), m * std::exp(sigma * z), 1e-7, "mass q");
  }
}

const std::vector<SizeDistribution::SievePoint> kSieve = {
    {0.3 * kMm, 0.0}, {0.6 * kMm, 0.15}, {0.85 * kMm, 0.45}, {1.2 * kMm, 0.8}, {2.0 * kMm, 1.0}};

// Linear interpolation of the sieve table's CDF.
double sieve_quantile(double q) {
  std::size_t i = 1;
  while (kSieve[i].passing < q) ++i;
  const auto& lo = kSieve[i - 1];
  const auto& hi = kSieve[i];
  return lo.size + (q - lo.passing) / (hi.passing - lo.passing) * (hi.size - lo.size);
}

TEST(SizeDistribution, SieveByNumberClosedForm) {
  const auto s = SizeDistribution::sieve(kSieve, Basis::number);
  double mean = 0.0;
  for (std::size_t i = 1; i < kSieve.size(); ++i) {
    mean +=
        (kSieve[i].passing - kSieve[i - 1].passing) * 0.5 * (kSieve[i].size + kSieve[i - 1].size);
  }
  expect_rel(s.mean_by_number(), mean, 1e-12, "mean");
  for (double q : {0.1, 0.15, 0.5, 0.9})
    expect_rel(s.quantile_by_number(q), sieve_quantile(q), 1e-9, "q");
}

TEST(SizeDistribution, SieveByMassClosedForm) {
  const auto s = SizeDistribution::sieve(kSieve, Basis::mass);
  // Number density c_i d⁻³ on each piece, c_i the mass-density slope.
  double count = 0.0, first = 0.0, cube = 0.0;
  for (std::size_t i = 1; i < kSieve.size(); ++i) {
    const double a = kSieve[i - 1].size, b = kSieve[i].size;
    const double c = (kSieve[i].passing - kSieve[i - 1].passing) / (b - a);
    count += c * 0.5 * (1 / (a * a) - 1 / (b * b));
    first += c * (1 / a - 1 / b);
    cube += c * (b - a);
  }
  expect_rel(s.mean_by_number(), first / count, 1e-9, "mean");
  expect_rel(s.mean_mass_per_particle_factor(), cube / count, 1e-9, "E[d3]");
  for (double q : {0.1, 0.15, 0.5, 0.9})
    expect_rel(s.quantile_by_mass(q), sieve_quantile(q), 1e-9, "mass q");
}

// ----------------------------------------------------------- sampling --

struct Named {
  std::string name;
  SizeDistribution law;
};

std::vector<Named> realistic_feeds() {
  return {
      {"uniform/number", SizeDistribution::uniform(0.6 * kMm, 1.2 * kMm, Basis::number)},
      {"uniform/mass", SizeDistribution::uniform(0.5 * kMm, 2.0 * kMm, Basis::mass)},
      {"normal/number",
       SizeDistribution::normal(1.0 * kMm, 0.2 * kMm, 0.5 * kMm, 1.8 * kMm, Basis::number)},
      {"normal/mass",
       SizeDistribution::normal(1.0 * kMm, 0.25 * kMm, 0.3 * kMm, 2.0 * kMm, Basis::mass)},
      {"lognormal/number",
       SizeDistribution::lognormal(0.9 * kMm, 0.3, 0.3 * kMm, 3.0 * kMm, Basis::number)},
      {"lognormal/mass",
       SizeDistribution::lognormal(1.0 * kMm, 0.4, 0.3 * kMm, 3.0 * kMm, Basis::mass)},
      {"sieve/number", SizeDistribution::sieve(kSieve, Basis::number)},
      {"sieve/mass", SizeDistribution::sieve(kSieve, Basis::mass)},
  };
}

// One checked statistic: sample estimate, the law's value, and the
// standard error of the estimate (from the sample).
struct Estimate {
  double sample, law, standard_error;
};

// Weighted empirical q-quantile of sorted draws; its standard error is that
// of the weighted empirical CDF, sqrt(Σ w²(1{d ≤ x} − q)²)/Σ w, times the
// law's dQ/dq.
Estimate weighted_quantile(const std::vector<double>& sorted, double q,
                           const std::function<double(double)>& w,
                           const std::function<double(double)>& law_quantile) {
  double total = 0.0;
  for (double d : sorted) total += w(d);
  double running = 0.0, x = sorted.back();
  for (double d : sorted) {
    running += w(d);
    if (running >= q * total) {
      x = d;
      break;
    }
  }
  double variance = 0.0;
  for (double d : sorted) variance += std::pow(w(d) * ((d <= x ? 1.0 : 0.0) - q), 2);
  const double slope = (law_quantile(q + 0.01) - law_quantile(q - 0.01)) / 0.02;
  return {x, law_quantile(q), std::sqrt(variance) / total * slope};
}

Estimate sample_mean(const std::vector<double>& d, const std::function<double(double)>& g,
                     double law) {
  double sum = 0.0, sum_sq = 0.0;
  for (double x : d) {
    sum += g(x);
    sum_sq += g(x) * g(x);
  }
  const double n = static_cast<double>(d.size());
  return {sum / n, law, std::sqrt((sum_sq / n - sum * sum / (n * n)) / n)};
}

// 1e5 number draws per law, fixed seed; checked: the number mean, E[d³],
// the 10/50/90 % quantiles by number and the mass-weighted ones. Tolerance
// 1 % relative, or 4 standard errors of the estimate where that is larger:
// a few hundred draws carry the top 10 % of the mass of a wide by-mass law,
// so its mass-weighted 90 % quantile scatters by ~1 % from seed to seed.
TEST(SizeDistribution, SamplesMatchTheLaw) {
  for (const Named& feed : realistic_feeds()) {
    std::mt19937_64 rng(20240601);
    std::vector<double> d(100000);
    for (double& x : d) x = feed.law.sample(rng);
    std::sort(d.begin(), d.end());
    const auto one = [](double) { return 1.0; };
    const auto cube = [](double x) { return x * x * x; };
    const auto by_number = [&](double q) { return feed.law.quantile_by_number(q); };
    const auto by_mass = [&](double q) { return feed.law.quantile_by_mass(q); };
    std::vector<std::pair<std::string, Estimate>> checks = {
        {"mean", sample_mean(
                     d, [](double x) { return x; }, feed.law.mean_by_number())},
        {"E[d3]", sample_mean(d, cube, feed.law.mean_mass_per_particle_factor())}};
    for (double q : {0.1, 0.5, 0.9}) {
      const std::string at = std::to_string(static_cast<int>(100 * q)) + " %";
      checks.emplace_back("number " + at, weighted_quantile(d, q, one, by_number));
      checks.emplace_back("mass " + at, weighted_quantile(d, q, cube, by_mass));
    }
    for (const auto& [what, e] : checks) {
      EXPECT_NEAR(e.sample, e.law, std::max(0.01 * e.law, 4.0 * e.standard_error))
          << feed.name << ' ' << what;
    }
  }
}

// The uniform conversion is (bits >> 11) · 2⁻⁵³, so a uniform law maps the
// engine's raw output linearly: reproducible on any standard library.
TEST(SizeDistribution, SamplingUsesRawEngineBits) {
  const auto s = SizeDistribution::uniform(1.0 * kMm, 2.0 * kMm, Basis::number);
  std::mt19937_64 rng(42), raw(42);
  for (int n = 0; n < 1000; ++n) {
    const double u = static_cast<double>(raw() >> 11) * 0x1.0p-53;
    expect_rel(s.sample(rng), (1.0 + u) * kMm, 1e-12, "draw " + std::to_string(n));
  }
}

TEST(SizeDistribution, SameSeedSameSizes) {
  const auto s = SizeDistribution::lognormal(1.0 * kMm, 0.4, 0.3 * kMm, 3.0 * kMm, Basis::mass);
  std::mt19937_64 a(9), b(9);
  for (int n = 0; n < 1000; ++n) EXPECT_EQ(s.sample(a), s.sample(b));
}

TEST(SizeDistribution, RejectsInvalidLaws) {
  EXPECT_THROW(SizeDistribution::constant(0.0), std::invalid_argument);
  EXPECT_THROW(SizeDistribution::uniform(2 * kMm, 1 * kMm, Basis::number), std::invalid_argument);
  EXPECT_THROW(SizeDistribution::uniform(0.0, 1 * kMm, Basis::mass),
               std::invalid_argument);  // ∫ d⁻³ diverges
  EXPECT_THROW(SizeDistribution::normal(1 * kMm, 0.0, 0.0, 2 * kMm, Basis::number),
               std::invalid_argument);
  EXPECT_THROW(SizeDistribution::normal(1 * kMm, 0.01 * kMm, 2 * kMm, 3 * kMm, Basis::number),
               std::invalid_argument);  // nothing inside [min, max]
  EXPECT_THROW(SizeDistribution::lognormal(1 * kMm, -0.1, 0.0, 1.0, Basis::mass),
               std::invalid_argument);
  EXPECT_THROW(SizeDistribution::sieve({{1 * kMm, 0.0}, {1 * kMm, 1.0}}, Basis::mass),
               std::invalid_argument);
  EXPECT_THROW(SizeDistribution::sieve({{1 * kMm, 0.0}, {2 * kMm, 0.9}}, Basis::mass),
               std::invalid_argument);
  EXPECT_THROW(SizeDistribution::sieve(
                   {{1 * kMm, 0.0}, {2 * kMm, 0.6}, {3 * kMm, 0.5}, {4 * kMm, 1.0}}, Basis::number),
               std::invalid_argument);
  EXPECT_THROW(SizeDistribution::uniform(1 * kMm, 2 * kMm, Basis::number).quantile_by_mass(1.5),
               std::invalid_argument);
}

}  // namespace
}  // namespace ces::feed
