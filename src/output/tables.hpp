// The result tables users diff in CI: bins.csv, products.csv, crossings.csv,
// lost.csv. Masses in kg, lengths in m, times in s, all with the fixed
// number format of output/format.hpp.
//
// bins.csv and products.csv are tidy: one row per collector, bin (or
// product) and reported material, the material a column of its own, so
// their columns are the same for every scene.
//
// products.csv: per product and material, its count and mass; grade = its
// mass / the product's mass; recovery = its mass in the product / that
// material's mass whose fate is known (collected anywhere, or lost).
// Particles still in flight at the end count in neither, so a run that
// ends early does not read as a poor recovery. Grades and recoveries are
// fractions (0.98, not 98 %), here and in every output. Each comes with
// its standard error over the feed's sampling (ratio_standard_error):
// how much another seed's feed of the same scene moves it.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "output/records.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

// The materials the tables report: those some feed uses, by Model index.
std::vector<int> fed_materials(const Simulation& sim);

// The standard error of part / whole, two sums of the masses of particles
// drawn independently, the part's particles among the whole's: the delta
// method's for a ratio estimator (Cochran, Sampling Techniques, 3rd ed.,
// 1977, section 6.3). With r = part / whole a particle's residual is its
// mass times 1 - r in the part and -r outside it, so
//   se^2 = n / (n - 1) ((1 - r)^2 q_part + r^2 (q_whole - q_part)) / whole^2,
// q the sums of the squared masses, n the whole's particle count. Equal
// masses give the binomial sqrt(r (1 - r) / (n - 1)). 0 for fewer than two
// particles, and where all or none of the whole is in the part: the
// sample then shows no spread (n particles all one way put the other way's
// share below 3 / n by count at 95 %).
double ratio_standard_error(double part, double whole, double q_part, double q_whole,
                            std::uint64_t n);

// One material in one product.
struct ProductShare {
  int material = -1;  // its Model index
  std::uint64_t count = 0;
  double kg = 0.0;
  double grade = 0.0;     // its mass / the product's (0 when the product is empty)
  double recovery = 0.0;  // its mass here / its mass collected or lost (0 when none)
  double grade_se = 0.0, recovery_se = 0.0;  // their standard errors
};

struct ProductResult {
  int collector = 0;
  int product = 0;
  std::vector<ProductShare> shares;  // per reported material
  double total_kg = 0.0;
  int main_share = -1;  // the share of the largest mass; -1 for an empty product
  // The main material's share; all zeros (material -1) for an empty product.
  ProductShare main() const {
    return main_share < 0 ? ProductShare{} : shares[std::size_t(main_share)];
  }
};

std::vector<ProductResult> product_results(const Simulation& sim, const Collection& c,
                                           const std::vector<int>& materials);

// The tables' header lines, which `compare` expects of what it reads.
inline constexpr std::string_view kBinsHeader = "collector,bin,from_m,to_m,material,count,mass_kg";
inline constexpr std::string_view kProductsHeader =
    "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery,grade_se,recovery_se";
inline constexpr std::string_view kCrossingsHeader =
    "id,time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,along_m,diameter_m,mass_kg,material,charge_c,"
    "collector,bin,product";
inline constexpr std::string_view kLostHeader =
    "id,time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,diameter_m,mass_kg,material,reason";

std::string bins_csv(const Simulation& sim, const Collection& c, const std::vector<int>& materials);
std::string products_csv(const Simulation& sim, const std::vector<ProductResult>& products,
                         const std::vector<int>& materials);
// The last step's rows of crossings.csv and lost.csv (no header), in the
// order of Collection::crossings() / losses(): (time, id).
std::string crossing_rows(const Simulation& sim, const Collection& c);
std::string lost_rows(const Simulation& sim, const Collection& c);

}  // namespace ces::output
