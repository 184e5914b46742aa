// Electrostatic field models of the separator (docs/physics.md §3).
//
// Frame: the drum axis is the z axis through the origin, the cross-section is
// the x–y plane, gravity is −y. SI units throughout: m, V, V/m. Every model is
// an immutable value: build it once, then query it from any thread.
//
// The two analytic models are 2-D (z-invariant). docs/physics.md §3.2 switches the
// electric forces off beyond the drum width, so their field() is zero for
// |z| > half_width; their potential() is that of the cross-section and
// ignores z. Inside a conductor (drum or electrode) the field is zero and the
// potential is the conductor's own, which also keeps queries away from the
// line-charge singularities.
#pragma once
#include <array>
#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "common/math.hpp"

namespace ces::fields {

// The grounded roll as the 2-D models see it.
struct Drum {
  double radius = 0.0;      // R1, m
  double half_width = 0.0;  // W/2, m: no field for |z| > half_width
};

// A long cylindrical electrode parallel to the drum axis (static electrode
// or corona wire).
struct Electrode {
  Vec2 centre = Vec2::Zero();  // axis position in the x–y plane, m
  double radius = 0.0;         // m
  double potential = 0.0;      // V

  // Axis `distance` from the drum axis at `angle` (rad, counter-clockwise
  // from +x), the way docs/physics.md §2 describes the machine.
  static Electrode at_polar(double distance, double angle, double radius, double potential);
};

// Exact 2-D field of the grounded drum and one cylindrical electrode: two
// line charges ±λ at the common inverse points (foci) of the two circles
// (docs/physics.md §3.1, implemented from the formulas there).
class BipolarField {
 public:
  // Throws std::invalid_argument unless the radii and half-width are
  // positive and the electrode lies entirely outside the drum.
  BipolarField(const Drum& drum, const Electrode& electrode);

  Vec3 field(const Vec3& p) const;        // V/m
  double potential(const Vec3& p) const;  // V

  // The construction constants of §3.1, for regression checks.
  double h1() const { return h1_; }  // m
  double h2() const { return h2_; }  // m
  double j() const { return j_; }    // m
  double f() const { return f_; }    // V

 private:
  Vec2 to_electrode_frame(const Vec3& p) const;  // (x1, y1) of §3.1
  bool in_drum(const Vec3& p) const;
  bool in_electrode(const Vec3& p) const;

  Drum drum_;
  Electrode electrode_;
  double cos_a_, sin_a_;
  double h1_, h2_, j_, f_, ln_k1_;
};

// Several electrodes as line charges at their axes, each with its image in
// the grounded drum; the strengths make φ = U_k at the point of each
// electrode nearest the drum (docs/physics.md §3.2). Approximate: with the static
// electrode alone it overestimates the drum field by ~2 % against §3.1.
class LineChargeField {
 public:
  // Throws std::invalid_argument for an empty list, non-positive radii, an
  // electrode touching the drum or two electrodes overlapping.
  LineChargeField(const Drum& drum, std::vector<Electrode> electrodes);

  Vec3 field(const Vec3& p) const;        // V/m
  double potential(const Vec3& p) const;  // V

  const std::vector<Electrode>& electrodes() const { return electrodes_; }

 private:
  // Line charge λ at the electrode axis and −λ at its image R1² p/s².
  struct LineCharge {
    Vec2 position;
    Vec2 image;
    double strength = 0.0;  // λ / (2π ε0), V
    double ln_ratio = 0.0;  // ln(R1/s): makes the pair's potential 0 on the drum
  };

  static double unit_potential(const LineCharge& c, const Vec2& r);
  double cross_section_potential(const Vec2& r) const;
  const Electrode* conductor_at(const Vec3& p) const;

  Drum drum_;
  std::vector<Electrode> electrodes_;
  std::vector<LineCharge> charges_;
};

// A field sampled on a regular 3-D grid (e.g. an FEA export, docs/physics.md §3.3),
// trilinearly interpolated, zero outside the grid.
class GridField {
 public:
  struct Axis {
    double origin = 0.0;    // first node, m
    double spacing = 0.0;   // > 0, m
    std::size_t count = 0;  // >= 2 nodes
  };

  // values[i + nx * (j + ny * k)] is the field at node (i, j, k).
  // Throws std::invalid_argument on inconsistent sizes.
  GridField(const std::array<Axis, 3>& axes, std::vector<Vec3> values);

  // CSV with the header `x,y,z,Ex,Ey,Ez` and one row per node in any order.
  // The axes are inferred from the coordinates. Throws std::runtime_error
  // "<file>:<line>: <reason>" for malformed rows, non-regular axes or
  // duplicate nodes, and "<file>: <reason>" for an incomplete grid.
  static GridField load_csv(const std::filesystem::path& path);
  // Same, from a stream; `source` names it in error messages.
  static GridField parse_csv(std::istream& in, const std::string& source);

  Vec3 field(const Vec3& p) const;  // V/m
  const std::array<Axis, 3>& axes() const { return axes_; }

 private:
  const Vec3& at(std::size_t i, std::size_t j, std::size_t k) const;

  std::array<Axis, 3> axes_;
  std::vector<Vec3> values_;
};

// The field a scene selects. A grid is shared, not copied (never null).
using ElectricField = std::variant<BipolarField, LineChargeField, std::shared_ptr<const GridField>>;

Vec3 field_at(const ElectricField& model, const Vec3& p);

}  // namespace ces::fields
