#include "format.hpp"

#include <cstdio>

namespace ces::exporter {

std::string metres(double v) {
  char s[32];
  if (std::abs(v) >= 0.1)
    std::snprintf(s, sizeof s, "%.4g m", v);
  else
    std::snprintf(s, sizeof s, "%.4g mm", 1e3 * v);
  return s;
}

std::string percent(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%.3g %%", 100.0 * v);
  return s;
}

std::string vector_text(const Vec3& v) {
  char s[96];
  // Rounding noise (-1e-17) reads as a real component; print it as 0.
  const auto clean = [](double x) { return std::abs(x) < 1e-12 ? 0.0 : x; };
  std::snprintf(s, sizeof s, "[%.6g, %.6g, %.6g]", clean(v.x()), clean(v.y()), clean(v.z()));
  return s;
}

}  // namespace ces::exporter
