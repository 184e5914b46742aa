#include "output/report.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "output/format.hpp"
#include "output/report_page.hpp"

namespace ces::output {
namespace {

std::int32_t tenth_mm(double metres) { return std::int32_t(std::lround(metres * 1e4)); }

// JSON inside <script>: a "</" would end the element, and a "<!--" would
// keep the HTML parser from seeing its end. JSON has '<' only inside its
// strings, where \u003c stands for it: none is left for the parser.
std::string script_safe(const std::string& json) {
  std::string out;
  out.reserve(json.size());
  for (const char c : json) {
    if (c == '<')
      out += "\\u003c";
    else
      out += c;
  }
  return out;
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) continue;
    out += c;
  }
  return out + "\"";
}

template <class T>
void json_array(std::ostringstream& out, const std::vector<T>& v) {
  out << '[';
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i) out << ',';
    if constexpr (std::is_floating_point_v<T>)
      out << format_number(double(v[i]));
    else
      out << v[i];
  }
  out << ']';
}

// The parts whose cross section is a circle (a cylinder along z) or a
// polygon (a box's section through its centre), at their pose at t = 0,
// with the electrodes and the collectors' planes; in 0.1 mm.
void machine_json(const Simulation& sim, std::ostringstream& out) {
  out << "{\"circles\":[";
  bool first = true;
  auto circle = [&](const std::string& name, double x, double y, double r) {
    out << (first ? "" : ",") << "{\"name\":" << json_string(name) << ",\"x\":" << tenth_mm(x)
        << ",\"y\":" << tenth_mm(y) << ",\"r\":" << tenth_mm(r) << '}';
    first = false;
  };
  for (const RigidBody& b : sim.model->bodies)
    if (const auto* c = std::get_if<geo::Cylinder>(&b.shape)) {
      const Vec3 axis = b.pose.orientation * Vec3::UnitZ();
      if (std::abs(std::abs(axis.z()) - 1.0) < 1e-6)
        circle(b.name, b.pose.position.x(), b.pose.position.y(), c->radius);
    }
  for (const NamedElectrode& e : sim.electrodes)
    circle(e.name, e.electrode.centre.x(), e.electrode.centre.y(), e.electrode.radius);
  out << "],\"polygons\":[";
  first = true;
  for (const RigidBody& b : sim.model->bodies)
    if (const auto* box = std::get_if<geo::Box>(&b.shape)) {
      const Vec3 h = box->half_extents;
      std::vector<std::int32_t> points;
      for (const auto& [sx, sy] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
        const Vec3 p = b.pose.apply(Vec3(sx * h.x(), sy * h.y(), 0.0));
        points.insert(points.end(), {tenth_mm(p.x()), tenth_mm(p.y())});
      }
      out << (first ? "" : ",") << "{\"name\":" << json_string(b.name) << ",\"points\":";
      json_array(out, points);
      out << '}';
      first = false;
    }
  out << "],\"collectors\":[";
  first = true;
  for (const Collector& c : sim.collectors) {
    const Vec3 a = c.point + c.axis * (c.from - c.axis.dot(c.point));
    const Vec3 b = c.point + c.axis * (c.to - c.axis.dot(c.point));
    out << (first ? "" : ",") << "{\"name\":" << json_string(c.name) << ",\"points\":["
        << tenth_mm(a.x()) << ',' << tenth_mm(a.y()) << ',' << tenth_mm(b.x()) << ','
        << tenth_mm(b.y()) << "]}";
    first = false;
  }
  out << "]}";
}

void frames_json(const CrossSection& section, std::ostringstream& out) {
  out << '[';
  const auto& frames = section.frames();
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const CrossSection::Frame& fr = frames[f];
    out << (f ? "," : "") << "{\"t\":" << format_number(fr.time) << ",\"x\":";
    json_array(out, fr.x);
    out << ",\"y\":";
    json_array(out, fr.y);
    out << ",\"m\":";
    json_array(out, fr.material);
    out << ",\"q\":";
    json_array(out, fr.charge);
    out << '}';
  }
  out << ']';
}

}  // namespace

CrossSection::CrossSection(double step) : every_(step), step_(step) {}

void CrossSection::observe(const State& state) {
  // Due at frames_.size() * every_, within half a step of rounding.
  if (state.time + 0.5 * step_ < double(frames_.size()) * every_) return;
  frames_.push_back(frame(state));
  if (frames_.size() == 2 * std::size_t(kFrames)) thin();
}

void CrossSection::finish(const State& state) {
  if (frames_.empty() || state.time > frames_.back().time + 0.5 * step_)
    frames_.push_back(frame(state));
}

// Every other frame, from the first, at twice the interval.
void CrossSection::thin() {
  for (std::size_t k = 0; 2 * k < frames_.size(); ++k) frames_[k] = std::move(frames_[2 * k]);
  frames_.resize((frames_.size() + 1) / 2);
  every_ *= 2.0;
}

CrossSection::Frame CrossSection::frame(const State& state) const {
  const Particles& p = state.particles;
  const std::size_t budget = kPoints / (2 * kFrames);
  const std::uint64_t stride = p.size() <= budget ? 1 : (p.size() + budget - 1) / budget;
  Frame f;
  f.time = state.time;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.id[i] % stride != 0) continue;
    f.x.push_back(tenth_mm(p.position[i].x()));
    f.y.push_back(tenth_mm(p.position[i].y()));
    f.material.push_back(p.material[i]);
    f.charge.push_back(float(particle_charge(p, i)));
  }
  return f;
}

void CrossSection::save(ByteWriter& out) const {
  out.value(every_);
  out.value(std::uint64_t(frames_.size()));
  for (const Frame& f : frames_) {
    out.value(f.time);
    out.values(f.x);
    out.values(f.y);
    out.values(f.material);
    out.values(f.charge);
  }
}

void CrossSection::load(ByteReader& in) {
  in.value(every_);
  if (!(every_ >= step_)) throw CorruptData("an animation interval shorter than the step");
  const auto n = in.value<std::uint64_t>();
  if (n > 2 * std::uint64_t(kFrames)) throw CorruptData("more animation frames than a run keeps");
  frames_.resize(std::size_t(n));
  for (Frame& f : frames_) {
    in.value(f.time);
    in.values(f.x);
    in.values(f.y);
    in.values(f.material);
    in.values(f.charge);
  }
}

std::string report_html(const Simulation& sim, const std::string& summary_json,
                        const std::string& distribution_svg, const std::string& field_svg,
                        const CrossSection& section) {
  std::ostringstream data;
  data << "{\"summary\":" << summary_json << ",\"materials\":[";
  const auto& materials = sim.model->materials.materials();
  for (std::size_t m = 0; m < materials.size(); ++m)
    data << (m ? "," : "") << json_string(materials[m].name);
  data << "],\"machine\":";
  machine_json(sim, data);
  data << ",\"frames\":";
  frames_json(section, data);
  data << '}';
  return report_page(sim.name, script_safe(data.str()), distribution_svg, field_svg);
}

}  // namespace ces::output
