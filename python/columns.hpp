// Tables for Python as columns: {name: numpy array} where numpy imports,
// {name: list} where it does not. A run's CSV files read back the same way.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <variant>
#include <vector>

#include <pybind11/pybind11.h>

namespace ces::python {

using Values =
    std::variant<std::vector<double>, std::vector<std::int64_t>, std::vector<std::string>>;

struct Column {
  std::string name;
  Values values;
};
using Table = std::vector<Column>;

// A run's CSV file (one header row, comma-separated, no quoting; the
// conventions of docs/outputs.md). A column holds text when it names
// things (collector, product, material, ...) or a cell is not a number;
// integers when its name carries no unit, it is no fraction (grade,
// recovery) and every cell is an integer; numbers otherwise. Throws
// FileNotFoundError, or ValueError naming the line of a row that does not
// match the header.
Table read_csv(const std::filesystem::path& path);

// The whole file; throws FileNotFoundError when it cannot be read.
std::string read_text(const std::filesystem::path& path);

// numpy arrays (float64, int64, str) when numpy imports, else lists.
pybind11::dict to_python(const Table& table);

}  // namespace ces::python
