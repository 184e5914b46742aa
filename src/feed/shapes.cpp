#include "feed/shapes.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace ces::feed {
namespace {

// ceil(x), robust to x landing a rounding error above an integer.
int whole_steps(double x) { return int(std::ceil(x - 1e-9)); }

std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

// Four comma-separated numbers, or nothing.
bool parse_row(std::string_view line, double (&v)[4]) {
  for (int k = 0; k < 4; ++k) {
    const auto comma = k < 3 ? line.find(',') : line.size();
    if (comma == std::string_view::npos) return false;
    const std::string_view field = trim(line.substr(0, comma));
    const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), v[k]);
    if (ec != std::errc() || end != field.data() + field.size() || !std::isfinite(v[k]))
      return false;
    line.remove_prefix(std::min(line.size(), comma + 1));
  }
  return true;
}

bool is_header(std::string_view line) {
  std::string compact;
  for (const char c : line)
    if (c != ' ' && c != '\t' && c != '\r') compact += c;
  return compact == "x,y,z,r";
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
  // Not a device or a pipe: reading one may never end.
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(path.string() + ": not a regular file");
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open the file");
  SphereList out;
  std::string text;
  bool first_row = true;
  for (int line = 1; std::getline(in, text); ++line) {
    const std::string_view row = trim(text);
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
