// `ces-sim compare`: do two output folders agree within tolerances?
//  - bins.csv and products.csv: row by row (collector, bin or product,
//    material), cell by cell; counts within tol_count particles; masses
//    within tol_mass times the larger total mass of that material in that
//    collector (both folders); grade and recovery within tol_mass
//    (absolute);
//  - crossings.csv: per collector and material, the Wasserstein-1 distance of
//    the mass-weighted landing positions along the collector axis within
//    tol_w1_mm.
// Differences in layout (bins, products) are always differences; a table
// without the header ces-sim writes is refused. A products.csv from before
// its standard-error columns is read, and compared on the columns both
// folders have (a note names the others).
#pragma once
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace ces::output {

struct CompareOptions {
  std::uint64_t tol_count = 0;
  double tol_mass = 0.0;
  double tol_w1_mm = 0.0;
};

struct CompareResult {
  std::vector<std::string> differences;  // one readable line each
  std::vector<std::string> notes;        // what was compared, e.g. W1 values
  bool agree() const { return differences.empty(); }
};

// A CSV table as written by output/tables (no quoting). Throws IoError when
// the file is missing, empty or ragged, has none of the accepted headers
// (when any are given; the error names the first, today's), or lacks a
// requested column or number.
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::vector<int> lines;  // each row's line in the file
  std::size_t column(const std::string& name, const std::filesystem::path& file) const;
  double number(std::size_t row, std::size_t column, const std::filesystem::path& file) const;
};
Table read_table(const std::filesystem::path& file,
                 std::initializer_list<std::string_view> accepted_headers = {});

// Landing positions along the collector axis and masses, per
// "material at collector", from a crossings.csv.
using Landings = std::map<std::string, std::vector<std::pair<double, double>>>;
Landings read_landings(const std::filesystem::path& crossings_csv);

// Throws IoError when a folder lacks a file or a file is not a table.
CompareResult compare_outputs(const std::filesystem::path& a, const std::filesystem::path& b,
                              const CompareOptions& options);

// Wasserstein-1 distance between two weighted samples of positions
// (position, weight); each is normalised to total weight 1.
double wasserstein1(std::vector<std::pair<double, double>> a,
                    std::vector<std::pair<double, double>> b);

}  // namespace ces::output
