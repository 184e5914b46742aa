#include "fields/electrostatics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/parallel.hpp"

namespace ces::fields {
namespace {

// A sphere touches a body when its contact gap is below this fraction of its
// radius, plus the turning allowance of touch_tolerance(): resting contacts
// sit within solver tolerance of zero, while a contact that is only inside
// the collision envelope (up to 25 % of r plus one step's travel) has not
// touched yet.
constexpr double kTouchFraction = 0.01;

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

// Largest gap at which contact k (body first, particle i second) still
// counts as touching its body. On a turning body a carried particle starts
// each step off the surface by the chord sag ρ (ω h)² / 2 of its last step
// (semi-implicit Euler moves it along a tangent; the solve pulls it back):
// 3 µm at 60 rpm and 1 ms, 14 µm at 128 rpm. Twice that is allowed, on top
// of the fraction of r. A particle SLIDING on the body rides higher: the
// velocity-level cone complementarity (the relaxation of Anitescu and
// Tasora, 2010) gives a sliding contact the normal velocity μ |v_t|, so it
// starts each step μ |v_t| h off the surface (50 µm for an FR-4 flake
// landing on the drum 0.2 m/s faster than its surface, at μ = 0.5 and
// 0.5 ms: 17 % of its spheres' radius), and a sliding conductor is still
// in contact with the grounded drum. Twice that is allowed too; v_t is the
// slip at the contact point at the start of the step. (The image force
// does not need a touch: it acts at the distance of the nearest drum
// surface, nearest_drum.)
double touch_tolerance(const Model& model, const Contacts& c, std::size_t k, const Bodies& bodies,
                       std::size_t body, const Particles& p, std::size_t i) {
  const double h = model.step, friction = model.materials.surfaces(c.surfaces[k]).friction;
  const Vec3& w = bodies.angular_velocity[body];
  const double r = c.radius[k];
  const Vec3 arm = c.point[k] - bodies.pose[body].position;
  const double rho = w.squaredNorm() > 0.0 ? arm.cross(w.normalized()).norm() : 0.0;
  const Vec3 slip = p.velocity_at(i, c.point[k]) - bodies.velocity_at(body, c.point[k]);
  const Vec3& n = c.normal[k];
  const double v_t = (slip - slip.dot(n) * n).norm();
  return kTouchFraction * r + w.squaredNorm() * (rho + r) * h * h + 2.0 * friction * v_t * h;
}

constexpr double kInf = std::numeric_limits<double>::infinity();

// Contacts per chunk of find_touches; fixed, so the chunks do not depend on
// the threads.
constexpr std::size_t kTouchChunk = 4096;

// Flat shapes (ShapeElectrics): at least this many thicknesses wide both
// ways across their thinnest principal axis, so t/a <= 2/1.5 = 1.33, inside
// the Laplace table of the flake laws (fields/charge.cpp, to t/a = 2). The
// measured PCB flakes are 1.9 to 50 times as wide as thick.
constexpr double kFlatWidth = 1.5;
// Cells per side of the grid the footprint area is counted on: the area of
// a disc comes out within 0.1 %.
constexpr int kFootprintCells = 512;

// Area of the union of discs (centre (u, v), radius r) by counting the
// centres of a grid's cells over their bounding box.
double union_area(const std::vector<std::array<double, 3>>& discs) {
  double u0 = kInf, u1 = -kInf, v0 = kInf, v1 = -kInf;
  for (const auto& [u, v, r] : discs) {
    u0 = std::min(u0, u - r), u1 = std::max(u1, u + r);
    v0 = std::min(v0, v - r), v1 = std::max(v1, v + r);
  }
  const int n = kFootprintCells;
  const double du = (u1 - u0) / n, dv = (v1 - v0) / n;
  std::vector<std::uint8_t> covered(std::size_t(n) * std::size_t(n), 0);
  for (const auto& [u, v, r] : discs) {
    const int i0 = std::max(0, int((u - r - u0) / du)), i1 = std::min(n - 1, int((u + r - u0) / du));
    const int j0 = std::max(0, int((v - r - v0) / dv)), j1 = std::min(n - 1, int((v + r - v0) / dv));
    for (int i = i0; i <= i1; ++i) {
      const double x = u0 + (i + 0.5) * du - u;
      for (int j = j0; j <= j1; ++j) {
        const double y = v0 + (j + 0.5) * dv - v;
        if (x * x + y * y <= r * r) covered[std::size_t(i) * std::size_t(n) + std::size_t(j)] = 1;
      }
    }
  }
  return double(std::count(covered.begin(), covered.end(), 1)) * du * dv;
}

}  // namespace

namespace {

// The thinnest principal axis k of a shape, and the shape's extents.
int thinnest_axis(const ParticleShape& shape, Vec3& extent) {
  Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
  for (std::size_t s = 0; s < shape.centers.size(); ++s) {
    const Vec3 r = Vec3::Constant(shape.radii[s]);
    lo = lo.cwiseMin(shape.centers[s] - r), hi = hi.cwiseMax(shape.centers[s] + r);
  }
  extent = hi - lo;
  int k = 0;
  for (int a = 1; a < 3; ++a)
    if (extent[a] < extent[k]) k = a;
  return k;
}

}  // namespace

double footprint_area(const ParticleShape& shape) {
  Vec3 extent;
  const int k = thinnest_axis(shape, extent);
  const int i = (k + 1) % 3, j = (k + 2) % 3;
  std::vector<std::array<double, 3>> discs;
  for (std::size_t s = 0; s < shape.centers.size(); ++s)
    discs.push_back({shape.centers[s][i], shape.centers[s][j], shape.radii[s]});
  return union_area(discs);
}

ShapeElectrics shape_electrics(const ParticleShape& shape) {
  ShapeElectrics e;
  Vec3 extent;
  const int k = thinnest_axis(shape, extent);
  const double thickness = extent[k];
  const double width = std::min(extent[(k + 1) % 3], extent[(k + 2) % 3]);
  if (width < kFlatWidth * thickness) return e;
  e.face_area = footprint_area(shape);
  e.face_normal = Vec3::Unit(k);
  e.flat_cos = std::sqrt(1.0 - std::min(1.0, (thickness / width) * (thickness / width)));
  return e;
}

namespace {

// ---------------------------------------------------------------- corona --

double angle_from(double angle, double origin) {
  const double turn = 2.0 * kPi;
  const double a = std::fmod(angle - origin, turn);
  return a < 0.0 ? a + turn : a;
}

bool in_zone(const CoronaZone& zone, double drum_radius, const Vec3& x) {
  if (std::hypot(x.x(), x.y()) > drum_radius + zone.depth) return false;
  return angle_from(std::atan2(x.y(), x.x()), zone.angle_begin) <=
         zone.angle_end - zone.angle_begin;
}

// The seed's instant charging: straight to Q_s, unless the charge already
// is at or beyond it (no ion reaches it then, as in pauthenier_step).
double saturate(double charge, double saturation) {
  if (saturation == 0.0 || charge / saturation >= 1.0) return charge;
  return saturation;
}

// ------------------------------------------------------------ validation --

void validate_material(const ElectricalMaterial& m, std::size_t index) {
  const std::string at = "electrostatics: material " + std::to_string(index) + ": ";
  require(m.metal_fraction >= 0.0 && m.metal_fraction <= 1.0,
          at + "metal fraction must be in [0, 1]");
  require(m.relative_permittivity >= 1.0, at + "relative permittivity must be >= 1");
  require(m.decay_time >= 0.0, at + "decay time must be >= 0 (0 or infinity: no decay)");
}

void validate_zone(const CoronaZone& z, std::size_t index) {
  const std::string at = "electrostatics: corona zone " + std::to_string(index) + ": ";
  const double span = z.angle_end - z.angle_begin;
  require(span > 0.0 && span <= 2.0 * kPi,
          at + "needs angle_begin < angle_end <= angle_begin + 2 pi");
  require(z.depth > 0.0, at + "depth must be positive");
  require(!z.field || (std::isfinite(*z.field) && *z.field >= 0.0), at + "field must be >= 0");
  require(z.mode == CoronaCharging::Saturation || z.current_density > 0.0,
          at + "Pauthenier charging needs a current density > 0");
  require(z.ion_sign == 1.0 || z.ion_sign == -1.0, at + "ion sign must be +1 or -1");
}

void validate_body(int body, std::size_t bodies, const char* name) {
  require(body >= 0 && std::size_t(body) < bodies,
          std::string("electrostatics: ") + name + " " + std::to_string(body) +
              " is not a body of the model (" + std::to_string(bodies) + " bodies)");
}

void validate(const ElectrostaticsSpec& spec, const Model& model) {
  require(spec.drum.radius > 0.0 && spec.drum.half_width > 0.0,
          "electrostatics: drum radius and half-width must be positive");
  validate_body(spec.drum_body, model.bodies.size(), "drum_body");
  if (spec.brush_body) {
    validate_body(*spec.brush_body, model.bodies.size(), "brush_body");
    require(*spec.brush_body != spec.drum_body, "electrostatics: the brush cannot be the drum");
  }
  const std::size_t materials = model.materials.materials().size();
  require(spec.materials.size() == materials,
          "electrostatics: " + std::to_string(spec.materials.size()) +
              " electrical materials given for " + std::to_string(materials) + " materials");
  for (std::size_t k = 0; k < spec.materials.size(); ++k) validate_material(spec.materials[k], k);
  for (std::size_t k = 0; k < spec.corona.size(); ++k) validate_zone(spec.corona[k], k);
  for (const CoronaBand& b : spec.bands)
    require(b.ion_sign == spec.bands.front().ion_sign && b.peak_current_density >= 0.0,
            "electrostatics: corona wires of both polarities, expected one");
  require(spec.medium_relative_permittivity >= 1.0,
          "electrostatics: medium relative permittivity must be >= 1");
  if (const auto* grid = std::get_if<std::shared_ptr<const GridField>>(&spec.field))
    require(*grid != nullptr, "electrostatics: the grid field is missing");
}

// A flat flake lies on the drum with its face when its face normal is
// within the shape's tilt of the contact normal (either face down).
bool lies_flat(const ShapeElectrics& shape, const Quat& orientation, const Vec3* normal) {
  if (shape.face_area <= 0.0 || !normal) return false;
  return std::abs((orientation * shape.face_normal).dot(*normal)) >= shape.flat_cos;
}

}  // namespace

// Where one particle is this step, as far as its charges are concerned.
struct ElectrostaticsStage::Site {
  Vec3 position;            // centre of mass
  Vec3 field;               // E there (with the corona space charge); zero beyond the drum width
  double current_density;   // J of the corona bands there
  bool active;              // |z| <= half-width
  const Vec3* drum_normal;  // out of the drum at the touching contact, or null
  DrumGap image;            // the drum surface nearest the particle: its charging and pull
  bool brush;               // touches the brush
  double radius;            // sphere of the particle's volume
  FlatFlake flake;          // a flat shape's face and thickness; face area 0 for a compact one
  bool flat_touch;          // lying flat on the touching drum contact
  bool flat_image;          // lying flat over the nearest drum surface
};

ElectrostaticsStage::ElectrostaticsStage(ElectrostaticsSpec spec, const Model& model)
    : spec_(std::move(spec)) {
  validate(spec_, model);
  for (const ParticleShape& s : model.shapes) shapes_.push_back(shape_electrics(s));
  for (const Material& m : model.materials.materials()) density_.push_back(m.density);
}

void ElectrostaticsStage::apply(const Model& model, const Contacts& contacts,
                                const Bodies& bodies, Particles& p) {
  const double h = model.step;
  find_touches(model, contacts, bodies, p);
  for_each_index(p.size(), [&](std::size_t i) { update(model, p, i, contacts, h); });
}

// This step's touches, from the contact list (body contacts name the body
// first and point their normal out of it). A cluster touching the drum
// with several spheres uses its closest contact. In parallel: a
// particle's contacts with one body follow each other in the list
// (Collider::narrowphase), so each particle's entries are written by the
// one chunk that holds that run.
void ElectrostaticsStage::find_touches(const Model& model, const Contacts& c, const Bodies& bodies,
                                       const Particles& p) {
  const std::size_t np = p.size();
  drum_contact_.assign(np, -1);
  brush_touch_.assign(np, 0);
  const int drum = int(np) + spec_.drum_body;
  const int brush = spec_.brush_body ? int(np) + *spec_.brush_body : -1;
  auto same_pair = [&](std::size_t k, std::size_t l) {
    return c.body_a[k] == c.body_a[l] && c.body_b[k] == c.body_b[l];
  };
  for_each_run_chunk(c.size(), kTouchChunk, same_pair, [&](std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      const int body = c.body_a[k];
      if (body == drum || body == brush) touch(model, c, k, body == drum, bodies, p);
    }
  });
  // A particle asleep on the drum (dynamics/sleep.hpp) has no contact with
  // it listed: it touches it where its nearest sphere does, which is
  // where its closest contact was.
  carried_.resize(np);
  for_each_index(np, [&](std::size_t i) {
    carried_[i] = p.carrier[i] == spec_.drum_body
                      ? nearest_drum(model.shapes[std::size_t(p.shape[i])], p, i)
                      : DrumGap{};
  });
}

// Contact k of particle c.body_b[k] with the drum or the brush, into its
// touches.
void ElectrostaticsStage::touch(const Model& model, const Contacts& c, std::size_t k,
                                bool on_drum, const Bodies& bodies, const Particles& p) {
  const auto i = std::size_t(c.body_b[k]);
  const std::size_t body = std::size_t(c.body_a[k]) - p.size();
  if (c.gap[k] > touch_tolerance(model, c, k, bodies, body, p, i)) return;
  if (!on_drum) {
    brush_touch_[i] = 1;
    return;
  }
  std::int32_t& best = drum_contact_[i];
  if (best < 0 || c.gap[k] < c.gap[std::size_t(best)]) best = std::int32_t(k);
}

const ElectricalMaterial& ElectrostaticsStage::material(const Particles& p, std::size_t i) const {
  return spec_.materials[std::size_t(p.material[i])];
}

// The field model's E at x; inside corona bands scaled to √(E² + E_sc²)
// (docs/physics.md §4.5), and their current density J.
Vec3 ElectrostaticsStage::field_at(const Vec3& x, double& current_density) const {
  Vec3 e = fields::field_at(spec_.field, x);
  double space_charge = 0.0;
  current_density = 0.0;
  for (const CoronaBand& band : spec_.bands) {
    if (!band.covers(x)) continue;
    current_density += band.current_density(x);
    space_charge += std::pow(band.space_charge_field(x), 2);
  }
  const double e2 = e.squaredNorm();
  if (space_charge > 0.0 && e2 > 0.0) e *= std::sqrt(1.0 + space_charge / e2);
  return e;
}

// The drum's surface nearest particle i: the gap of its sphere closest to
// the drum's cylinder, and the outward normal there. The image pull and
// the flat flake's charge take it from the geometry, not from the contact
// list: a drum contact is listed only within the collision envelope (a
// quarter of a sphere's radius plus a step's travel), which shrinks with
// the step, while the pull reaches a flake that hops a millimetre off the
// drum at several times its weight. Within one drum radius of the surface: farther, a
// plane's image no longer stands for the cylinder, and the pull is a
// millionth of what it is on the drum.
DrumGap ElectrostaticsStage::nearest_drum(const ParticleShape& s, const Particles& p,
                                          std::size_t i) const {
  const double R = spec_.drum.radius;
  const Vec3& x = p.position[i];
  DrumGap out;
  if (std::hypot(x.x(), x.y()) - s.bounding_radius * p.scale[i] > 2.0 * R) return out;
  const Mat3 to_world = p.orientation[i].toRotationMatrix() * p.scale[i];
  for (std::size_t k = 0; k < s.centers.size(); ++k) {
    const Vec3 c = x + to_world * s.centers[k];
    const double r = s.radii[k] * p.scale[i];
    // A centre farther from the axis than R, its radius and the least gap
    // so far (by a margin far above the rounding) is no nearer: it is
    // passed over before the hypot.
    const double beat = out.gap + R + r;
    if (beat > 0.0 && c.x() * c.x() + c.y() * c.y() > beat * beat * (1.0 + 1e-12)) continue;
    const double axis = std::hypot(c.x(), c.y());
    const double gap = axis - R - r;
    if (gap >= out.gap || axis == 0.0) continue;
    out.gap = gap;
    out.normal = Vec3(c.x() / axis, c.y() / axis, 0.0);
  }
  if (out.gap > R) out = DrumGap{};
  return out;
}

ElectrostaticsStage::Site ElectrostaticsStage::site(const Model& model, const Particles& p, std::size_t i,
                              const Contacts& c) const {
  const Vec3& x = p.position[i];
  const bool active = std::abs(x.z()) <= spec_.drum.half_width;
  const std::int32_t k = drum_contact_[i];
  const Vec3* touch = k >= 0 ? &c.normal[std::size_t(k)] : nullptr;
  if (carried_[i].found()) touch = &carried_[i].normal;
  const ShapeElectrics& shape = shapes_[std::size_t(p.shape[i])];
  const double volume = p.mass[i] / density_[std::size_t(p.material[i])];
  const double area = p.scale[i] * p.scale[i] * shape.face_area;
  double j = 0.0;
  const Vec3 e = active ? field_at(x, j) : Vec3::Zero();
  // Only an insulating part on the drum's width charges and feels the
  // image pull.
  const bool pulled = active && material(p, i).metal_fraction < 1.0;
  // A carried particle's nearest drum is find_touches' (the same positions).
  const bool carried = p.carrier[i] == spec_.drum_body;
  const DrumGap image = !pulled   ? DrumGap{}
                        : carried ? carried_[i]
                                  : nearest_drum(model.shapes[std::size_t(p.shape[i])], p, i);
  return {x,
          e,
          j,
          active,
          touch,
          image,
          brush_touch_[i] != 0,
          equal_volume_radius(volume),
          {area, area > 0.0 ? volume / area : 0.0},
          lies_flat(shape, p.orientation[i], touch),
          image.found() && lies_flat(shape, p.orientation[i], &image.normal)};
}

// One particle: both parts' charges for this step, then the w-weighted
// sum of their forces (docs/physics.md §5).
void ElectrostaticsStage::update(const Model& model, Particles& p, std::size_t i,
                                 const Contacts& c, double h) const {
  const ElectricalMaterial& m = material(p, i);
  const Site at = site(model, p, i, c);
  const double w = m.metal_fraction;
  Vec3 force = Vec3::Zero();
  if (w > 0.0) force += w * metal_part(w < 1.0 ? p.metal_charge[i] : p.charge[i], at);
  if (w < 1.0) force += (1.0 - w) * insulating_part(p.charge[i], m, at, h);
  if (at.active) p.force[i] += force;
}

// Conductor: on the grounded drum its charge follows the local field
// (relaxation ~1e-19 s) and it feels the lift force of a flat flake or of a
// sphere on a plane; off the drum the charge is frozen and the force is Q E.
Vec3 ElectrostaticsStage::metal_part(double& charge, const Site& at) const {
  if (!at.drum_normal) return charge * at.field;
  const Vec3& n = *at.drum_normal;
  const double en = at.field.dot(n);
  const double eps = spec_.medium_relative_permittivity;
  if (at.flat_touch) {
    charge = flat_conductor_charge(at.flake, en, eps);
    return flat_conductor_lift(at.flake, en, eps) * n;
  }
  charge = conductor_induced_charge(at.radius, en, eps);
  return conductor_lift_force(charge, en) * n;
}

// Pauthenier's saturation charge magnitude in |E|: the sphere's, or for a
// flake lying flat over the drum its face's at the gap under it, where
// that is more. The gap comes from the geometry, as the image pull's
// does, so whether a flake charges flat does not hang on which contacts
// the step's envelope lists; far enough off, the face's charge falls
// below the sphere's, which then stands for the flake in flight.
double ElectrostaticsStage::saturation_charge(const Site& at, double eps_r, double field) const {
  const double sphere = pauthenier_saturation_charge(at.radius, eps_r, field);
  if (!at.flat_image) return sphere;
  return std::max(sphere, flake_saturation_charge(at.flake, eps_r, field, at.image.gap));
}

// Insulator: relaxes, charges under the corona, loses everything at the
// brush; Q E plus, on the drum, the pull of its image charge.
Vec3 ElectrostaticsStage::insulating_part(double& charge, const ElectricalMaterial& m, const Site& at,
                     double h) const {
  if (m.decay_time > 0.0 && std::isfinite(m.decay_time))
    charge = decay_step(charge, m.decay_time, h);
  const double eps = m.relative_permittivity;
  if (at.active) {
    for (const CoronaZone& zone : spec_.corona) {
      if (!in_zone(zone, spec_.drum.radius, at.position)) continue;
      const double e = zone.field.value_or(at.field.norm());
      const double saturation = zone.ion_sign * saturation_charge(at, eps, e);
      charge = zone.mode == CoronaCharging::Saturation
                   ? saturate(charge, saturation)
                   : pauthenier_growth(charge, saturation,
                                       pauthenier_time_constant(e, zone.current_density), h);
    }
    if (at.current_density > 0.0) {
      const double e = at.field.norm();
      charge = pauthenier_growth(charge, spec_.bands.front().ion_sign * saturation_charge(at, eps, e),
                                 pauthenier_time_constant(e, at.current_density), h);
    }
  }
  if (at.brush) charge = 0.0;
  Vec3 force = charge * at.field;
  if (at.image.found()) {
    // At the gap of the closest sphere: a flake lying flat by the
    // bridged face law, anything else by the sphere law with its charge
    // r + gap from the drum.
    const double eps_m = spec_.medium_relative_permittivity;
    const double gap = std::max(0.0, at.image.gap);
    const double pull =
        at.flat_image ? flat_image_force(charge, at.flake.face_area, eps_m, gap,
                                         flake_image_factor(at.flake, eps))
                      : image_force(charge, at.radius + gap, eps_m);
    force -= pull * at.image.normal;
  }
  return force;
}

}  // namespace ces::fields
