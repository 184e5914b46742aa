// Particle size distributions of the feed. Diameters in metres.
//
// A distribution is given either by number (the density of particle counts
// over diameter) or by mass (the density of mass over diameter, what a sieve
// analysis measures). A feeder spawns particles, so sampling is always by
// number: for a mass-basis law the number density is f_mass(d)/d³,
// renormalised.
//
// Construction tabulates the number and mass CDFs once, on a fine grid with
// Gauss–Legendre integration of the analytic density (every sieve size is a
// grid node, so kinks are exact); sampling inverts the number CDF, taking the
// density as linear inside a grid interval (exact for piecewise-constant
// densities, ~1e-8 relative in the quantiles otherwise). Sampling
// uses only the raw bits of std::mt19937_64 (a fully specified engine) and
// arithmetic, never std::*_distribution, so a seed gives the same sizes with
// every standard library.
#pragma once
#include <random>
#include <vector>

namespace ces::feed {

enum class Basis { number, mass };

class SizeDistribution {
 public:
  // Cumulative fraction passing a sieve of `size` (m); by number or by mass
  // according to the basis.
  struct SievePoint {
    double size = 0.0;
    double passing = 0.0;
  };

  // Every particle has diameter d > 0.
  static SizeDistribution constant(double diameter);
  // Uniform density on [min, max].
  static SizeDistribution uniform(double min, double max, Basis basis);
  // Normal density of the basis truncated to [min, max] and renormalised
  // (no point masses at the bounds).
  static SizeDistribution normal(double mean, double sd, double min, double max, Basis basis);
  // ln d normal with median `median` and standard deviation `sigma`,
  // truncated to [min, max] and renormalised.
  static SizeDistribution lognormal(double median, double sigma, double min, double max,
                                    Basis basis);
  // Sizes strictly increasing from > 0, passing fractions non-decreasing from
  // 0 to 1; the CDF is linear in d between sieves.
  static SizeDistribution sieve(const std::vector<SievePoint>& table, Basis basis);

  // One particle diameter, drawn by number (what a feeder spawns).
  double sample(std::mt19937_64& rng) const;

  double mean_by_number() const { return mean_; }
  // E[d³] by number: the mean particle mass is ρ π/6 times this.
  double mean_mass_per_particle_factor() const { return mean_cube_; }
  // Diameter below which a fraction q (0..1) of the particles lie.
  double quantile_by_number(double q) const;
  // Diameter below which a fraction q (0..1) of the mass lies.
  double quantile_by_mass(double q) const;

 private:
  SizeDistribution() = default;

  template <class Density>
  static SizeDistribution tabulate(const std::vector<double>& breaks, Basis basis,
                                   const Density& density);

  // A CDF at the grid nodes; inside each interval the density is taken as
  // linear, tilted by (f_right − f_left)/(f_right + f_left).
  struct Cdf {
    std::vector<double> value;  // at the nodes, 0 .. 1
    std::vector<double> tilt;   // per interval, −1 .. 1
    double invert(const std::vector<double>& nodes, double q) const;
  };

  std::vector<double> diameter_;  // grid nodes, increasing
  Cdf by_number_;
  Cdf by_mass_;
  double mean_ = 0.0;
  double mean_cube_ = 0.0;
};

}  // namespace ces::feed
