#include "scene/compiler.hpp"

namespace ces::scene {

void Compiler::read_collectors() {
  const Node* list = root_.find("collectors");
  if (!list) return;
  NameTable names("collector");
  for (const Node& c : list->items) {
    names.declare(c.at("name").string(), c.at("name").mark, c.at("name").path,
                  int(sim_.collectors.size()), diags_);
    Collector collector;
    collector.name = c.at("name").string();
    const Node& plane = c.at("plane");
    const Node& bins = c.at("bins");
    collector.point = vec3(plane.at("point"));
    collector.normal = direction(plane.at("normal")).value_or(Vec3::UnitY());
    collector.axis = direction(bins.at("axis")).value_or(Vec3::UnitX());
    collector.from = bins.at("from").number();
    collector.to = bins.at("to").number();
    collector.bins = bins.at("count").scalar.get<int>();
    if (check_bins(bins, collector)) read_products(c.find("products"), collector);
    check_reachable(plane, bins, collector);
    sim_.collectors.push_back(std::move(collector));
  }
}

// Each bin keeps a tally per material.
void Compiler::check_bin_tallies() {
  double bins = 0.0;
  for (const Collector& c : sim_.collectors) bins += c.bins;
  const double tallies = bins * double(model_->materials.materials().size());
  if (tallies > limits::kBinTallies)
    diags_.error(root_.at("collectors"),
                 whole(bins) + " bins for " +
                     std::to_string(model_->materials.materials().size()) +
                     " materials make " + whole(tallies) + " tallies, expected at most " +
                     whole(limits::kBinTallies) + " (fewer bins)");
}

bool Compiler::check_bins(const Node& bins, const Collector& c) {
  if (std::abs(c.axis.dot(c.normal)) > 1.0 - 1e-9) {
    diags_.error(bins.at("axis"),
                 "the bin axis is along the plane's normal, so every particle would land at "
                 "the same place; expected an axis in the plane");
    return false;
  }
  if (!(c.from < c.to)) {
    diags_.error(bins.at("to"), "to " + metres(c.to) + " is not above from " + metres(c.from) +
                                    ", expected from < to");
    return false;
  }
  return true;
}

void Compiler::read_products(const Node* products, Collector& c) {
  if (!products) return;
  std::vector<std::pair<Product, const Node*>> sorted;
  for (const Entry& e : products->entries) {
    const Product p{e.key, e.value.items[0].number(), e.value.items[1].number()};
    if (!(p.from < p.to)) {
      diags_.error(e.value, "the range is empty or reversed, expected [from, to] with from < to");
    } else if (p.from < c.from || p.to > c.to) {
      diags_.error(e.value, "the range leaves the bins [" + format(c.from) + ", " + format(c.to) +
                                "] m, expected a range inside them");
    } else {
      sorted.emplace_back(p, &e.value);
    }
    c.products.push_back(p);
  }
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& a, const auto& b) { return a.first.from < b.first.from; });
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i].first.from < sorted[i - 1].first.to)
      diags_.error(*sorted[i].second, "overlaps product '" + sorted[i - 1].first.name +
                                          "', expected products that do not overlap");
  }
}

// With a domain, the plane must cut it: particles leave the domain first
// otherwise.
void Compiler::check_reachable(const Node& plane, const Node& bins, const Collector& c) {
  if (!sim_.domain) return;
  double lo = kInf, hi = -kInf;
  for (int k = 0; k < 8; ++k) {
    const double side = c.normal.dot(sim_.domain->corner(k) - c.point);
    lo = std::min(lo, side);
    hi = std::max(hi, side);
  }
  if (lo >= 0.0 || hi <= 0.0)
    return diags_.error(
        plane,
        "the plane misses the domain, so no particle can reach it; expected a plane through "
        "domain.box");
  if (c.from < c.to) check_bins_in_domain(bins, c);
}

// The domain's extent along the bin axis bounds where a particle can
// cross the plane.
void Compiler::check_bins_in_domain(const Node& bins, const Collector& c) {
  double lo = kInf, hi = -kInf;
  for (int k = 0; k < 8; ++k) {
    const double along = c.axis.dot(sim_.domain->corner(k) - c.point);
    lo = std::min(lo, along);
    hi = std::max(hi, along);
  }
  if (c.to <= lo || c.from >= hi)
    diags_.error(bins, "the bins [" + format(c.from) + ", " + format(c.to) +
                           "] m lie outside the domain, which spans [" + format(lo) + ", " +
                           format(hi) + "] m along the bin axis; expected bins inside it");
}

void Compiler::read_air() {
  const Node* air = root_.find("air");
  if (!air) return;
  fields::DragSpec drag;
  drag.air.density = air->at("density").number();
  drag.air.viscosity = air->at("viscosity").number();
  drag.law = air->at("drag").string() == "stokes" ? fields::DragLaw::Stokes
                                                  : fields::DragLaw::SchillerNaumann;
  sim_.drag = drag;
}

void Compiler::read_electrostatics() {
  const Node* section = root_.find("electrostatics");
  if (!section) return;
  std::vector<int> fed;
  for (const Feed& f : sim_.feeds)
    for (const FeedComponent& c : f.mix) fed.push_back(c.material);
  compile_electrostatics({*section, root_.find("materials"), *model_, fed, scene_dir_,
                          [this](const Node& ref) { return bodies_.resolve(ref, diags_); }},
                         sim_, diags_);
}

// A frame is written at most once a step, so a shorter interval counts as
// the step.
void Compiler::check_frames(const Node& every_node, double every) {
  const double interval = std::max(every, model_->step);
  const double frames = sim_.end_time / interval;
  if (frames <= limits::kFrames) return;
  const std::string given = every < model_->step ? "a frame every step (" + format(interval) + " s)"
                                                 : "a frame every " + format(interval) + " s";
  diags_.error(every_node, given + " makes " + whole(frames) +
                               " trajectory frames, expected at most " +
                               whole(limits::kFrames) + " (a longer interval)");
}

void Compiler::read_output() {
  const Node& out = root_.at("output");
  sim_.output.dir = out.at("dir").string();
  sim_.output.steps_csv = out.at("steps").boolean();
  sim_.output.distribution_svg = out.at("distribution").boolean();
  const Node* t = out.find("trajectories");
  if (t && t->at("format").string() != "none") {
    const std::string& kind = t->at("format").string();
    sim_.output.trajectories.every = t->at("every").number();
    check_frames(t->at("every"), sim_.output.trajectories.every);
    sim_.output.trajectories.vtk = kind != "csv";
    sim_.output.trajectories.csv = kind != "vtk";
  } else {
    sim_.output.trajectories = {0.0, false, false};
  }
  if (const Node* field = out.find("field")) read_field_picture(*field);
  if (const Node* c = out.find("checkpoint"))
    sim_.output.checkpoint_every = c->at("every").number();
}

void Compiler::read_field_picture(const Node& f) {
  if (!sim_.electrostatics) {
    if (!root_.find("electrostatics"))  // else the section's own problems were reported
      diags_.error(f, "the field picture needs a field, expected an electrostatics section");
    return;
  }
  FieldPicture picture;
  picture.resolution = f.at("resolution").number();
  if (const Node* extent = f.find("extent")) {
    const Node& lo = extent->at("min");
    const Node& hi = extent->at("max");
    picture.min = Vec2(lo.items[0].number(), lo.items[1].number());
    picture.max = Vec2(hi.items[0].number(), hi.items[1].number());
    if (!(picture.min.array() < picture.max.array()).all())
      return diags_.error(hi, "max is not above min on both axes, expected max > min");
  } else {
    default_extent(picture);
  }
  const Vec2 cells = (picture.max - picture.min) / picture.resolution;
  if ((cells.x() + 1.0) * (cells.y() + 1.0) > kMaxFieldSamples)
    return diags_.error(f.at("resolution"), "a resolution of " + metres(picture.resolution) +
                                                " needs " +
                                                format((cells.x() + 1.0) * (cells.y() + 1.0)) +
                                                " samples, expected a coarser one (at most " +
                                                format(kMaxFieldSamples) + ")");
  sim_.output.field = picture;
}

// The drum and the electrodes, with a margin of a fifth of the drum radius.
void Compiler::default_extent(FieldPicture& p) const {
  const double r = sim_.electrostatics->drum.radius;
  p.min = Vec2(-r, -r);
  p.max = Vec2(r, r);
  for (const NamedElectrode& e : sim_.electrodes) {
    const Vec2 reach = Vec2::Constant(e.electrode.radius);
    p.min = p.min.cwiseMin(e.electrode.centre - reach);
    p.max = p.max.cwiseMax(e.electrode.centre + reach);
  }
  p.min -= Vec2::Constant(0.2 * r);
  p.max += Vec2::Constant(0.2 * r);
}

// What the run has to build (summary.json's active_components, docs/outputs.md):
// absent sections cost nothing.
void Compiler::list_components() {
  const Model& m = *model_;
  const auto any_body = [&](BodyKind kind) {
    return std::any_of(m.bodies.begin(), m.bodies.end(),
                       [&](const RigidBody& b) { return b.kind == kind; });
  };
  const bool meshes = std::any_of(m.bodies.begin(), m.bodies.end(), [](const RigidBody& b) {
    return std::holds_alternative<std::shared_ptr<const geo::TriMesh>>(b.shape);
  });
  const bool clusters = std::any_of(m.shapes.begin(), m.shapes.end(),
                                    [](const ParticleShape& s) { return !s.is_sphere(); });
  const std::vector<std::pair<const char*, bool>> components = {
      {"gravity", m.gravity != Vec3::Zero()},
      {"contacts", !sim_.feeds.empty() || any_body(BodyKind::Dynamic)},
      {"kinematic_bodies", any_body(BodyKind::Kinematic)},
      {"dynamic_bodies", any_body(BodyKind::Dynamic)},
      {"joints", !m.joints.empty()},
      {"motors", !m.motors.empty()},
      {"meshes", meshes},
      {"clusters", clusters},
      {"feeds", !sim_.feeds.empty()},
      {"collectors", !sim_.collectors.empty()},
      {"domain", sim_.domain.has_value()},
      {"drag", sim_.drag.has_value()},
      {"electrostatics", sim_.electrostatics.has_value()},
      {"corona_charging", sim_.electrostatics && (!sim_.electrostatics->corona.empty() ||
                                                  !sim_.electrostatics->bands.empty())},
      {"brush", sim_.electrostatics && sim_.electrostatics->brush_body.has_value()},
      {"trajectories", sim_.output.trajectories.every > 0.0},
  };
  for (const auto& [name, on] : components)
    if (on) sim_.active_components.push_back(name);
}

}  // namespace ces::scene
