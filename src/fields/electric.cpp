#include "fields/electric.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <tuple>
#include <utility>

#include "common/csv.hpp"

namespace ces::fields {
namespace {

// A point counts as inside a conductor only when it is deeper than this
// fraction of the radius, so surface points computed with rounding either
// way get the outside (physical) limit of the field.
constexpr double kSurfaceTolerance = 1e-9;

bool inside_circle(const Vec2& centre, double radius, const Vec3& p) {
  return (p.head<2>() - centre).norm() < radius * (1.0 - kSurfaceTolerance);
}

bool beyond_width(const Drum& drum, const Vec3& p) { return std::abs(p.z()) > drum.half_width; }

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}

void validate_drum(const Drum& drum) {
  require(drum.radius > 0.0, "drum radius must be positive");
  require(drum.half_width > 0.0, "drum half-width must be positive");
}

void validate_electrode(const Drum& drum, const Electrode& e) {
  require(e.radius > 0.0, "electrode radius must be positive");
  require(e.centre.norm() > drum.radius + e.radius, "electrode must lie outside the drum");
}

}  // namespace

Electrode Electrode::at_polar(double distance, double angle, double radius, double potential) {
  return {distance * Vec2(std::cos(angle), std::sin(angle)), radius, potential};
}

// ---------------------------------------------------------------- bipolar --

BipolarField::BipolarField(const Drum& drum, const Electrode& electrode)
    : drum_(drum), electrode_(electrode) {
  validate_drum(drum);
  validate_electrode(drum, electrode);
  const double L = electrode.centre.norm();
  const double R1 = drum.radius;
  const double R2 = electrode.radius;
  cos_a_ = electrode.centre.x() / L;
  sin_a_ = electrode.centre.y() / L;
  // docs/physics.md §3.1, term by term.
  h1_ = (L * L + R1 * R1 - R2 * R2) / (2.0 * L);
  h2_ = L - h1_;
  j_ = std::sqrt(h1_ * h1_ - R1 * R1);
  f_ = electrode.potential /
       std::log((h1_ + j_ - R1) * (h2_ + j_ - R2) / ((R1 + j_ - h1_) * (R2 + j_ - h2_)));
  ln_k1_ = std::log((R1 + j_ - h1_) / (h1_ + j_ - R1));
}

Vec2 BipolarField::to_electrode_frame(const Vec3& p) const {
  return {p.x() * cos_a_ + p.y() * sin_a_, -p.x() * sin_a_ + p.y() * cos_a_};
}

bool BipolarField::in_drum(const Vec3& p) const {
  return inside_circle(Vec2::Zero(), drum_.radius, p);
}

bool BipolarField::in_electrode(const Vec3& p) const {
  return inside_circle(electrode_.centre, electrode_.radius, p);
}

double BipolarField::potential(const Vec3& p) const {
  if (in_drum(p)) return 0.0;
  if (in_electrode(p)) return electrode_.potential;
  const Vec2 q = to_electrode_frame(p);
  const double rA2 = (q.x() - h1_ + j_) * (q.x() - h1_ + j_) + q.y() * q.y();
  const double rB2 = (q.x() - h1_ - j_) * (q.x() - h1_ - j_) + q.y() * q.y();
  return 0.5 * f_ * std::log(rA2 / rB2) - f_ * ln_k1_;
}

Vec3 BipolarField::field(const Vec3& p) const {
  if (beyond_width(drum_, p) || in_drum(p) || in_electrode(p)) return Vec3::Zero();
  const Vec2 q = to_electrode_frame(p);
  const double ax = q.x() - h1_ + j_;  // from A = (h1 − j, 0)
  const double bx = q.x() - h1_ - j_;  // from B = (h1 + j, 0)
  const double rA2 = ax * ax + q.y() * q.y();
  const double rB2 = bx * bx + q.y() * q.y();
  const double e1x = -f_ * (ax / rA2 - bx / rB2);
  const double e1y = -f_ * (q.y() / rA2 - q.y() / rB2);
  // Back to the drum frame, turned by the electrode's angle.
  return {e1x * cos_a_ - e1y * sin_a_, e1x * sin_a_ + e1y * cos_a_, 0.0};
}

// ------------------------------------------------------------ line charge --

LineChargeField::LineChargeField(const Drum& drum, std::vector<Electrode> electrodes)
    : drum_(drum), electrodes_(std::move(electrodes)) {
  validate_drum(drum);
  require(!electrodes_.empty(), "at least one electrode is needed");
  const double R1 = drum.radius;
  for (std::size_t k = 0; k < electrodes_.size(); ++k) {
    const Electrode& e = electrodes_[k];
    validate_electrode(drum, e);
    for (std::size_t m = 0; m < k; ++m) {
      require((e.centre - electrodes_[m].centre).norm() > e.radius + electrodes_[m].radius,
              "electrodes must not overlap");
    }
    const double s2 = e.centre.squaredNorm();
    charges_.push_back({e.centre, (R1 * R1 / s2) * e.centre, 0.0, std::log(R1 / std::sqrt(s2))});
  }
  // φ(c_i) = Σ_k strength_k · unit_potential_k(c_i) = U_i, with c_i the
  // point of electrode i nearest the drum.
  const auto n = static_cast<Eigen::Index>(electrodes_.size());
  Eigen::MatrixXd a(n, n);
  Eigen::VectorXd u(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Electrode& e = electrodes_[i];
    const Vec2 c = e.centre * (1.0 - e.radius / e.centre.norm());
    for (Eigen::Index k = 0; k < n; ++k) a(i, k) = unit_potential(charges_[k], c);
    u(i) = e.potential;
  }
  const Eigen::VectorXd strength = a.partialPivLu().solve(u);
  for (Eigen::Index k = 0; k < n; ++k) charges_[k].strength = strength(k);
}

double LineChargeField::unit_potential(const LineCharge& c, const Vec2& r) {
  return std::log((r - c.image).norm()) - std::log((r - c.position).norm()) - c.ln_ratio;
}

double LineChargeField::cross_section_potential(const Vec2& r) const {
  double phi = 0.0;
  for (const LineCharge& c : charges_) phi += c.strength * unit_potential(c, r);
  return phi;
}

const Electrode* LineChargeField::conductor_at(const Vec3& p) const {
  for (const Electrode& e : electrodes_) {
    if (inside_circle(e.centre, e.radius, p)) return &e;
  }
  return nullptr;
}

double LineChargeField::potential(const Vec3& p) const {
  if (inside_circle(Vec2::Zero(), drum_.radius, p)) return 0.0;
  if (const Electrode* e = conductor_at(p)) return e->potential;
  return cross_section_potential(p.head<2>());
}

Vec3 LineChargeField::field(const Vec3& p) const {
  if (beyond_width(drum_, p) || inside_circle(Vec2::Zero(), drum_.radius, p) ||
      conductor_at(p) != nullptr) {
    return Vec3::Zero();
  }
  const Vec2 r = p.head<2>();
  Vec2 e = Vec2::Zero();
  for (const LineCharge& c : charges_) {
    const Vec2 from_charge = r - c.position;
    const Vec2 from_image = r - c.image;
    e += c.strength *
         (from_charge / from_charge.squaredNorm() - from_image / from_image.squaredNorm());
  }
  return {e.x(), e.y(), 0.0};
}

// ------------------------------------------------------------------- grid --

namespace {

constexpr std::array<const char*, 3> kAxisName = {"x", "y", "z"};
constexpr std::array<std::string_view, 6> kHeader = {"x", "y", "z", "Ex", "Ey", "Ez"};

// Coordinates closer than this fraction of the axis extent are the same
// node written twice (floating-point noise in an exporter).
constexpr double kSameNodeTolerance = 1e-9;
// A gap between neighbouring node coordinates may differ from a whole
// number of spacings by this fraction (coordinates printed with ~6
// significant digits); more is an irregular axis.
constexpr double kLatticeTolerance = 1e-3;

struct Row {
  Vec3 position;
  Vec3 value;
  std::size_t line;
};

[[noreturn]] void fail_at(const std::string& source, std::size_t line, const std::string& what) {
  throw std::runtime_error(source + ":" + std::to_string(line) + ": " + what);
}

std::string format_point(const Vec3& p) {
  std::ostringstream out;
  out.precision(9);
  out << '(' << p.x() << ", " << p.y() << ", " << p.z() << ')';
  return out.str();
}

void check_header(std::string_view line, const std::string& source) {
  const auto fields = csv::split(csv::without_bom(line));
  if (!std::equal(fields.begin(), fields.end(), kHeader.begin(), kHeader.end())) {
    fail_at(source, 1, "expected the header x,y,z,Ex,Ey,Ez");
  }
}

std::vector<Row> read_rows(std::istream& in, const std::string& source) {
  std::string line;
  if (!std::getline(in, line)) {
    throw std::runtime_error(source + ": empty file, expected the header x,y,z,Ex,Ey,Ez");
  }
  check_header(line, source);
  std::vector<Row> rows;
  for (std::size_t number = 2; std::getline(in, line); ++number) {
    if (csv::trim(line).empty()) continue;
    const auto fields = csv::split(line);
    if (fields.size() != kHeader.size()) {
      fail_at(source, number, "expected 6 values, found " + std::to_string(fields.size()));
    }
    std::array<double, 6> v{};
    for (std::size_t c = 0; c < v.size(); ++c) {
      const auto parsed = csv::number(fields[c]);
      if (!parsed) {
        fail_at(
            source, number,
            std::string(kHeader[c]) + " is not a finite number: '" + std::string(fields[c]) + "'");
      }
      v[c] = *parsed;
    }
    rows.push_back({{v[0], v[1], v[2]}, {v[3], v[4], v[5]}, number});
  }
  return rows;
}

// The regular axis through the distinct values of coordinate `a`. Its
// spacing is the smallest gap; wider gaps must be whole multiples of it (a
// missing plane then shows up as an incomplete grid, naming a node).
GridField::Axis infer_axis(const std::vector<Row>& rows, int a, const std::string& source) {
  std::vector<std::pair<double, std::size_t>> values;  // (coordinate, line)
  values.reserve(rows.size());
  for (const Row& r : rows) values.emplace_back(r.position[a], r.line);
  std::sort(values.begin(), values.end());
  const double same = kSameNodeTolerance * (values.back().first - values.front().first);

  // Distinct node coordinates, each with the first line that uses it.
  std::vector<std::pair<double, std::size_t>> nodes;
  for (const auto& [v, line] : values) {
    if (nodes.empty() || v - nodes.back().first > same) {
      nodes.emplace_back(v, line);
    } else {
      nodes.back().second = std::min(nodes.back().second, line);
    }
  }
  if (nodes.size() < 2) {
    throw std::runtime_error(source + ": the grid needs at least 2 distinct " + kAxisName[a] +
                             " values");
  }
  double gap = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < nodes.size(); ++i) {
    gap = std::min(gap, nodes[i].first - nodes[i - 1].first);
  }
  double steps = 0.0;
  for (std::size_t i = 1; i < nodes.size(); ++i) {
    const double ratio = (nodes[i].first - nodes[i - 1].first) / gap;
    const double whole = std::round(ratio);
    if (std::abs(ratio - whole) > kLatticeTolerance * whole) {
      std::ostringstream what;
      what.precision(9);
      what << kAxisName[a] << " = " << nodes[i].first << " is off the regular " << kAxisName[a]
           << " axis (spacing " << gap << " from " << nodes.front().first << ')';
      fail_at(source, nodes[i].second, what.str());
    }
    steps += whole;
  }
  if (steps + 1.0 > static_cast<double>(rows.size())) {
    std::ostringstream what;
    what.precision(9);
    what << source << ": incomplete grid: " << kAxisName[a] << " values spaced " << gap
         << " span more nodes than the " << rows.size() << " rows";
    throw std::runtime_error(what.str());
  }
  const double origin = nodes.front().first;
  return {origin, (nodes.back().first - origin) / steps, static_cast<std::size_t>(steps) + 1};
}

// A row's node, as (k, j, i) so that sorting gives the storage order.
struct Slot {
  std::array<std::size_t, 3> index;
  std::size_t row;
};

Slot slot_of(const std::array<GridField::Axis, 3>& axes, const std::vector<Row>& rows,
             std::size_t row) {
  Slot slot{{}, row};
  for (int a = 0; a < 3; ++a) {
    const double t = (rows[row].position[a] - axes[a].origin) / axes[a].spacing;
    slot.index[2 - a] = static_cast<std::size_t>(std::llround(t));
  }
  return slot;
}

Vec3 node_position(const std::array<GridField::Axis, 3>& axes,
                   const std::array<std::size_t, 3>& kji) {
  Vec3 p;
  for (int a = 0; a < 3; ++a) {
    p[a] = axes[a].origin + static_cast<double>(kji[2 - a]) * axes[a].spacing;
  }
  return p;
}

// The next node in storage order (x fastest).
void advance(const std::array<GridField::Axis, 3>& axes, std::array<std::size_t, 3>& kji) {
  for (int a = 0; a < 3; ++a) {
    if (++kji[2 - a] < axes[a].count || a == 2) return;
    kji[2 - a] = 0;
  }
}

}  // namespace

GridField::GridField(const std::array<Axis, 3>& axes, std::vector<Vec3> values)
    : axes_(axes), values_(std::move(values)) {
  for (const Axis& axis : axes_) {
    require(axis.count >= 2, "a grid axis needs at least 2 nodes");
    require(axis.spacing > 0.0 && std::isfinite(axis.spacing),
            "grid spacing must be positive and finite");
  }
  require(values_.size() == axes_[0].count * axes_[1].count * axes_[2].count,
          "grid value count does not match the axes");
}

GridField GridField::load_csv(const std::filesystem::path& path) {
  std::ifstream in = csv::open(path);
  return parse_csv(in, path.string());
}

GridField GridField::parse_csv(std::istream& in, const std::string& source) {
  const std::vector<Row> rows = read_rows(in, source);
  if (rows.empty()) throw std::runtime_error(source + ": no data rows");
  const std::array<Axis, 3> axes = {infer_axis(rows, 0, source), infer_axis(rows, 1, source),
                                    infer_axis(rows, 2, source)};

  // Sorted into storage order, duplicates are neighbours and a missing node
  // is the first place where the sequence skips.
  std::vector<Slot> slots;
  slots.reserve(rows.size());
  for (std::size_t r = 0; r < rows.size(); ++r) slots.push_back(slot_of(axes, rows, r));
  std::sort(slots.begin(), slots.end(), [&](const Slot& u, const Slot& v) {
    return std::tie(u.index, rows[u.row].line) < std::tie(v.index, rows[v.row].line);
  });
  // Report the duplicate met first in the file, against the node's first row.
  const Row* duplicate = nullptr;
  std::size_t first_line = 0;
  for (std::size_t n = 1, run = 0; n < slots.size(); ++n) {
    if (slots[n].index != slots[run].index) {
      run = n;
      continue;
    }
    const Row& row = rows[slots[n].row];
    if (!duplicate || row.line < duplicate->line) {
      duplicate = &row;
      first_line = rows[slots[run].row].line;
    }
  }
  if (duplicate) {
    fail_at(source, duplicate->line,
            "duplicate node " + format_point(duplicate->position) + ", first given on line " +
                std::to_string(first_line));
  }
  std::array<std::size_t, 3> expected{};
  for (const Slot& slot : slots) {
    if (slot.index != expected) break;
    advance(axes, expected);
  }
  if (expected[0] < axes[2].count) {
    throw std::runtime_error(source + ": incomplete grid: no row for node " +
                             format_point(node_position(axes, expected)) + " (" +
                             std::to_string(rows.size()) + " rows for a " +
                             std::to_string(axes[0].count) + " x " + std::to_string(axes[1].count) +
                             " x " + std::to_string(axes[2].count) + " grid)");
  }
  std::vector<Vec3> values;
  values.reserve(slots.size());
  for (const Slot& slot : slots) values.push_back(rows[slot.row].value);
  return GridField(axes, std::move(values));
}

const Vec3& GridField::at(std::size_t i, std::size_t j, std::size_t k) const {
  return values_[i + axes_[0].count * (j + axes_[1].count * k)];
}

Vec3 GridField::field(const Vec3& p) const {
  std::array<std::size_t, 3> cell{};
  std::array<double, 3> w{};  // position inside the cell, 0..1 per axis
  for (int a = 0; a < 3; ++a) {
    const Axis& axis = axes_[a];
    const double t = (p[a] - axis.origin) / axis.spacing;
    const auto last = static_cast<double>(axis.count - 1);
    if (!(t >= 0.0 && t <= last)) return Vec3::Zero();  // outside, or NaN
    cell[a] = std::min(static_cast<std::size_t>(t), axis.count - 2);
    w[a] = t - static_cast<double>(cell[a]);
  }
  Vec3 sum = Vec3::Zero();
  for (std::size_t corner = 0; corner < 8; ++corner) {
    double weight = 1.0;
    std::array<std::size_t, 3> node{};
    for (std::size_t a = 0; a < 3; ++a) {
      const bool upper = (corner >> a) & 1U;
      node[a] = cell[a] + (upper ? 1 : 0);
      weight *= upper ? w[a] : 1.0 - w[a];
    }
    sum += weight * at(node[0], node[1], node[2]);
  }
  return sum;
}

// ---------------------------------------------------------------- variant --

Vec3 field_at(const ElectricField& model, const Vec3& p) {
  struct Visit {
    const Vec3& p;
    Vec3 operator()(const BipolarField& f) const { return f.field(p); }
    Vec3 operator()(const LineChargeField& f) const { return f.field(p); }
    Vec3 operator()(const std::shared_ptr<const GridField>& f) const { return f->field(p); }
  };
  return std::visit(Visit{p}, model);
}

}  // namespace ces::fields
