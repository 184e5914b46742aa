// The result tables users diff in CI: bins.csv, products.csv, crossings.csv,
// lost.csv. Masses in kg, lengths in m, times in s, all with the fixed
// number format of output/format.hpp.
//
// products.csv: per product, the mass of each material; its main material
// (the largest mass); grade = main material mass / product mass; recovery =
// main material mass in the product / that material's mass whose fate is
// known (collected anywhere, or lost). Particles still in flight at the end
// count in neither, so a run that ends early does not read as a poor recovery.
#pragma once
#include <string>
#include <vector>

#include "output/records.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

// The materials the tables report: those some feed uses, by Model index.
std::vector<int> fed_materials(const Simulation& sim);

struct ProductResult {
  int collector = 0;
  int product = 0;
  std::vector<double> kg;  // per reported material
  double total_kg = 0.0;
  int main_material = -1;  // Model index; -1 for an empty product
  double grade = 0.0;
  double recovery = 0.0;
};

std::vector<ProductResult> product_results(const Simulation& sim, const Collection& c,
                                           const std::vector<int>& materials);

std::string bins_csv(const Simulation& sim, const Collection& c, const std::vector<int>& materials);
std::string products_csv(const Simulation& sim, const std::vector<ProductResult>& products,
                         const std::vector<int>& materials);
// Rows in the order of Collection::crossings() / losses() (sort them first).
std::string crossings_csv(const Simulation& sim, const Collection& c);
std::string lost_csv(const Simulation& sim, const Collection& c);

}  // namespace ces::output
