#include "scene/compiler.hpp"

#include "common/tally.hpp"

namespace ces::scene {

void Compiler::read_feeds() {
  const Node* list = root_.find("feeds");
  if (!list) return;
  NameTable names("feed");
  for (const Node& f : list->items) {
    names.declare(f.at("name").string(), f.at("name").mark, f.at("name").path,
                  int(sim_.feeds.size()), diags_);
    Feed feed;
    feed.name = f.at("name").string();
    feed.start = f.at("start").number();
    if (const Node* duration = f.find("duration"))
      feed.duration = duration->number();
    else if (sim_.until_collected)
      diags_.error(f, "feed '" + feed.name + "' has no duration, so it never stops and the run "
                      "could not end with time.until: collected; expected a duration");
    const Node& rate = f.at("rate");
    (rate.dimension == "mass_rate" ? feed.mass_rate : feed.count_rate) = rate.number();
    feed.velocity = vec3(f.at("velocity"));
    feed.velocity_spread = f.at("velocity_spread").number();
    feed.random_orientation = f.at("random_orientation").boolean();
    if (f.at("lie_flat").boolean()) {
      if (model_->gravity == Vec3::Zero())
        diags_.error(f.at("lie_flat"), "lying flat needs a down, expected gravity");
      else
        feed.lie_flat = -model_->gravity.normalized();
    }
    feed.max_attempts = f.at("max_attempts").scalar.get<int>();
    const std::vector<double> across = read_mix(f.at("mix"), feed);
    const Node& region = f.at("region");
    if (const auto box = feed_region(region)) {
      feed.region = *box;
      check_fit(region, *box, across);
      check_free(region, *box);
    }
    sim_.feeds.push_back(std::move(feed));
    feed_rates_.push_back(&rate);
  }
}

std::optional<geo::Aabb> Compiler::feed_region(const Node& region) {
  std::optional<geo::Aabb> box;
  if (const Node* b = region.find("box")) {
    box = aabb(*b);
  } else {
    box = outlet(region.at("outlet"));
  }
  if (box && !inside_domain(*box)) {
    diags_.error(
        region,
        "the region reaches outside the domain, so particles would be lost as they appear; "
        "expected a region inside domain.box");
    return std::nullopt;
  }
  return box;
}

// The feed region is an axis-aligned box, so an outlet faces along an axis.
std::optional<geo::Aabb> Compiler::outlet(const Node& o) {
  const Vec3 n = vec3(o.at("normal"));
  int axis = -1;
  for (int k = 0; k < 3; ++k)
    if (n[k] != 0.0 && n[(k + 1) % 3] == 0.0 && n[(k + 2) % 3] == 0.0) axis = k;
  if (axis < 0) {
    diags_.error(o.at("normal"), "got an oblique normal, expected one along x, y or z");
    return std::nullopt;
  }
  // The size lists the two other axes in x, y, z order.
  const int u = axis == 0 ? 1 : 0;
  const int v = axis == 2 ? 1 : 2;
  Vec3 half = Vec3::Zero();
  half[u] = 0.5 * o.at("size").items[0].number();
  half[v] = 0.5 * o.at("size").items[1].number();
  const Vec3 c = vec3(o.at("center"));
  return geo::Aabb{c - half, c + half};
}

// Returns the bounding diameter of each component's largest particles.
std::vector<double> Compiler::read_mix(const Node& mix, Feed& feed) {
  std::vector<double> across;
  double total = 0.0;
  for (const Node& c : mix.items) {
    FeedComponent component;
    component.mass_fraction = c.at("fraction").number();
    total += component.mass_fraction;
    const auto material = dense_material(c.at("material"), "feed '" + feed.name + "'");
    if (c.find("thickness")) {
      auto drawn = shapes_.drawn_shape(c);
      if (!material || !drawn) continue;
      component.material = *material;
      across.push_back(2.0 * drawn->largest_bounding_radius(model_->shapes));
      component.drawn = std::move(*drawn);
      check_masses(c, component, feed.name);
      feed.mix.push_back(component);
      continue;
    }
    if (!c.find("size")) {
      diags_.error(c, "missing key 'size', expected a size law, or thickness with width "
                      "(flake) or length (rod)");
      continue;
    }
    const auto shape = shapes_.particle_shape(c);
    const feed::Basis basis =
        c.at("by").string() == "mass" ? feed::Basis::mass : feed::Basis::number;
    const auto size = shapes_.size_distribution(c.at("size"), basis);
    if (!material || !shape || !size) continue;
    component.material = *material;
    component.shape = *shape;
    component.shape_size = shapes_.size(*shape);
    component.size = *size;
    check_masses(c, component, feed.name);
    feed.mix.push_back(component);
    across.push_back(2.0 * model_->shapes[std::size_t(*shape)].bounding_radius *
                     law_end(*size, c.at("size"), true) / component.shape_size);
  }
  if (std::abs(total - 1.0) > 1e-9)
    diags_.error(mix, "the fractions add up to " + format(total) + ", expected 1");
  return across;
}

// The diameter of a law's smallest (upper: largest) particles. A constant,
// uniform or sieve law reaches its ends; a normal or lognormal law reaches
// a far tail, or its min or max there, only by a vanishing chance: its
// one-in-a-million size stands in (a min or max in the bulk is that size,
// to a millionth of the spread).
double Compiler::law_end(const feed::SizeDistribution& d, const Node& law, bool upper) {
  const std::string& kind = law.entries.front().key;
  const bool reached = kind == "constant" || kind == "uniform" || kind == "sieve";
  const double q = reached ? 0.0 : 1e-6;
  return d.quantile_by_number(upper ? 1.0 - q : q);
}

// The volume of a component's smallest (upper: largest) particle: of its
// law's end, or of a drawn shape's thinnest and narrowest (thickest and
// widest).
double Compiler::end_volume(const Node& c, const FeedComponent& component, bool upper) const {
  if (const auto& d = component.drawn) {
    const Node& extent = c.find("width") ? c.at("width") : c.at("length");
    return d->volume(law_end(d->thickness, c.at("thickness"), upper),
                     law_end(d->extent, extent, upper));
  }
  const double scale = law_end(component.size, c.at("size"), upper) / component.shape_size;
  return model_->shapes[std::size_t(component.shape)].volume * scale * scale * scale;
}

// The masses of a component's lightest and heaviest particles against
// those the balance counts exactly: refused here, with the line, rather
// than at the step that draws one.
void Compiler::check_masses(const Node& c, const FeedComponent& component,
                            const std::string& feed) {
  const double density = model_->materials.materials()[std::size_t(component.material)].density;
  for (const double v : {end_volume(c, component, false), end_volume(c, component, true)}) {
    if (tally_holds(density * v)) continue;
    diags_.error(c, "feed '" + feed + "' makes particles of " + format(density * v) +
                        " kg, expected " + format(kMassUnit) + " to " + format(kMaxParticleMass) +
                        " kg, the masses the balance counts exactly (check the sizes and the "
                        "density)");
    return;
  }
}

// The largest particles against the region's extent (an outlet's
// thickness excepted).
void Compiler::check_fit(const Node& region, const geo::Aabb& box,
                         const std::vector<double>& across) {
  const Vec3 extent = box.max - box.min;
  const double largest = across.empty() ? 0.0 : *std::max_element(across.begin(), across.end());
  for (int k = 0; k < 3; ++k) {
    if (extent[k] == 0.0 || extent[k] >= largest) continue;
    diags_.error(region, "the region is " + metres(extent[k]) + " wide along " + "xyz"[k] +
                             " but the largest particles are " + metres(largest) +
                             " across, expected a region that holds them");
    return;
  }
}

// A region all inside one convex solid (a box, a solid cylinder, a
// plane's half-space) that stays put can place no particle. Convexity
// makes the corners enough.
void Compiler::check_free(const Node& region, const geo::Aabb& box) {
  for (const RigidBody& b : model_->bodies) {
    const auto* c = std::get_if<geo::Cylinder>(&b.shape);
    const bool convex = std::holds_alternative<geo::Plane>(b.shape) ||
                        std::holds_alternative<geo::Box>(b.shape) ||
                        (c && (c->thickness == 0.0 || c->thickness >= c->radius));
    if (!convex || !fixed_in_space(b)) continue;
    bool inside = true;
    for (int k = 0; k < 8 && inside; ++k) {
      hits_.clear();
      geo::query(b.shape, b.pose.inverse_apply(box.corner(k)), 0.0, hits_);
      inside = std::any_of(hits_.begin(), hits_.end(),
                           [](const geo::SurfaceHit& h) { return h.distance < 0.0; });
    }
    if (inside)
      return diags_.error(region, "the region lies inside body '" + b.name +
                                      "', so no particle can be placed; expected a region in "
                                      "free space");
  }
}

// The particles the feeds make over the run, expected from the rates:
// all of them are held in memory at once if nothing leaves.
void Compiler::check_feed_counts() {
  double total = 0.0, largest = -1.0;
  std::size_t at = 0;
  for (std::size_t i = 0; i < sim_.feeds.size(); ++i) {
    const double n = expected_particles(sim_.feeds[i]);
    total += n;
    if (!(n <= largest)) {
      largest = n;
      at = i;
    }
  }
  if (total <= limits::kFedParticles) return;
  diags_.error(*feed_rates_[at],
               "feed '" + sim_.feeds[at].name + "' makes about " + whole(largest) +
                   " particles over the run (all feeds " + whole(total) + "), expected at most " +
                   whole(limits::kFedParticles) + " in all (a lower rate or a shorter feed)");
}

double Compiler::expected_particles(const Feed& f) const {
  const double time = std::max(0.0, std::min(f.duration, sim_.end_time - f.start));
  if (f.count_rate > 0.0) return f.count_rate * time;
  double per_kg = 0.0;  // particles in a kilogram of the mix
  for (const FeedComponent& c : f.mix) {
    const double density = model_->materials.materials()[std::size_t(c.material)].density;
    per_kg += c.mass_fraction / (density * mean_volume(c));
  }
  return f.mass_rate * time * per_kg;
}

// A drawn flake's or rod's at its median dimensions: a bound's estimate.
double Compiler::mean_volume(const FeedComponent& c) const {
  if (c.drawn)
    return c.drawn->volume(c.drawn->thickness.quantile_by_number(0.5),
                           c.drawn->extent.quantile_by_number(0.5));
  const double volume = model_->shapes[std::size_t(c.shape)].volume;
  return volume * c.size.mean_mass_per_particle_factor() /
         (c.shape_size * c.shape_size * c.shape_size);
}

// Without gravity, fed particles keep their feed velocity: with none,
// they hang where they appear. A scene may mean it (gravity: [0, 0, 0]
// says so); leaving gravity out is usually an omission.
void Compiler::check_gravity() {
  if (sim_.feeds.empty() || root_.find("gravity")) return;
  diags_.warning(root_.at("feeds"),
                 "particles are fed but the scene gives no gravity: they move only by their feed "
                 "velocity, drag and fields; expected gravity (e.g. [0, -9.81 m/s^2, 0]), or "
                 "gravity: [0, 0, 0] to say there is none");
}

}  // namespace ces::scene
