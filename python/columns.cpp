#include "columns.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <fstream>
#include <optional>
#include <sstream>
#include <string_view>

namespace ces::python {
namespace {

namespace py = pybind11;
using namespace pybind11::literals;

// The unit suffixes of docs/outputs.md, and study.csv's mm.
constexpr std::array<std::string_view, 10> kUnits = {"_m", "_mm",  "_s", "_kg", "_mps",
                                                     "_c", "_vpm", "_v", "_J",  "_radps"};
// Columns that name things: text, even where every name looks like a number.
constexpr std::array<std::string_view, 6> kNames = {"collector", "product", "material",
                                                    "main_material", "reason", "shape"};
// Columns of fractions, ratios and a quaternion's parts: numbers, even
// where every cell is a whole number.
constexpr std::array<std::string_view, 11> kFractions = {
    "grade", "recovery", "grade_error", "recovery_error", "max_penetration_rel",
    "max_wall_penetration_rel", "max_penetration_relative", "qw", "qx", "qy", "qz"};
// study.csv's distances, one column per material and collector.
constexpr std::string_view kDistancePrefix = "w1_mm ";

bool is_one_of(std::string_view name, const auto& names) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

bool has_unit(std::string_view name) {
  return std::any_of(kUnits.begin(), kUnits.end(),
                     [&](std::string_view u) { return name.ends_with(u); });
}

template <class T>
std::optional<T> parse(std::string_view s) {
  T v{};
  const auto [end, error] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (error != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

// What a column can hold, from the narrowest: each cell widens it.
enum Kind { kInteger, kNumber, kText };

Kind kind_of(std::string_view cell) {
  if (parse<std::int64_t>(cell)) return kInteger;
  return parse<double>(cell) ? kNumber : kText;
}

// The narrowest kind a column of this name may take: a column has the same
// type in every scene and every run, whatever its cells happen to be.
Kind narrowest(std::string_view name) {
  if (is_one_of(name, kNames)) return kText;
  if (has_unit(name) || is_one_of(name, kFractions) || name.starts_with(kDistancePrefix))
    return kNumber;
  return kInteger;
}

void split(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  for (std::size_t start = 0;;) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma - start));
    if (comma == std::string_view::npos) return;
    start = comma + 1;
  }
}

// Calls row(fields) for each line after the header; every line must have
// the header's number of fields.
template <class Row>
void for_each_row(std::string_view text, const std::filesystem::path& path, std::size_t width,
                  Row row) {
  std::vector<std::string_view> fields;
  std::size_t line = 2;  // the file's, counted from 1
  const std::size_t header_end = text.find('\n');
  std::size_t start = header_end == std::string_view::npos ? text.size() : header_end + 1;
  for (; start < text.size(); ++line) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    split(text.substr(start, end - start), fields);
    if (fields.size() != width)
      throw py::value_error(path.string() + ":" + std::to_string(line) + ": " +
                            std::to_string(fields.size()) + " fields where the header has " +
                            std::to_string(width));
    row(fields);
    start = end + 1;
  }
}

Values empty_values(Kind kind) {
  if (kind == kText) return std::vector<std::string>();
  if (kind == kInteger) return std::vector<std::int64_t>();
  return std::vector<double>();
}

void append(Values& values, std::string_view cell) {
  std::visit(
      [&](auto& v) {
        using T = typename std::decay_t<decltype(v)>::value_type;
        if constexpr (std::is_same_v<T, std::string>)
          v.emplace_back(cell);
        else
          v.push_back(*parse<T>(cell));
      },
      values);
}

template <class T>
py::object column_object(const std::vector<T>& v, const py::object& numpy) {
  if (numpy.is_none()) return py::cast(v);
  if constexpr (std::is_same_v<T, std::string>)
    return numpy.attr("array")(py::cast(v), "dtype"_a = "str");
  else
    return py::array_t<T>(py::ssize_t(v.size()), v.data());
}

py::object numpy_if_installed() {
  try {
    return py::module_::import("numpy");
  } catch (py::error_already_set& e) {
    if (!e.matches(PyExc_ImportError)) throw;
    return py::none();
  }
}

}  // namespace

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    PyErr_SetString(PyExc_FileNotFoundError, ("cannot read " + path.string()).c_str());
    throw py::error_already_set();
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Two passes over the text: the first finds each column's kind, the second
// parses the cells into it, so no cell is held as a string on the way.
Table read_csv(const std::filesystem::path& path) {
  const std::string text = read_text(path);
  std::vector<std::string_view> header;
  split(std::string_view(text).substr(0, text.find('\n')), header);
  std::vector<Kind> kinds;
  for (const std::string_view name : header) kinds.push_back(narrowest(name));
  for_each_row(text, path, header.size(), [&](const std::vector<std::string_view>& fields) {
    for (std::size_t k = 0; k < fields.size(); ++k)
      if (kinds[k] != kText) kinds[k] = std::max(kinds[k], kind_of(fields[k]));
  });
  Table table;
  for (std::size_t k = 0; k < header.size(); ++k) {
    table.push_back({std::string(header[k]), empty_values(kinds[k])});
  }
  for_each_row(text, path, header.size(), [&](const std::vector<std::string_view>& fields) {
    for (std::size_t k = 0; k < fields.size(); ++k) append(table[k].values, fields[k]);
  });
  return table;
}

py::dict to_python(const Table& table) {
  const py::object numpy = numpy_if_installed();
  py::dict out;
  for (const Column& c : table)
    out[py::str(c.name)] = std::visit([&](const auto& v) { return column_object(v, numpy); },
                                      c.values);
  return out;
}

}  // namespace ces::python
