#include "output/field_picture.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>

#include "output/format.hpp"
#include "output/svg.hpp"

namespace ces::output {
namespace {

// ------------------------------------------------------------ sampling

std::optional<double> potential(const fields::ElectricField& model, const Vec3& x) {
  if (const auto* b = std::get_if<fields::BipolarField>(&model)) return b->potential(x);
  if (const auto* l = std::get_if<fields::LineChargeField>(&model)) return l->potential(x);
  return std::nullopt;  // a gridded field carries no potential
}

int node_count(double from, double to, double step) {
  return int(std::floor((to - from) / step + 1e-9)) + 1;
}

// ------------------------------------------------------------ SVG helpers

constexpr double kPlot = 560;  // px along the longer side of the picture
constexpr double kLeft = 70, kTop = 56, kRight = 170, kBottom = 56;
constexpr int kLevels = 20;           // colour bands of |E|
constexpr double kArrowsAcross = 22;  // arrows along the longer side
constexpr double kVperCm = 1e5;       // V/m in one kV/cm

// ColorBrewer YlOrRd: pale where the field is weak, dark where it is strong;
// black arrows stay readable on every band.
constexpr std::array<const char*, 9> kRamp = {"ffffcc", "ffeda0", "fed976", "feb24c", "fd8d3c",
                                              "fc4e2a", "e31a1c", "bd0026", "800026"};
constexpr const char* kDrumFill = "#c8c8c8";
constexpr const char* kElectrodeFill = "#505050";
// A white outline keeps labels readable over arrows and colour bands.
constexpr const char* kHalo = " stroke=\"#fff\" stroke-width=\"3\" paint-order=\"stroke\"";

// Linear blend of the ramp at t in [0, 1], as "#rrggbb".
std::string ramp_colour(double t) {
  const double pos = std::clamp(t, 0.0, 1.0) * double(kRamp.size() - 1);
  const auto k = std::min(std::size_t(pos), kRamp.size() - 2);
  const double f = pos - double(k);
  std::string out = "#";
  for (int c = 0; c < 3; ++c) {
    const int a = std::stoi(std::string(kRamp[k] + 2 * c, 2), nullptr, 16);
    const int b = std::stoi(std::string(kRamp[k + 1] + 2 * c, 2), nullptr, 16);
    const int v = int(std::lround(a + f * (b - a)));
    const char hex[] = "0123456789abcdef";
    out += hex[v / 16];
    out += hex[v % 16];
  }
  return out;
}

std::string level_colour(int level) { return ramp_colour((level + 0.5) / kLevels); }

// The smallest of 1, 2, 2.5, 5 times a power of ten at or above v > 0.
double nice_ceiling(double v) {
  const double decade = std::pow(10.0, std::floor(std::log10(v)));
  for (const double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * decade >= v * (1.0 - 1e-12)) return m * decade;
  return 10.0 * decade;
}

// A rectangle as a closed subpath: "Mx,yh<w>v<h>h<-w>z".
void append_rect(std::string& d, const Vec2& corner, double w, double h) {
  d += 'M';
  d += svg_number(corner.x());
  d += ',';
  d += svg_number(corner.y());
  d += 'h';
  d += svg_number(w);
  d += 'v';
  d += svg_number(h);
  d += 'h';
  d += svg_number(-w);
  d += 'z';
}

void circle(std::string& s, const Vec2& c, double r, const char* fill) {
  s += "<circle cx=\"" + svg_number(c.x()) + "\" cy=\"" + svg_number(c.y()) + "\" r=\"" +
       svg_number(r) + "\" fill=\"" + fill + "\" stroke=\"#000\" stroke-width=\"1.5\"/>\n";
}

// ------------------------------------------------------------ the picture

class FieldSvg {
 public:
  FieldSvg(const Simulation& sim, const FieldGrid& g) : sim_(sim), g_(g) {
    const double res = g.picture.resolution;
    lo_ = g.node(0, 0) - Vec2::Constant(0.5 * res);
    hi_ = g.node(g.nx - 1, g.ny - 1) + Vec2::Constant(0.5 * res);
    scale_ = kPlot / (hi_ - lo_).maxCoeff();
    width_ = (hi_.x() - lo_.x()) * scale_;
    height_ = (hi_.y() - lo_.y()) * scale_;
    classify();
  }

  std::string render() {
    std::string s = header();
    s += "<g clip-path=\"url(#plot)\">\n";
    bands(s);
    conductors(s);
    arrows(s);
    s += "</g>\n";
    axes(s);
    colour_bar(s);
    s += "</svg>\n";
    return s;
  }

 private:
  static constexpr int kDrum = -1, kElectrode = -2;

  double px(double x) const { return kLeft + (x - lo_.x()) * scale_; }
  double py(double y) const { return kTop + (hi_.y() - y) * scale_; }
  Vec2 to_px(const Vec2& p) const { return {px(p.x()), py(p.y())}; }

  int conductor_at(const Vec2& p) const {
    if (p.norm() < sim_.electrostatics->drum.radius) return kDrum;
    for (const NamedElectrode& e : sim_.electrodes)
      if ((p - e.electrode.centre).norm() < e.electrode.radius) return kElectrode;
    return 0;
  }

  // A band per node (or a conductor); the top of the scale is the 99th
  // percentile of |E| outside the conductors, rounded up, so a thin
  // corona wire's peak does not wash out the rest.
  void classify() {
    std::vector<double> magnitude;
    for (int j = 0; j < g_.ny; ++j)
      for (int i = 0; i < g_.nx; ++i)
        if (conductor_at(g_.node(i, j)) == 0) magnitude.push_back(field(i, j).norm() / kVperCm);
    double p99 = 0.0;
    if (!magnitude.empty()) {
      const auto k = magnitude.begin() + std::ptrdiff_t(0.99 * double(magnitude.size() - 1));
      std::nth_element(magnitude.begin(), k, magnitude.end());
      p99 = *k;
    }
    top_ = p99 > 0.0 ? nice_ceiling(p99) : 1.0;
    level_.resize(std::size_t(g_.nx) * std::size_t(g_.ny));
    for (int j = 0; j < g_.ny; ++j) {
      for (int i = 0; i < g_.nx; ++i) {
        const int c = conductor_at(g_.node(i, j));
        const double t = field(i, j).norm() / kVperCm / top_;
        level_[index(i, j)] = c != 0 ? c : std::min(kLevels - 1, int(t * kLevels));
      }
    }
  }

  std::size_t index(int i, int j) const {
    return std::size_t(i) + std::size_t(g_.nx) * std::size_t(j);
  }
  const Vec2& field(int i, int j) const { return g_.field[index(i, j)]; }

  std::string header() const {
    const double w = kLeft + width_ + kRight, h = kTop + height_ + kBottom;
    std::string s =
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" "
        "width=\"" +
        svg_number(w) + "\" height=\"" + svg_number(h) + "\" viewBox=\"0 0 " + svg_number(w) + " " +
        svg_number(h) +
        "\" font-family=\"Helvetica, Arial, sans-serif\" font-size=\"13\">\n"
        "<defs><marker id=\"head\" viewBox=\"0 0 10 10\" refX=\"8\" refY=\"5\" markerWidth=\"4\" "
        "markerHeight=\"4\" orient=\"auto\"><path d=\"M0,0 L10,5 L0,10 z\" fill=\"#1a1a1a\"/>"
        "</marker><clipPath id=\"plot\"><rect x=\"" +
        svg_number(kLeft) + "\" y=\"" + svg_number(kTop) + "\" width=\"" + svg_number(width_) +
        "\" height=\"" + svg_number(height_) +
        "\"/></clipPath></defs>\n<rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>\n";
    svg::text(s, kLeft + width_ / 2, 24,
              sim_.name + ": electric field at z = 0 (" + model_name() + ")", "middle",
              " font-size=\"16\"");
    return s;
  }

  std::string model_name() const {
    const auto& f = sim_.electrostatics->field;
    if (std::holds_alternative<fields::BipolarField>(f)) return "bipolar, exact";
    if (std::holds_alternative<fields::LineChargeField>(f)) return "line charges with images";
    return "gridded field";
  }

  // One path per band: runs of equal bands along each row become rectangles.
  void bands(std::string& s) const {
    std::vector<std::string> paths(kLevels);
    const double cell = g_.picture.resolution * scale_;
    for (int j = 0; j < g_.ny; ++j) {
      for (int i = 0; i < g_.nx;) {
        const int level = level_[index(i, j)];
        int end = i + 1;
        while (end < g_.nx && level_[index(end, j)] == level) ++end;
        if (level >= 0) {
          const Vec2 corner = to_px(g_.node(i, j)) - Vec2(0.5 * cell, 0.5 * cell);
          append_rect(paths[std::size_t(level)], corner, cell * (end - i), cell);
        }
        i = end;
      }
    }
    s += "<g shape-rendering=\"crispEdges\">\n";
    for (int k = 0; k < kLevels; ++k)
      if (!paths[std::size_t(k)].empty())
        s += "<path fill=\"" + level_colour(k) + "\" d=\"" + paths[std::size_t(k)] + "\"/>\n";
    s += "</g>\n";
  }

  void conductors(std::string& s) const {
    const double r = sim_.electrostatics->drum.radius;
    circle(s, to_px(Vec2::Zero()), r * scale_, kDrumFill);
    svg::text(s, px(0), py(0) + 5, "drum, 0 V", "middle");
    for (const NamedElectrode& e : sim_.electrodes) {
      const Vec2 c = to_px(e.electrode.centre);
      const double rp = std::max(2.0, e.electrode.radius * scale_);  // a wire stays visible
      circle(s, c, rp, kElectrodeFill);
      svg::text(s, c.x(), c.y() + rp + 15,
                e.name + ", " + format_number(e.electrode.potential / 1e3) + " kV", "middle",
                kHalo);
    }
  }

  // Direction only (fixed length): the colour carries the magnitude.
  void arrows(std::string& s) const {
    const int stride = std::max(1, int(std::lround(std::max(g_.nx, g_.ny) / kArrowsAcross)));
    const double half = 0.38 * stride * g_.picture.resolution * scale_;
    for (int j = stride / 2; j < g_.ny; j += stride) {
      for (int i = stride / 2; i < g_.nx; i += stride) {
        const Vec2& e = field(i, j);
        if (level_[index(i, j)] < 0 || e.norm() / kVperCm < 0.02 * top_) continue;
        const Vec2 c = to_px(g_.node(i, j));
        const Vec2 d = Vec2(e.x(), -e.y()).normalized() * half;  // SVG y points down
        svg::line(s, c.x() - d.x(), c.y() - d.y(), c.x() + d.x(), c.y() + d.y(),
                  "stroke=\"#1a1a1a\" stroke-width=\"1.2\" marker-end=\"url(#head)\"");
      }
    }
  }

  void axes(std::string& s) const {
    const double left = px(lo_.x()), right = px(hi_.x()), top = py(hi_.y()), bottom = py(lo_.y());
    s += "<rect x=\"" + svg_number(left) + "\" y=\"" + svg_number(top) + "\" width=\"" +
         svg_number(width_) + "\" height=\"" + svg_number(height_) +
         "\" fill=\"none\" stroke=\"#000\"/>\n";
    const double dx = svg::tick_step(hi_.x() - lo_.x());
    for (double x = std::ceil(lo_.x() / dx) * dx; x <= hi_.x(); x += dx) {
      svg::line(s, px(x), bottom, px(x), bottom + 5, "stroke=\"#000\"");
      svg::text(s, px(x), bottom + 19, format_number(std::abs(x) < 1e-9 * dx ? 0.0 : x), "middle");
    }
    const double dy = svg::tick_step(hi_.y() - lo_.y());
    for (double y = std::ceil(lo_.y() / dy) * dy; y <= hi_.y(); y += dy) {
      svg::line(s, left - 5, py(y), left, py(y), "stroke=\"#000\"");
      svg::text(s, left - 8, py(y) + 4, format_number(std::abs(y) < 1e-9 * dy ? 0.0 : y), "end");
    }
    svg::text(s, (left + right) / 2, bottom + 42, "x (m)", "middle");
    const double mid = (top + bottom) / 2;
    svg::text(s, 22, mid, "y (m)", "middle",
              " transform=\"rotate(-90 22 " + svg_number(mid) + ")\"");
  }

  void colour_bar(std::string& s) const {
    const double x = kLeft + width_ + 40, w = 18, top = kTop, h = height_;
    for (int k = 0; k < kLevels; ++k) {
      const double y = top + h * (1.0 - double(k + 1) / kLevels);
      s += "<rect x=\"" + svg_number(x) + "\" y=\"" + svg_number(y) + "\" width=\"" +
           svg_number(w) + "\" height=\"" + svg_number(h / kLevels + 0.5) + "\" fill=\"" +
           level_colour(k) + "\"/>\n";
    }
    s += "<rect x=\"" + svg_number(x) + "\" y=\"" + svg_number(top) + "\" width=\"" +
         svg_number(w) + "\" height=\"" + svg_number(h) + "\" fill=\"none\" stroke=\"#000\"/>\n";
    const double step = svg::tick_step(top_);
    for (double v = 0.0; v <= top_ * (1.0 + 1e-9); v += step) {
      const double y = top + h * (1.0 - v / top_);
      svg::line(s, x + w, y, x + w + 5, y, "stroke=\"#000\"");
      svg::text(s, x + w + 8, y + 4, format_number(v), "start");
    }
    svg::text(s, x + w / 2, top - 14, "|E| (kV/cm)", "middle");
    svg::text(s, x - 4, top + h + 20, "above " + format_number(top_) + ": top colour", "start",
              " font-size=\"11\"");
  }

  const Simulation& sim_;
  const FieldGrid& g_;
  Vec2 lo_, hi_;  // the pictured rectangle: the grid's cells
  double scale_ = 1.0, width_ = 0.0, height_ = 0.0;
  double top_ = 1.0;        // kV/cm at the top of the colour scale
  std::vector<int> level_;  // per node: band, or kDrum / kElectrode
};

}  // namespace

Vec2 FieldGrid::node(int i, int j) const {
  return picture.min + picture.resolution * Vec2(double(i), double(j));
}

FieldGrid sample_field(const Simulation& sim) {
  FieldGrid g;
  g.picture = *sim.output.field;
  const FieldPicture& p = g.picture;
  g.nx = node_count(p.min.x(), p.max.x(), p.resolution);
  g.ny = node_count(p.min.y(), p.max.y(), p.resolution);
  const fields::ElectricField& model = sim.electrostatics->field;
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const Vec2 at = g.node(i, j);
      const Vec3 x(at.x(), at.y(), 0.0);
      g.field.push_back(fields::field_at(model, x).head<2>());
      g.potential.push_back(potential(model, x));
    }
  }
  return g;
}

std::string field_csv(const FieldGrid& g) {
  std::string text = "x_m,y_m,ex_vpm,ey_vpm,e_vpm,phi_v\n";
  CsvWriter row(text);
  for (int j = 0; j < g.ny; ++j) {
    for (int i = 0; i < g.nx; ++i) {
      const std::size_t k = std::size_t(i) + std::size_t(g.nx) * std::size_t(j);
      const Vec2 at = g.node(i, j);
      const Vec2& e = g.field[k];
      row << at.x() << at.y() << e.x() << e.y() << e.norm();
      if (g.potential[k])
        row << *g.potential[k];
      else
        row << "";
      row.end_row();
    }
  }
  return text;
}

std::string field_svg(const Simulation& sim, const FieldGrid& grid) {
  return FieldSvg(sim, grid).render();
}

}  // namespace ces::output
