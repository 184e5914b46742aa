#include "feed/shapes.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <string_view>

#include "common/csv.hpp"

namespace ces::feed {
namespace {

// ceil(x), robust to x landing a rounding error above an integer.
int whole_steps(double x) { return int(std::ceil(x - 1e-9)); }

// Four comma-separated numbers, or nothing.
bool parse_row(std::string_view line, double (&v)[4]) {
  const auto fields = csv::split(line);
  if (fields.size() != 4) return false;
  for (int k = 0; k < 4; ++k) {
    const auto parsed = csv::number(fields[k]);
    if (!parsed) return false;
    v[k] = *parsed;
  }
  return true;
}

bool is_header(std::string_view line) {
  const auto fields = csv::split(line);
  constexpr std::string_view kHeader[] = {"x", "y", "z", "r"};
  return std::equal(fields.begin(), fields.end(), std::begin(kHeader), std::end(kHeader));
}

}  // namespace

SphereList flake_spheres(double aspect) {
  const double r = 0.5 * aspect;
  const double reach = 0.5 - r;  // of the outermost centres
  const int rings = whole_steps(reach / (2.0 * r));
  const double spacing = rings > 0 ? reach / rings : 0.0;
  SphereList out;
  // Axial hexagonal coordinates (q, k): ring max(|q|, |k|, |q + k|).
  for (int k = -rings; k <= rings; ++k) {
    for (int q = -rings; q <= rings; ++q) {
      if (std::abs(q + k) > rings) continue;
      out.centers.emplace_back(spacing * (q + 0.5 * k), spacing * std::sqrt(3.0) / 2.0 * k, 0.0);
      out.radii.push_back(r);
    }
  }
  return out;
}

SphereList rod_spheres(double aspect) {
  const double r = 0.5 * aspect;
  const double span = 1.0 - 2.0 * r;  // between the end centres
  const int gaps = whole_steps(span / r);
  SphereList out;
  for (int i = 0; i <= gaps; ++i) {
    out.centers.emplace_back(gaps > 0 ? -0.5 * span + span * i / gaps : 0.0, 0.0, 0.0);
    out.radii.push_back(r);
  }
  return out;
}

SphereList read_sphere_csv(const std::filesystem::path& path) {
  std::ifstream in = csv::open(path);
  SphereList out;
  std::string text;
  bool first_row = true;
  for (int line = 1; std::getline(in, text); ++line) {
    const std::string_view row = csv::trim(line == 1 ? csv::without_bom(text) : text);
    if (row.empty() || row.front() == '#') continue;
    const bool header = first_row && is_header(row);
    first_row = false;
    if (header) continue;
    double v[4];
    if (!parse_row(row, v) || !(v[3] > 0.0))
      throw std::runtime_error(path.string() + ":" + std::to_string(line) +
                               ": expected a row x,y,z,r of numbers with r > 0, got '" +
                               std::string(row) + "'");
    out.centers.emplace_back(v[0], v[1], v[2]);
    out.radii.push_back(v[3]);
  }
  if (out.centers.empty()) throw std::runtime_error(path.string() + ": no spheres in the file");
  return out;
}

}  // namespace ces::feed
