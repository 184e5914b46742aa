#include "output/compare.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "common/csv.hpp"
#include "output/files.hpp"
#include "output/format.hpp"
#include "output/tables.hpp"

namespace ces::output {
namespace {

std::vector<std::string> split(std::string_view line) {
  const auto fields = csv::split(line);
  return {fields.begin(), fields.end()};
}

// IoError, as every failure to read a folder is.
std::ifstream open_table(const std::filesystem::path& file) {
  try {
    return csv::open(file);
  } catch (const std::runtime_error& e) {
    throw IoError(e.what());
  }
}

// products.csv as ces-sim wrote it before the grades' and recoveries'
// standard errors: its columns are the first of today's.
constexpr std::string_view kProductsHeaderWithoutErrors =
    "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery";

bool has_control_character(std::string_view s) {
  return std::any_of(s.begin(), s.end(), [](unsigned char b) { return b < 0x20 || b == 0x7F; });
}

// A file's text as a message quotes it: never its control characters (an
// escape sequence would act on the terminal), never more than a short line.
std::string shown_text(std::string_view text) {
  constexpr std::size_t kShown = 80;
  if (has_control_character(text)) return "text with control characters";
  if (text.size() > kShown) return "'" + std::string(text.substr(0, kShown)) + "...'";
  return "'" + std::string(text) + "'";
}

// A cell of a table read_tally_table checked.
double number(const std::string& s) { return *csv::number(s); }

// The columns that name a row of bins.csv or products.csv: the collector,
// the bin or product, the material.
std::vector<std::size_t> key_columns(const Table& t) {
  std::vector<std::size_t> keys;
  for (std::size_t c = 0; c < t.header.size(); ++c)
    if (c == 1 || t.header[c] == "collector" || t.header[c] == "material") keys.push_back(c);
  return keys;
}

std::string row_name(const Table& t, const std::vector<std::string>& row,
                     const std::vector<std::size_t>& keys) {
  std::string name;
  for (const std::size_t c : keys) {
    if (!name.empty()) name += ' ';
    if (c == 1) name.append(t.header[c]).append(" ");
    name += row[c];
  }
  return name;
}

// Mass tolerance scale per collector and material: that material's mass
// over the collector's rows, the larger of the two folders'.
using Scales = std::map<std::pair<std::string, std::string>, double>;

Scales mass_scales(const Table& a, const Table& b, const std::filesystem::path& file) {
  const std::size_t collector = a.column("collector", file), material = a.column("material", file),
                    mass = a.column("mass_kg", file);
  Scales sums[2];
  for (int side = 0; side < 2; ++side)
    for (const auto& row : (side == 0 ? a : b).rows)
      sums[side][{row[collector], row[material]}] += number(row[mass]);
  for (auto& [key, value] : sums[0]) value = std::max(value, sums[1][key]);
  return sums[0];
}

struct CellCheck {
  const std::string& column;
  double a, b;
  double tolerance;
};

// A difference line, or empty when the cell agrees.
std::string check_cell(const std::string& where, const CellCheck& c) {
  const double d = std::abs(c.a - c.b);
  if (d <= c.tolerance) return {};
  return where + " " + c.column + ": " + format_number(c.a) + " vs " + format_number(c.b) +
         " (difference " + format_number(d) + " > tolerance " + format_number(c.tolerance) + ")";
}

std::string compare_cell(const std::string& where, const std::string& column, const std::string& a,
                         const std::string& b, double mass_scale, const CompareOptions& o) {
  if (a == b) return {};
  const double x = number(a), y = number(b);
  if (column == "from_m" || column == "to_m")
    return check_cell(where, {column, x, y, 1e-9 * std::max(std::abs(x), std::abs(y))});
  if (column == "count") return check_cell(where, {column, x, y, double(o.tol_count)});
  if (column == "mass_kg") return check_cell(where, {column, x, y, o.tol_mass * mass_scale});
  if (column == "grade" || column == "recovery" || column == "grade_se" || column == "recovery_se")
    return check_cell(where, {column, x, y, o.tol_mass});
  return where + " " + column + ": " + a + " vs " + b;
}

// The columns past those both tables have (a table from before a column
// was added has the earlier ones, in order), as a note; empty if none.
std::string unshared_columns(const char* file, const Table& a, const Table& b) {
  const bool a_longer = a.header.size() > b.header.size();
  const Table& longer = a_longer ? a : b;
  std::string names;
  for (std::size_t c = std::min(a.header.size(), b.header.size()); c < longer.header.size(); ++c)
    names += (names.empty() ? "" : ", ") + longer.header[c];
  if (names.empty()) return names;
  return std::string(file) + ": " + names + " only in " + (a_longer ? "A" : "B") +
         " (the other written before them): not compared";
}

// Cell-by-cell comparison of bins.csv or products.csv, row by row; the
// collector, bin or product and material name a row.
void compare_tables(const std::filesystem::path& dir_a, const char* file, const Table& a,
                    const Table& b, const CompareOptions& o, CompareResult& r) {
  if (a.rows.size() != b.rows.size()) {
    r.differences.push_back(std::string(file) + ": " + std::to_string(a.rows.size()) +
                            " rows vs " + std::to_string(b.rows.size()));
    return;
  }
  const std::vector<std::size_t> keys = key_columns(a);
  const std::size_t collector = a.column("collector", dir_a / file),
                    material = a.column("material", dir_a / file);
  const Scales scales = mass_scales(a, b, dir_a / file);
  for (std::size_t i = 0; i < a.rows.size(); ++i) {
    const auto &ra = a.rows[i], &rb = b.rows[i];
    const std::string where = std::string(file) + ": " + row_name(a, ra, keys);
    if (row_name(a, ra, keys) != row_name(b, rb, keys)) {
      r.differences.push_back(where + " vs " + row_name(b, rb, keys) + ": rows differ");
      continue;
    }
    const double scale = scales.at({ra[collector], ra[material]});
    for (std::size_t c = 0; c < std::min(ra.size(), rb.size()); ++c) {
      if (std::find(keys.begin(), keys.end(), c) != keys.end()) continue;
      std::string d = compare_cell(where, a.header[c], ra[c], rb[c], scale, o);
      if (!d.empty()) r.differences.push_back(std::move(d));
    }
  }
  r.notes.push_back(std::string(file) + ": " + std::to_string(a.rows.size()) + " rows compared");
  if (std::string unshared = unshared_columns(file, a, b); !unshared.empty())
    r.notes.push_back(std::move(unshared));
}

// A cell ces-sim cannot have written: its names are scene names, which
// hold no control characters, and its counts and masses are not negative,
// the counts whole. The message never echoes the cell's bytes.
void check_tally_cell(const Table& t, std::size_t i, std::size_t c, bool key,
                      const std::filesystem::path& file) {
  const std::string& cell = t.rows[i][c];
  std::string wrong;
  if (key) {
    if (has_control_character(cell)) wrong = "holds a control character, expected a name";
  } else if (const double x = t.number(i, c, file); t.header[c] == "count") {
    if (!(x >= 0.0 && x == std::floor(x))) wrong = "is " + cell + ", expected a whole count >= 0";
  } else if (t.header[c] == "mass_kg" && !(x >= 0.0)) {
    wrong = "is " + cell + ", expected a mass >= 0";
  }
  if (!wrong.empty())
    throw IoError(file.string() + ":" + std::to_string(t.lines[i]) + ": " + t.header[c] + " " +
                  wrong + " (not a table ces-sim wrote)");
}

// bins.csv or products.csv: every cell but those naming its row a number.
Table read_tally_table(const std::filesystem::path& file,
                       std::initializer_list<std::string_view> accepted_headers) {
  Table t = read_table(file, accepted_headers);
  const std::vector<std::size_t> keys = key_columns(t);
  for (std::size_t i = 0; i < t.rows.size(); ++i)
    for (std::size_t c = 0; c < t.header.size(); ++c)
      check_tally_cell(t, i, c, std::find(keys.begin(), keys.end(), c) != keys.end(), file);
  return t;
}

void compare_landings(const Landings& a, const Landings& b, const CompareOptions& o,
                      CompareResult& r) {
  std::vector<std::string> keys;
  for (const auto& [k, v] : a) keys.push_back(k);
  for (const auto& [k, v] : b)
    if (!a.count(k)) keys.push_back(k);
  std::sort(keys.begin(), keys.end());
  for (const std::string& k : keys) {
    const auto ia = a.find(k), ib = b.find(k);
    if (ia == a.end() || ib == b.end()) {
      r.differences.push_back("crossings.csv: " + k + ": collected only in " +
                              (ia == a.end() ? "B" : "A"));
      continue;
    }
    const double w1 = 1e3 * wasserstein1(ia->second, ib->second);
    r.notes.push_back("crossings.csv: " + k + ": W1 " + format_number(w1) + " mm");
    if (w1 > o.tol_w1_mm)
      r.differences.push_back("crossings.csv: " + k + ": landing distributions differ by W1 " +
                              format_number(w1) + " mm > tolerance " + format_number(o.tol_w1_mm) +
                              " mm");
  }
}

}  // namespace

double Table::number(std::size_t row, std::size_t column, const std::filesystem::path& file) const {
  const std::string& cell = rows[row][column];
  if (const auto v = csv::number(cell)) return *v;
  throw IoError(file.string() + ":" + std::to_string(lines[row]) + ": " + header[column] +
                " is not a finite number: " + shown_text(cell));
}

std::size_t Table::column(const std::string& name, const std::filesystem::path& file) const {
  const auto it = std::find(header.begin(), header.end(), name);
  if (it == header.end()) throw IoError(file.string() + ": no column '" + name + "'");
  return std::size_t(it - header.begin());
}

Table read_table(const std::filesystem::path& file,
                 std::initializer_list<std::string_view> accepted_headers) {
  std::ifstream in = open_table(file);
  Table t;
  std::string line;
  if (!std::getline(in, line)) throw IoError(file.string() + ": empty file");
  t.header = split(csv::without_bom(line));
  const bool accepted = accepted_headers.size() == 0 ||
                        std::any_of(accepted_headers.begin(), accepted_headers.end(),
                                    [&](std::string_view h) { return t.header == split(h); });
  if (!accepted) {
    std::string expected;
    for (std::string_view h : accepted_headers)
      expected += (expected.empty() ? "" : " or ") + std::string(h);
    throw IoError(file.string() + ":1: expected the header " + expected + ", found " +
                  shown_text(csv::trim(csv::without_bom(line))));
  }
  for (int n = 2; std::getline(in, line); ++n) {
    if (csv::trim(line).empty()) continue;
    t.rows.push_back(split(line));
    t.lines.push_back(n);
    if (t.rows.back().size() != t.header.size())
      throw IoError(file.string() + ":" + std::to_string(n) + ": expected " +
                    std::to_string(t.header.size()) + " fields");
  }
  return t;
}

Landings read_landings(const std::filesystem::path& file) {
  const Table t = read_table(file, {kCrossingsHeader});
  const std::size_t along = t.column("along_m", file), mass = t.column("mass_kg", file),
                    material = t.column("material", file), collector = t.column("collector", file);
  Landings out;
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    const auto& row = t.rows[i];
    const double x = t.number(i, along, file), kg = t.number(i, mass, file);
    out[row[material] + " at " + row[collector]].emplace_back(x, kg);
  }
  return out;
}

double wasserstein1(std::vector<std::pair<double, double>> a,
                    std::vector<std::pair<double, double>> b) {
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  double wa = 0, wb = 0;
  for (const auto& p : a) wa += p.second;
  for (const auto& p : b) wb += p.second;
  // Integrate |F_a - F_b| between consecutive positions of the merged samples.
  double fa = 0, fb = 0, distance = 0;
  std::size_t i = 0, j = 0;
  double x = std::min(a.empty() ? 0.0 : a[0].first, b.empty() ? 0.0 : b[0].first);
  while (i < a.size() || j < b.size()) {
    const double next =
        std::min(i < a.size() ? a[i].first : b[j].first, j < b.size() ? b[j].first : a[i].first);
    distance += std::abs(fa - fb) * (next - x);
    x = next;
    for (; i < a.size() && a[i].first == next; ++i) fa += a[i].second / wa;
    for (; j < b.size() && b[j].first == next; ++j) fb += b[j].second / wb;
  }
  return distance;
}

namespace {

// Whether the run in `dir` completed, by its summary.json: a note where it
// did not, or where that is not known. The tables of a run that stopped
// hold what it had collected by then.
void note_incomplete(const std::filesystem::path& dir, CompareResult& r) {
  std::ifstream in(dir / "summary.json");
  const nlohmann::json summary = nlohmann::json::parse(in, nullptr, false);
  if (!summary.is_object() || !summary.contains("complete") || !summary["complete"].is_boolean()) {
    r.notes.push_back(dir.string() + ": no summary.json saying whether its run completed");
    return;
  }
  if (summary["complete"].get<bool>()) return;
  const std::string reason =
      summary.contains("reason") && summary["reason"].is_string() ? summary["reason"] : "";
  r.notes.push_back(dir.string() + ": its run did not complete (" + reason +
                    "): its tables hold what it had collected when it stopped");
}

}  // namespace

CompareResult compare_outputs(const std::filesystem::path& a, const std::filesystem::path& b,
                              const CompareOptions& options) {
  CompareResult r;
  note_incomplete(a, r);
  note_incomplete(b, r);
  compare_tables(a, "bins.csv", read_tally_table(a / "bins.csv", {kBinsHeader}),
                 read_tally_table(b / "bins.csv", {kBinsHeader}), options, r);
  const auto products = [](const std::filesystem::path& dir) {
    return read_tally_table(dir / "products.csv", {kProductsHeader, kProductsHeaderWithoutErrors});
  };
  compare_tables(a, "products.csv", products(a), products(b), options, r);
  compare_landings(read_landings(a / "crossings.csv"), read_landings(b / "crossings.csv"), options, r);
  return r;
}

}  // namespace ces::output
