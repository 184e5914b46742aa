#include "scene/electrostatics.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "scene/compile_support.hpp"
#include "scene/diagnostics.hpp"
#include "scene/limits.hpp"
#include "scene/resolve.hpp"
#include "scene/schema.hpp"

namespace ces::scene {
namespace {

// The electrode keys a corona wire's ions read, and nothing else does.
constexpr const char* kCoronaKeys[] = {"mobility", "air_density"};

std::string millimetres(double x) { return format(x * 1e3) + " mm"; }
std::string degrees(double rad) { return format(rad * 180.0 / kPi) + " deg"; }

// A direction is "along z" to within rounding of the scene's numbers.
bool along_z(const Vec3& axis) { return std::abs(std::abs(axis.normalized().z()) - 1.0) < 1e-9; }
bool on_z_axis(const Vec3& p) { return std::hypot(p.x(), p.y()) < 1e-9; }

class ElectrostaticsCompiler {
 public:
  ElectrostaticsCompiler(const ElectrostaticsInput& in, Diagnostics& diags)
      : in_(in), s_(in.section), diags_(diags) {}

  void compile(Simulation& sim) {
    const auto drum_body = in_.body(s_.at("drum"));
    const auto drum = drum_body ? drum_geometry(*drum_body) : std::nullopt;
    const auto brush = brush_body(drum_body);
    std::vector<NamedElectrode> electrodes = read_electrodes(drum);
    auto field = drum ? field_model(*drum, electrodes) : std::nullopt;
    std::vector<fields::CoronaBand> bands =
        field && drum ? corona_bands(*drum, *field, electrodes) : std::vector<fields::CoronaBand>{};
    std::vector<fields::CoronaZone> corona = read_corona();
    std::vector<fields::ElectricalMaterial> materials = read_materials();
    if (!field || !brush) return;
    fields::ElectrostaticsSpec spec(std::move(*field));
    spec.drum = *drum;
    spec.drum_body = *drum_body;
    spec.brush_body = *brush;
    spec.corona = std::move(corona);
    spec.bands = std::move(bands);
    spec.materials = std::move(materials);
    spec.medium_relative_permittivity = s_.at("medium_permittivity").number();
    sim.electrostatics = std::move(spec);
    sim.electrodes = std::move(electrodes);
  }

 private:
  // ------------------------------------------------------------ drum, brush

  // The field models' drum: a cylinder about the z axis centred on the
  // origin, turning (if it turns) about that axis.
  std::optional<fields::Drum> drum_geometry(int index) {
    const Node& ref = s_.at("drum");
    const RigidBody& b = in_.model.bodies[std::size_t(index)];
    const auto* c = std::get_if<geo::Cylinder>(&b.shape);
    if (!c) {
      diags_.error(ref, "body '" + b.name + "' is not a cylinder, expected the drum's cylinder");
      return std::nullopt;
    }
    const bool placed =
        b.pose.position.norm() < 1e-9 && along_z(b.pose.orientation * Vec3::UnitZ());
    const PrescribedMotion& m = b.motion;
    const bool turns_in_place = b.kind != BodyKind::Kinematic ||
                                (m.linear_velocity == Vec3::Zero() && on_z_axis(m.center) &&
                                 (m.angular_speed == 0.0 || along_z(m.axis)));
    if (!placed || !turns_in_place) {
      diags_.error(ref, "body '" + b.name +
                            "' is not where the field models put the drum, expected its centre "
                            "at [0, 0, 0], its axis and any rotation along z");
      return std::nullopt;
    }
    return fields::Drum{c->radius, c->half_length};
  }

  // nullopt: reported; an empty optional inside: no brush.
  std::optional<std::optional<int>> brush_body(std::optional<int> drum) {
    const Node* ref = s_.find("brush");
    if (!ref) return std::optional<int>();
    const auto brush = in_.body(*ref);
    if (!brush) return std::nullopt;
    if (brush == drum) {
      diags_.error(*ref, "the brush is the drum, expected another body");
      return std::nullopt;
    }
    return brush;
  }

  // ------------------------------------------------------------ electrodes

  std::vector<NamedElectrode> read_electrodes(const std::optional<fields::Drum>& drum) {
    std::vector<NamedElectrode> out;
    const Node* list = s_.find("electrodes");
    if (!list) return out;
    std::map<std::string, int> lines;
    for (const Node& e : list->items) {
      const std::string& name = e.at("name").string();
      if (const auto [it, fresh] = lines.emplace(name, e.at("name").mark.line); !fresh) {
        diags_.error(e.at("name"), "duplicate electrode name '" + name + "', first given at line " +
                                       std::to_string(it->second));
        continue;
      }
      const auto electrode = read_electrode(e);
      if (!electrode || !corona_keys_on_corona(e) ||
          (drum && !clear_of_drum(e, name, *electrode, *drum)) ||
          !clear_of_others(e, *electrode, out)) {
        ok_ = false;
        continue;
      }
      out.push_back({name, *electrode});
      nodes_.push_back(&e);
    }
    return out;
  }

  // mobility and air_density describe a wire's ions: on a static
  // electrode nothing would read them, so a scene giving them there has
  // most likely forgotten type: corona.
  bool corona_keys_on_corona(const Node& e) {
    if (e.at("type").string() == "corona") return true;
    for (const char* key : kCoronaKeys) {
      const Node* given = e.find(key);
      if (!given || given->defaulted) continue;
      diags_.error(*given, std::string(key) + " is read for a corona electrode only, expected "
                                              "type: corona on this electrode or no " + key);
      return false;
    }
    return true;
  }

  std::optional<fields::Electrode> read_electrode(const Node& e) {
    const Node* position = e.find("position");
    const Node* polar = e.find("polar");
    if (!position == !polar) {
      diags_.error(e, position ? "both position and polar given, expected one of them"
                               : "neither position nor polar given, expected one of them");
      return std::nullopt;
    }
    const double radius = e.at("radius").number();
    const double voltage = e.at("voltage").number();
    if (polar)
      return fields::Electrode::at_polar(polar->at("distance").number(),
                                         polar->at("angle").number(), radius, voltage);
    return fields::Electrode{Vec2(position->items[0].number(), position->items[1].number()), radius,
                             voltage};
  }

  bool clear_of_drum(const Node& e, const std::string& name, const fields::Electrode& el,
                     const fields::Drum& drum) {
    const double nearest = el.centre.norm() - el.radius;
    if (nearest > drum.radius) return true;
    const Node& where = e.find("position") ? e.at("position") : e.at("polar");
    diags_.error(where, "electrode '" + name + "' reaches " + metres(nearest) +
                            " from the drum axis, inside the drum (radius " + metres(drum.radius) +
                            "), expected it clear of the drum");
    return false;
  }

  bool clear_of_others(const Node& e, const fields::Electrode& el,
                       const std::vector<NamedElectrode>& before) {
    for (const NamedElectrode& o : before) {
      if ((el.centre - o.electrode.centre).norm() > el.radius + o.electrode.radius) continue;
      diags_.error(e,
                   "overlaps electrode '" + o.name + "', expected electrodes clear of each other");
      return false;
    }
    return true;
  }

  // ------------------------------------------------------------ field model

  std::optional<fields::ElectricField> field_model(const fields::Drum& drum,
                                                   const std::vector<NamedElectrode>& electrodes) {
    const Node& f = s_.at("field");
    const Node& model = f.at("model");
    const Node* file = f.find("file");
    if (model.string() == "grid") return grid(f, drum);
    if (file) {
      diags_.error(*file, "only the grid model reads a file, expected model: grid or no file");
      return std::nullopt;
    }
    if (!ok_) return std::nullopt;  // an electrode was reported
    if (!electrode_count_fits(model, electrodes.size())) return std::nullopt;
    std::vector<fields::Electrode> plain;
    for (const NamedElectrode& e : electrodes) plain.push_back(e.electrode);
    try {
      if (model.string() == "bipolar") return fields::BipolarField(drum, plain.front());
      return fields::LineChargeField(drum, plain);
    } catch (const std::invalid_argument& e) {
      diags_.error(model, std::string("cannot build the field: ") + e.what());
      return std::nullopt;
    }
  }

  bool electrode_count_fits(const Node& model, std::size_t n) {
    if (model.string() == "bipolar" && n != 1) {
      diags_.error(model, "bipolar is the field of exactly one electrode, the scene lists " +
                              std::to_string(n) + "; expected one electrode, or line_charges");
      return false;
    }
    if (n == 0) {
      diags_.error(model, "line_charges needs at least one electrode, the scene lists none");
      return false;
    }
    return true;
  }

  // The grid's field is 0 outside its box: a grid that misses part of the
  // drum's surface, where the electric forces decide the separation, is
  // said to, with its box.
  void warn_uncovered(const Node& file, const fields::GridField& grid, const fields::Drum& drum) {
    constexpr int kSamples = 360;
    const auto& axes = grid.axes();
    auto last = [&](int a) { return axes[a].origin + double(axes[a].count - 1) * axes[a].spacing; };
    auto inside = [&](int a, double x) { return x >= axes[a].origin && x <= last(a); };
    int covered = 0;
    for (int k = 0; k < kSamples; ++k) {
      const double angle = 2.0 * kPi * k / kSamples;
      covered += inside(0, drum.radius * std::cos(angle)) &&
                 inside(1, drum.radius * std::sin(angle)) && inside(2, 0.0);
    }
    if (covered == kSamples) return;
    auto span = [&](int a) { return format(axes[a].origin) + " to " + format(last(a)); };
    diags_.warning(file, "the field grid covers " + std::to_string(100 * covered / kSamples) +
                             " % of the drum's surface (x " + span(0) + ", y " + span(1) + ", z " +
                             span(2) + " m): outside it the field is 0");
  }

  std::optional<fields::ElectricField> grid(const Node& f, const fields::Drum& drum) {
    const Node* file = f.find("file");
    if (!file) {
      diags_.error(f, "missing required key 'file', expected the grid's CSV file");
      return std::nullopt;
    }
    const std::filesystem::path path = in_.scene_dir / file->string();
    if (const std::string why = too_large(path, limits::kDataFileBytes); !why.empty()) {
      diags_.error(*file, "cannot read the field grid: " + path.string() + ": " + why);
      return std::nullopt;
    }
    try {
      auto field = std::make_shared<const fields::GridField>(fields::GridField::load_csv(path));
      warn_uncovered(*file, *field, drum);
      return field;
    } catch (const std::exception& e) {
      diags_.error(*file, std::string("cannot read the field grid: ") + e.what());
      return std::nullopt;
    }
  }

  // ------------------------------------------------------------ corona wires

  std::vector<fields::CoronaBand> corona_bands(const fields::Drum& drum,
                                               const fields::ElectricField& field,
                                               const std::vector<NamedElectrode>& electrodes) {
    std::vector<fields::CoronaBand> out;
    for (std::size_t k = 0; k < electrodes.size(); ++k) {
      const Node& e = *nodes_[k];
      if (e.at("type").string() != "corona") continue;
      if (const auto band = corona_band(e, drum, field, electrodes[k].electrode)) out.push_back(*band);
    }
    return out;
  }

  std::optional<fields::CoronaBand> corona_band(const Node& e, const fields::Drum& drum,
                                                const fields::ElectricField& field,
                                                const fields::Electrode& wire) {
    const auto* lines = std::get_if<fields::LineChargeField>(&field);
    if (!lines) {
      diags_.error(e.at("type"), "a corona electrode needs the field of every electrode at the "
                                 "wire, expected field.model: line_charges");
      return std::nullopt;
    }
    if (wire.radius > kMaxCoronaWireRadius) {
      diags_.error(e.at("radius"), "a corona wire of radius " + millimetres(wire.radius) +
                                       " does not ionise, expected a radius of at most " +
                                       millimetres(kMaxCoronaWireRadius));
      return std::nullopt;
    }
    const std::string polarity = wire.potential < 0.0 ? "negative" : "positive";
    const Node* mobility = e.find("mobility");
    const fields::CoronaWire spec{
        wire,
        mobility ? mobility->number()
                 : schema()
                       .at("definitions")
                       .at("electrode")
                       .at("properties")
                       .at("mobility")
                       .at("x-default-by-polarity")
                       .at(polarity)
                       .get<double>(),
        e.at("air_density").number()};
    try {
      return fields::corona_band(drum, *lines, spec);
    } catch (const std::invalid_argument& what) {
      diags_.error(e.at("voltage"), std::string(what.what()) + ", expected a voltage above onset");
      return std::nullopt;
    }
  }

  // ------------------------------------------------------------ corona

  std::vector<fields::CoronaZone> read_corona() {
    std::vector<fields::CoronaZone> out;
    const Node* list = s_.find("corona");
    if (!list) return out;
    for (const Node& z : list->items) {
      fields::CoronaZone zone;
      zone.angle_begin = z.at("from").number();
      zone.angle_end = z.at("to").number();
      if (!sector_fits(z, zone)) continue;
      zone.depth = z.at("depth").number();
      zone.mode = z.at("charging").string() == "saturation" ? fields::CoronaCharging::Saturation
                                                            : fields::CoronaCharging::Pauthenier;
      if (const Node* field = z.find("field")) zone.field = field->number();
      const Node* current = z.find("current_density");
      if (current) {
        zone.current_density = current->number();
      } else if (zone.mode == fields::CoronaCharging::Pauthenier) {
        diags_.error(z, "Pauthenier charging needs the ion current density, expected "
                        "current_density (or charging: saturation)");
        continue;
      }
      zone.ion_sign = z.at("polarity").string() == "positive" ? 1.0 : -1.0;
      out.push_back(zone);
    }
    return out;
  }

  bool sector_fits(const Node& z, const fields::CoronaZone& zone) {
    const double span = zone.angle_end - zone.angle_begin;
    if (span > 0.0 && span <= 2.0 * kPi) return true;
    diags_.error(z.at("to"),
                 "the sector from " + degrees(zone.angle_begin) + " to " + degrees(zone.angle_end) +
                     (span > 0.0 ? " spans more than a turn" : " is empty or reversed") +
                     ", expected from < to <= from + 360 deg (counter-clockwise)");
    return false;
  }

  // ------------------------------------------------------------ materials

  // One per Model material; only materials fed as particles must say how
  // they conduct.
  std::vector<fields::ElectricalMaterial> read_materials() {
    std::vector<fields::ElectricalMaterial> out;
    const auto& list = in_.model.materials.materials();
    for (std::size_t m = 0; m < list.size(); ++m) {
      const bool fed = std::find(in_.fed.begin(), in_.fed.end(), int(m)) != in_.fed.end();
      const Node* node = in_.materials ? in_.materials->find(list[m].name) : nullptr;
      out.push_back(node ? electrical(*node, list[m].name, fed) : fields::ElectricalMaterial{});
    }
    return out;
  }

  fields::ElectricalMaterial electrical(const Node& m, const std::string& name, bool fed) {
    fields::ElectricalMaterial e;
    const Node* conductor = m.find("conductor");
    const Node* fraction = m.find("metal_fraction");
    const Node* eps = m.find("relative_permittivity");
    if (fraction)
      e.metal_fraction = fraction->number();
    else if (conductor)
      e.metal_fraction = conductor->boolean() ? 1.0 : 0.0;
    if (!fed) return e;
    if (!conductor && !fraction) {
      diags_.error(m, "material '" + name +
                          "' is fed into the separator but does not say how it conducts, "
                          "expected conductor: true or false, or a metal_fraction");
      return e;
    }
    if (conductor && fraction && conductor->boolean() != (fraction->number() == 1.0)) {
      diags_.error(*fraction,
                   "metal_fraction " + format(fraction->number()) +
                       " contradicts conductor: " + (conductor->boolean() ? "true" : "false") +
                       ", expected one of them, or agreeing values");
      return e;
    }
    if (e.metal_fraction < 1.0) insulating_part(m, name, eps, e);
    return e;
  }

  // Pauthenier's charge needs εr; the decay time is given, or follows from
  // the resistivity (τ = ε0 εr ρ), or there is no decay.
  void insulating_part(const Node& m, const std::string& name, const Node* eps,
                       fields::ElectricalMaterial& e) {
    if (!eps) {
      diags_.error(m, "material '" + name +
                          "' is (partly) an insulator, whose corona charge needs its "
                          "relative_permittivity; expected relative_permittivity: (e.g. 4.4 "
                          "for FR-4)");
      return;
    }
    e.relative_permittivity = eps->number();
    if (const Node* tau = m.find("charge_decay_time"))
      e.decay_time = tau->number();
    else if (const Node* rho = m.find("resistivity"))
      e.decay_time = fields::relaxation_time(e.relative_permittivity, rho->number());
  }

  const ElectrostaticsInput& in_;
  const Node& s_;
  Diagnostics& diags_;
  bool ok_ = true;  // no electrode was reported
  std::vector<const Node*> nodes_;  // the scene's entry of each electrode read
};

}  // namespace

void drop_corona_defaults(Node& root) {
  Node* section = root.find("electrostatics");
  Node* list = section ? section->find("electrodes") : nullptr;
  if (!list || !list->is_sequence()) return;
  for (Node& e : list->items) {
    const Node* type = e.is_map() ? e.find("type") : nullptr;
    if (!type || (type->is_string() && type->string() == "corona")) continue;
    std::erase_if(e.entries, [](const Entry& entry) {
      return entry.value.defaulted &&
             std::find(std::begin(kCoronaKeys), std::end(kCoronaKeys), entry.key) !=
                 std::end(kCoronaKeys);
    });
  }
}

void compile_electrostatics(const ElectrostaticsInput& in, Simulation& sim, Diagnostics& diags) {
  ElectrostaticsCompiler(in, diags).compile(sim);
}

}  // namespace ces::scene
