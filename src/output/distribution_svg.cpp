#include "output/distribution_svg.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "output/format.hpp"
#include "output/svg.hpp"

namespace ces::output {
namespace {

// Okabe–Ito colours: distinguishable with colour-blindness and in print.
constexpr const char* kColours[] = {"#D55E00", "#0072B2", "#009E73", "#CC79A7",
                                    "#E69F00", "#56B4E9", "#000000", "#F0E442"};
constexpr double kWidth = 760, kPanelHeight = 420;
constexpr double kMarginLeft = 80, kMarginRight = 170, kMarginTop = 50, kMarginBottom = 60;

// v rounded up to a whole tick of an axis running from 0 to it.
double tick_ceiling(double v) {
  const double step = svg::tick_step(v);
  return std::ceil(v / step) * step;
}

// Maps data (mm, %) to the pixels of one panel.
struct Frame {
  double x0, x1, y1;  // data ranges; y starts at 0
  double top;         // panel offset (px)
  double px(double x) const {
    return kMarginLeft + (x - x0) / (x1 - x0) * (kWidth - kMarginLeft - kMarginRight);
  }
  double py(double y) const {
    return top + kMarginTop + (1.0 - y / y1) * (kPanelHeight - kMarginTop - kMarginBottom);
  }
};

void axes(std::string& s, const Frame& f) {
  const double bottom = f.py(0), top = f.py(f.y1);
  s += "<rect x=\"" + svg_number(kMarginLeft) + "\" y=\"" + svg_number(top) + "\" width=\"" +
       svg_number(f.px(f.x1) - kMarginLeft) + "\" height=\"" + svg_number(bottom - top) +
       "\" fill=\"none\" stroke=\"#000\"/>\n";
  const double dx = svg::tick_step(f.x1 - f.x0);
  for (double x = std::ceil(f.x0 / dx) * dx; x <= f.x1 + 1e-9 * dx; x += dx) {
    svg::line(s, f.px(x), bottom, f.px(x), bottom + 5, "stroke=\"#000\"");
    svg::text(s, f.px(x), bottom + 20, format_number(std::abs(x) < 1e-9 * dx ? 0.0 : x), "middle");
  }
  const double dy = svg::tick_step(f.y1);
  for (double y = 0; y <= f.y1 + 1e-9 * dy; y += dy) {
    svg::line(s, kMarginLeft - 5, f.py(y), kMarginLeft, f.py(y), "stroke=\"#000\"");
    svg::text(s, kMarginLeft - 8, f.py(y) + 5, format_number(y), "end");
  }
  svg::text(s, (kMarginLeft + f.px(f.x1)) / 2, bottom + 45,
            "Position along the collector axis (mm)", "middle");
  const double mid = (top + bottom) / 2;
  svg::text(s, 25, mid, "Mass (% of the material collected)", "middle",
            " transform=\"rotate(-90 25 " + svg_number(mid) + ")\"");
}

// Dashed lines at the product boundaries (once where two products meet),
// product names along the top.
void product_marks(std::string& s, const Frame& f, const Collector& c) {
  std::vector<double> edges;
  for (const Product& p : c.products) {
    const double a = std::max(p.from * 1e3, f.x0), b = std::min(p.to * 1e3, f.x1);
    if (a >= b) continue;
    edges.insert(edges.end(), {a, b});
    svg::text(s, (f.px(a) + f.px(b)) / 2, f.py(f.y1) + 16, p.name, "middle",
              " fill=\"#555\" font-size=\"12\"");
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const double edge : edges)
    if (edge > f.x0 && edge < f.x1)
      svg::line(s, f.px(edge), f.py(0), f.px(edge), f.py(f.y1),
                "stroke=\"#888\" stroke-dasharray=\"6 4\"");
}

// Mass % per bin of one material, or empty if the collector got none of it.
std::vector<double> percentages(const CollectorTallies& t, const Collector& c, int m,
                                std::size_t materials) {
  const MassUnits total = t.total[std::size_t(m)].mass;
  if (total == 0) return {};
  std::vector<double> pct(std::size_t(c.bins));
  for (std::size_t b = 0; b < pct.size(); ++b)
    pct[b] = 100.0 * double(t.bins[b * materials + std::size_t(m)].mass) / double(total);
  return pct;
}

void path_point(std::string& d, char command, double x, double y) {
  d += command;
  d += svg_number(x);
  d += ',';
  d += svg_number(y);
  d += ' ';
}

void step_line(std::string& s, const Frame& f, const std::vector<double>& pct, const char* colour) {
  const double width = (f.x1 - f.x0) / double(pct.size());
  std::string d;
  path_point(d, 'M', f.px(f.x0), f.py(0));
  for (std::size_t b = 0; b < pct.size(); ++b) {
    path_point(d, 'L', f.px(f.x0 + double(b) * width), f.py(pct[b]));
    path_point(d, 'L', f.px(f.x0 + double(b + 1) * width), f.py(pct[b]));
  }
  path_point(d, 'L', f.px(f.x1), f.py(0));
  s += "<path d=\"" + d + "\" fill=\"" + colour + "\" fill-opacity=\"0.12\" stroke=\"" + colour +
       "\" stroke-width=\"2\"/>\n";
}

void panel(std::string& s, const Simulation& sim, const Collection& c, std::size_t k,
           const std::vector<int>& materials) {
  const Collector& col = sim.collectors[k];
  const CollectorTallies& t = c.collectors()[k];
  std::vector<std::vector<double>> pct;
  double peak = 0;
  for (const int m : materials) {
    pct.push_back(percentages(t, col, m, c.material_count()));
    for (const double p : pct.back()) peak = std::max(peak, p);
  }
  const double y1 = peak > 0 ? tick_ceiling(1.1 * peak) : 100.0;
  const Frame f{col.from * 1e3, col.to * 1e3, y1, double(k) * kPanelHeight};
  svg::text(s, kWidth / 2, f.top + 28, sim.name + ": landing distribution at " + col.name, "middle",
            " font-size=\"16\"");
  axes(s, f);
  product_marks(s, f, col);
  double legend_y = f.py(f.y1) + 10;
  for (std::size_t i = 0; i < materials.size(); ++i) {
    const char* colour = kColours[i % std::size(kColours)];
    if (pct[i].empty()) continue;
    step_line(s, f, pct[i], colour);
    const double x = f.px(f.x1) + 15;
    svg::line(s, x, legend_y, x + 28, legend_y,
              "stroke=\"" + std::string(colour) + "\" stroke-width=\"3\"");
    svg::text(s, x + 36, legend_y + 5,
              sim.model->materials.materials()[std::size_t(materials[i])].name, "start");
    legend_y += 22;
  }
  if (peak == 0)
    svg::text(s, (kMarginLeft + f.px(f.x1)) / 2, f.py(y1 / 2), "nothing collected", "middle");
}

}  // namespace

std::string distribution_svg(const Simulation& sim, const Collection& c,
                             const std::vector<int>& materials) {
  const double height = kPanelHeight * double(std::max<std::size_t>(1, sim.collectors.size()));
  std::string s =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" "
      "width=\"" +
      svg_number(kWidth) + "\" height=\"" + svg_number(height) + "\" viewBox=\"0 0 " +
      svg_number(kWidth) + " " + svg_number(height) +
      "\" font-family=\"Helvetica, Arial, sans-serif\" font-size=\"14\">\n"
      "<rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>\n";
  for (std::size_t k = 0; k < sim.collectors.size(); ++k) panel(s, sim, c, k, materials);
  s += "</svg>\n";
  return s;
}

}  // namespace ces::output
