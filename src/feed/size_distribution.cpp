#include "feed/size_distribution.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include "common/random.hpp"

namespace ces::feed {
namespace {

// Grid intervals between consecutive breakpoints.
constexpr std::size_t kIntervalsPerPiece = 2048;

// Normal and lognormal laws are cut at 12 σ: the density there is 5e-32 of
// the peak, below what a double CDF resolves, and the grid stays on the
// distribution even when [min, max] is much wider.
constexpr double kTailSigmas = 12.0;

// 4-point Gauss–Legendre on [−1, 1]: exact for polynomials up to degree 7,
// so the d and d³ moments of piecewise-constant densities are exact.
constexpr std::array<double, 4> kGaussX = {-0.8611363115940526, -0.3399810435848563,
                                           0.3399810435848563, 0.8611363115940526};
constexpr std::array<double, 4> kGaussW = {0.3478548451374538, 0.6521451548625461,
                                           0.6521451548625461, 0.3478548451374538};

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}

// Grid nodes of one piece after `lo`: geometric when lo > 0 (constant
// relative resolution over wide size ranges), otherwise arithmetic.
void append_nodes(double lo, double hi, std::vector<double>& nodes) {
  for (std::size_t i = 1; i < kIntervalsPerPiece; ++i) {
    const double t = static_cast<double>(i) / static_cast<double>(kIntervalsPerPiece);
    nodes.push_back(lo > 0.0 ? lo * std::pow(hi / lo, t) : lo + t * (hi - lo));
  }
  nodes.push_back(hi);
}

// Shape of a linear density on one interval, from its end values.
double linear_tilt(double left, double right) {
  return left + right > 0.0 ? (right - left) / (right + left) : 0.0;
}

void require_fraction(double q) { require(q >= 0.0 && q <= 1.0, "quantile must be in [0, 1]"); }

}  // namespace

// Inverse CDF. Intervals of zero probability are never returned inside.
double SizeDistribution::Cdf::invert(const std::vector<double>& nodes, double q) const {
  const auto above = std::upper_bound(value.begin(), value.end(), q);
  if (above == value.end()) return nodes.back();
  const auto i = static_cast<std::size_t>(above - value.begin());  // value[i−1] <= q < value[i]
  const double w = (q - value[i - 1]) / (value[i] - value[i - 1]);
  if (w <= 0.0) return nodes[i - 1];  // also where the density starts at 0 (0/0 below)
  // Solve w = (1 − s) t + s t² for t in [0, 1] (density ∝ 1 + s (2t − 1)),
  // in the form without cancellation.
  const double s = tilt[i - 1];
  const double t = 2.0 * w / ((1.0 - s) + std::sqrt((1.0 - s) * (1.0 - s) + 4.0 * s * w));
  return nodes[i - 1] + t * (nodes[i] - nodes[i - 1]);
}

// `density(piece, d)`: the basis density (unnormalised) on
// [breaks[piece], breaks[piece + 1]].
template <class Density>
SizeDistribution SizeDistribution::tabulate(const std::vector<double>& breaks, Basis basis,
                                            const Density& density) {
  SizeDistribution s;
  s.diameter_ = {breaks.front()};
  for (std::size_t piece = 0; piece + 1 < breaks.size(); ++piece) {
    append_nodes(breaks[piece], breaks[piece + 1], s.diameter_);
  }
  // By mass the number density is f_mass / d³; the mass density is d³ × number.
  const auto number_density = [&](std::size_t piece, double d) {
    const double f = density(piece, d);
    return basis == Basis::mass ? f / (d * d * d) : f;
  };
  double count = 0.0, first_moment = 0.0, mass = 0.0;
  s.by_number_.value = {0.0};
  s.by_mass_.value = {0.0};
  std::size_t piece = 0;
  for (std::size_t i = 1; i < s.diameter_.size(); ++i) {
    const double lo = s.diameter_[i - 1];
    const double hi = s.diameter_[i];
    if (lo >= breaks[piece + 1]) ++piece;
    const double mid = 0.5 * (hi + lo);
    const double half = 0.5 * (hi - lo);
    for (std::size_t g = 0; g < kGaussX.size(); ++g) {
      const double d = mid + half * kGaussX[g];
      const double n = half * kGaussW[g] * number_density(piece, d);
      count += n;
      first_moment += n * d;
      mass += n * d * d * d;
    }
    s.by_number_.value.push_back(count);
    s.by_mass_.value.push_back(mass);
    const double n_lo = number_density(piece, lo);
    const double n_hi = number_density(piece, hi);
    s.by_number_.tilt.push_back(linear_tilt(n_lo, n_hi));
    s.by_mass_.tilt.push_back(linear_tilt(n_lo * lo * lo * lo, n_hi * hi * hi * hi));
  }
  require(count > 0.0 && std::isfinite(count) && mass > 0.0,
          "the size distribution has no probability inside [min, max]");
  for (double& c : s.by_number_.value) c /= count;
  for (double& c : s.by_mass_.value) c /= mass;
  s.mean_ = first_moment / count;
  s.mean_cube_ = mass / count;
  return s;
}

SizeDistribution SizeDistribution::constant(double diameter) {
  require(diameter > 0.0, "particle diameter must be positive");
  SizeDistribution s;
  s.diameter_ = {diameter, diameter};
  s.by_number_ = {{0.0, 1.0}, {0.0}};
  s.by_mass_ = s.by_number_;
  s.mean_ = diameter;
  s.mean_cube_ = diameter * diameter * diameter;
  return s;
}

SizeDistribution SizeDistribution::uniform(double min, double max, Basis basis) {
  require(min >= 0.0 && min < max, "uniform sizes need 0 <= min < max");
  require(basis == Basis::number || min > 0.0, "a mass basis needs min > 0");
  return tabulate({min, max}, basis, [](std::size_t, double) { return 1.0; });
}

SizeDistribution SizeDistribution::normal(double mean, double sd, double min, double max,
                                          Basis basis) {
  require(sd > 0.0, "standard deviation must be positive");
  require(min >= 0.0 && min < max, "normal sizes need 0 <= min < max");
  const double lo = std::max(min, mean - kTailSigmas * sd);
  const double hi = std::min(max, mean + kTailSigmas * sd);
  require(lo < hi, "the normal law has no probability inside [min, max]");
  require(basis == Basis::number || lo > 0.0, "a mass basis needs min > 0");
  return tabulate({lo, hi}, basis, [mean, sd](std::size_t, double d) {
    const double z = (d - mean) / sd;
    return std::exp(-0.5 * z * z);
  });
}

SizeDistribution SizeDistribution::lognormal(double median, double sigma, double min, double max,
                                             Basis basis) {
  require(median > 0.0 && sigma > 0.0, "lognormal sizes need median > 0 and sigma > 0");
  require(min >= 0.0 && min < max, "lognormal sizes need 0 <= min < max");
  // Weighting by d³ shifts a lognormal's median by exp(3σ²) (Hatch–Choate):
  // the grid must cover the number law's lower tail and the mass law's upper.
  const double shift = std::exp(3.0 * sigma * sigma);
  const double number_median = basis == Basis::mass ? median / shift : median;
  const double lo = std::max(min, number_median * std::exp(-kTailSigmas * sigma));
  const double hi = std::min(max, number_median * shift * std::exp(kTailSigmas * sigma));
  require(lo < hi, "the lognormal law has no probability inside [min, max]");
  return tabulate({lo, hi}, basis, [median, sigma](std::size_t, double d) {
    const double z = std::log(d / median) / sigma;
    return std::exp(-0.5 * z * z) / d;
  });
}

SizeDistribution SizeDistribution::sieve(const std::vector<SievePoint>& table, Basis basis) {
  require(table.size() >= 2, "a sieve table needs at least 2 sizes");
  require(table.front().size > 0.0, "sieve sizes must be positive");
  require(table.front().passing == 0.0 && table.back().passing == 1.0,
          "sieve passing fractions must run from 0 to 1");
  std::vector<double> breaks;
  std::vector<double> slope;  // the basis density on each piece
  for (std::size_t i = 0; i < table.size(); ++i) {
    breaks.push_back(table[i].size);
    if (i == 0) continue;
    require(table[i].size > table[i - 1].size, "sieve sizes must increase strictly");
    require(table[i].passing >= table[i - 1].passing, "passing fractions must not decrease");
    slope.push_back((table[i].passing - table[i - 1].passing) /
                    (table[i].size - table[i - 1].size));
  }
  return tabulate(breaks, basis, [&slope](std::size_t piece, double) { return slope[piece]; });
}

double SizeDistribution::sample(std::mt19937_64& rng) const {
  return by_number_.invert(diameter_, uniform01(rng));
}

double SizeDistribution::quantile_by_number(double q) const {
  require_fraction(q);
  return by_number_.invert(diameter_, q);
}

double SizeDistribution::quantile_by_mass(double q) const {
  require_fraction(q);
  return by_mass_.invert(diameter_, q);
}

}  // namespace ces::feed
