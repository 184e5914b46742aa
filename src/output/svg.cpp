#include "output/svg.hpp"

#include <cmath>

#include "output/format.hpp"

namespace ces::output::svg {

void text(std::string& s, double x, double y, const std::string& body, const char* anchor,
          std::string_view extra) {
  s += "<text x=\"" + svg_number(x) + "\" y=\"" + svg_number(y) + "\" text-anchor=\"" + anchor +
       "\"";
  s += extra;
  // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on a
  // literal + string + literal chain.
  s += '>';
  s += xml_escape(body);
  s += "</text>\n";
}

void line(std::string& s, double x1, double y1, double x2, double y2, std::string_view style) {
  s += "<line x1=\"" + svg_number(x1) + "\" y1=\"" + svg_number(y1) + "\" x2=\"" + svg_number(x2) +
       "\" y2=\"" + svg_number(y2) + "\" ";
  s += style;
  s += "/>\n";
}

double tick_step(double range) {
  const double raw = range / 5.0;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0})
    if (m * decade >= raw) return m * decade;
  return 10.0 * decade;
}

}  // namespace ces::output::svg
