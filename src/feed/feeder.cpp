#include "feed/feeder.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <sstream>
#include <string>

#include "common/hash.hpp"
#include "common/random.hpp"

namespace ces::feed {
namespace {

// A number in a message, to 6 significant digits.
std::string number(double x) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", x);
  return text;
}

const ParticleShape& shape_of(const Model& model, const FeedComponent& c) {
  return model.shapes.at(std::size_t(c.shape));
}

// Do two (possibly clustered) particles share any volume?
bool clusters_overlap(const ParticleShape& a, double scale_a, const Vec3& xa, const Quat& qa,
                      const ParticleShape& b, double scale_b, const Vec3& xb, const Quat& qb) {
  for (std::size_t i = 0; i < a.centers.size(); ++i) {
    const Vec3 ca = xa + qa * (scale_a * a.centers[i]);
    for (std::size_t j = 0; j < b.centers.size(); ++j) {
      const Vec3 cb = xb + qb * (scale_b * b.centers[j]);
      const double reach = scale_a * a.radii[i] + scale_b * b.radii[j];
      if ((ca - cb).squaredNorm() < reach * reach) return true;
    }
  }
  return false;
}

// The seed of the feed's particle number `ordinal` (0 for its first).
std::uint64_t particle_seed(std::uint64_t feed_stream, std::uint64_t ordinal) {
  return splitmix64(feed_stream ^ splitmix64(ordinal));
}

}  // namespace

std::uint64_t stream_seed(std::uint64_t scene_seed, std::string_view feed_name) {
  return splitmix64(scene_seed ^ splitmix64(fnv1a(feed_name)));
}

Tally FeedStats::total() const {
  Tally t;
  for (const Tally& c : fed) t += c;
  return t;
}

Feeder::Feeder(const Feed& feed, std::uint64_t scene_seed, const Model& model)
    : feed_(feed), model_(&model), stream_(stream_seed(scene_seed, feed.name)) {
  if (feed_.mix.empty()) throw std::invalid_argument("feed '" + feed_.name + "' has no mix");
  stats_.fed.resize(feed_.mix.size());
  for (const FeedComponent& c : feed_.mix) {
    if (c.drawn) {
      max_bounding_radius_ =
          std::max(max_bounding_radius_, c.drawn->largest_bounding_radius(model.shapes));
      continue;
    }
    const double largest = c.size.quantile_by_number(1.0) / c.shape_size;
    max_bounding_radius_ =
        std::max(max_bounding_radius_, largest * shape_of(model, c).bounding_radius);
  }
}

double Feeder::target(double t) const {
  const double elapsed = std::clamp(t - feed_.start, 0.0, feed_.duration);
  return (feed_.mass_rate > 0.0 ? feed_.mass_rate : feed_.count_rate) * elapsed;
}

double Feeder::fed_amount() const {
  const Tally t = stats_.total();
  return feed_.mass_rate > 0.0 ? t.kg() : double(t.count);
}

bool Feeder::finished(double t) const { return t >= feed_.start + feed_.duration && !owing_; }

void Feeder::feed(State& state) {
  const double goal = target(state.time + model_->step);
  neighbours_valid_ = false;
  owing_ = false;
  while (fed_amount() < goal) {
    if (!pending_) pending_ = draw_candidate();
    const double amount = feed_.mass_rate > 0.0 ? pending_->mass : 1.0;
    // Add the particle only if that brings the fed amount closer to the goal.
    if (fed_amount() + 0.5 * amount > goal) return;
    if (!place(state, *pending_)) {
      ++stats_.deferrals;
      owing_ = true;
      return;
    }
    pending_.reset();
  }
}

int Feeder::choose_component() const {
  const double total = stats_.total().kg();
  int best = 0;
  double best_deficit = -std::numeric_limits<double>::infinity();
  for (std::size_t c = 0; c < feed_.mix.size(); ++c) {
    const double fraction = feed_.mix[c].mass_fraction;
    const double deficit = fraction * total - stats_.fed[c].kg();
    // Ties (the first particle) go to the largest fraction, then the first listed.
    if (deficit > best_deficit ||
        (deficit == best_deficit && fraction > feed_.mix[std::size_t(best)].mass_fraction)) {
      best = int(c);
      best_deficit = deficit;
    }
  }
  return best;
}

// A size drawn for the component's shape, or (drawn dimensions) a
// thickness and a width or length, which pick the contact shape and give
// the mass and inertia.
Feeder::Candidate Feeder::draw_candidate() {
  rng_.seed(particle_seed(stream_, stats_.total().count));
  Candidate c;
  c.component = choose_component();
  const FeedComponent& comp = feed_.mix[std::size_t(c.component)];
  const double density = model_->materials.materials().at(std::size_t(comp.material)).density;
  double size = 0.0;
  if (comp.drawn) {
    const double t = comp.drawn->thickness.sample(rng_);
    size = comp.drawn->extent.sample(rng_);
    const DrawnShape::Rung& rung = comp.drawn->rung(t, size);
    c.shape = rung.shape;
    c.scale = size / rung.extent;
    c.mass = density * comp.drawn->volume(t, size);
    c.inertia = c.mass * comp.drawn->unit_inertia(
                             t, size, model_->shapes.at(std::size_t(c.shape)).unit_inertia);
  } else {
    size = comp.size.sample(rng_);
    c.shape = comp.shape;
    c.scale = size / comp.shape_size;
    c.mass = particle_mass(*model_, comp.shape, c.scale, comp.material);
    c.inertia = c.mass * c.scale * c.scale * shape_of(*model_, comp).unit_inertia;
  }
  if (!tally_holds(c.mass))
    throw std::runtime_error("feed '" + feed_.name + "': a particle of size " + number(size) +
                             " m has mass " + number(c.mass) + " kg, expected " +
                             number(kMassUnit) + " to " + number(kMaxParticleMass) +
                             " kg, the masses the balance counts exactly (check its size "
                             "distribution, shape size and density)");
  const double radius = c.scale * model_->shapes.at(std::size_t(c.shape)).bounding_radius;
  if (radius > max_bounding_radius_) {
    max_bounding_radius_ = radius;
    neighbours_valid_ = false;
  }
  return c;
}

bool Feeder::place(State& state, const Candidate& c) {
  if (!neighbours_valid_) find_neighbours(state);
  const FeedComponent& comp = feed_.mix[std::size_t(c.component)];
  const geo::Aabb& region = feed_.region;
  for (int attempt = 0; attempt < feed_.max_attempts; ++attempt) {
    Vec3 x;
    for (int k = 0; k < 3; ++k) x[k] = region.min[k] + uniform() * (region.max[k] - region.min[k]);
    const Quat q = orientation(c);
    if (overlaps_bodies(state, c, x, q) || overlaps_particles(state, c, x, q)) {
      ++stats_.retries;
      continue;
    }
    Vec3 v = feed_.velocity;
    if (feed_.velocity_spread > 0.0)
      for (int k = 0; k < 3; ++k) v[k] += feed_.velocity_spread * (2.0 * uniform() - 1.0);
    add_particle(state, c.shape, c.scale, comp.material, c.mass, c.inertia, x, q, v);
    const Particles& p = state.particles;
    neighbours_.push_back(p.size() - 1);
    // Those placed since the grid was sorted are checked one by one: past
    // as many as it holds, they are sorted in, so the unsorted tail stays
    // no longer than the sorted part. A one-step feed is still quadratic,
    // by a constant factor less: each check scans that tail.
    if (neighbours_.size() - grid_.gridded > std::max<std::size_t>(kUngriddedMost, grid_.gridded))
      grid_neighbours(p);
    stats_.fed[std::size_t(c.component)].add(to_mass_units(p.mass.back()));
    return true;
  }
  return false;
}

bool Feeder::overlaps_bodies(const State& state, const Candidate& c, const Vec3& x,
                             const Quat& q) {
  const ParticleShape& s = model_->shapes.at(std::size_t(c.shape));
  for (std::size_t k = 0; k < model_->bodies.size(); ++k) {
    const Pose& pose = state.bodies.pose[k];
    for (std::size_t j = 0; j < s.centers.size(); ++j) {
      const double r = c.scale * s.radii[j];
      hits_.clear();
      geo::query(model_->bodies[k].shape, pose.inverse_apply(x + q * (c.scale * s.centers[j])), r,
                 hits_);
      for (const geo::SurfaceHit& hit : hits_)
        if (hit.distance < r) return true;
    }
  }
  return false;
}

bool Feeder::overlaps_particles(const State& state, const Candidate& c, const Vec3& x,
                                const Quat& q) const {
  const ParticleShape& s = model_->shapes.at(std::size_t(c.shape));
  const double radius = c.scale * s.bounding_radius;
  const Particles& p = state.particles;
  bool overlap = false;
  for_each_neighbour_near(x, [&](std::size_t i) {
    const ParticleShape& o = model_->shapes[std::size_t(p.shape[i])];
    const double reach = radius + p.scale[i] * o.bounding_radius;
    if ((p.position[i] - x).squaredNorm() >= reach * reach) return false;
    overlap = clusters_overlap(s, c.scale, x, q, o, p.scale[i], p.position[i], p.orientation[i]);
    return overlap;
  });
  return overlap;
}

// fn(i) for the neighbours i that may be within reach of x (a point of the
// region), until it returns true.
template <class Fn>
void Feeder::for_each_neighbour_near(const Vec3& x, Fn&& fn) const {
  const Grid& g = grid_;
  std::array<std::size_t, 3> lo, hi;
  for (int k = 0; k < 3; ++k) {
    lo[std::size_t(k)] = g.coord(x, k, -1.0);
    hi[std::size_t(k)] = g.coord(x, k, 1.0);
  }
  for (std::size_t cx = lo[0]; cx <= hi[0]; ++cx)
    for (std::size_t cy = lo[1]; cy <= hi[1]; ++cy)
      for (std::size_t cz = lo[2]; cz <= hi[2]; ++cz) {
        const std::size_t cell = (cx * g.cells[1] + cy) * g.cells[2] + cz;
        for (std::size_t e = g.start[cell]; e < g.start[cell + 1]; ++e)
          if (fn(g.entry[e])) return;
      }
  for (std::size_t e = g.gridded; e < neighbours_.size(); ++e)
    if (fn(neighbours_[e])) return;
}

// Candidates for contact with a new particle: within reach of the region.
void Feeder::find_neighbours(const State& state) {
  neighbours_.clear();
  const Particles& p = state.particles;
  const geo::Aabb& region = feed_.region;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double reach = max_bounding_radius_ + bounding_radius(*model_, p, i);
    const Vec3 outside =
        (region.min - p.position[i]).cwiseMax(p.position[i] - region.max).cwiseMax(0.0);
    if (outside.squaredNorm() <= reach * reach) neighbours_.push_back(i);
  }
  grid_neighbours(p);
  neighbours_valid_ = true;
}

// All of neighbours_ into the grid, its cells as wide as a candidate's
// reach to the largest of them.
void Feeder::grid_neighbours(const Particles& p) {
  double largest = 0.0;  // of the neighbours' bounding radii
  for (const std::size_t i : neighbours_)
    largest = std::max(largest, bounding_radius(*model_, p, i));
  sort_neighbours(p, max_bounding_radius_ + largest);
}

// Cells a little wider than `reach` (rounding then never puts a neighbour
// in reach two cells away), over the region grown by it, where every
// neighbour lies; wider still where they would outnumber the neighbours
// several times over. A counting sort by cell.
void Feeder::sort_neighbours(const Particles& p, double reach) {
  Grid& g = grid_;
  const geo::Aabb box = feed_.region.inflated(reach);
  const Vec3 extent = box.max - box.min;
  const double most = std::max(4096.0, 4.0 * double(neighbours_.size()));
  double cell = reach > 0.0 ? reach * (1.0 + 1e-6) : 1.0;
  auto count = [&](int k) { return std::max(1.0, std::ceil(extent[k] / cell)); };
  while (count(0) * count(1) * count(2) > most) cell *= 2.0;
  g.min = box.min;
  g.inv_cell = 1.0 / cell;
  for (int k = 0; k < 3; ++k) g.cells[std::size_t(k)] = std::size_t(count(k));
  auto cell_of = [&](const Vec3& x) {
    return (g.coord(x, 0) * g.cells[1] + g.coord(x, 1)) * g.cells[2] + g.coord(x, 2);
  };
  const std::size_t cells = g.cells[0] * g.cells[1] * g.cells[2];
  g.start.assign(cells + 1, 0);
  for (const std::size_t i : neighbours_) ++g.start[cell_of(p.position[i]) + 1];
  for (std::size_t c = 0; c < cells; ++c) g.start[c + 1] += g.start[c];
  g.entry.resize(neighbours_.size());
  g.fill.assign(g.start.begin(), g.start.end() - 1);
  for (const std::size_t i : neighbours_) g.entry[g.fill[cell_of(p.position[i])]++] = i;
  g.gridded = neighbours_.size();
}

std::size_t Feeder::Grid::coord(const Vec3& x, int k, double shift) const {
  const double at = std::floor((x[k] - min[k]) * inv_cell) + shift;
  return std::size_t(std::clamp(at, 0.0, double(cells[std::size_t(k)] - 1)));
}

void Feeder::save(ByteWriter& out) const {
  std::ostringstream rng;
  rng << rng_;
  out.text(rng.str());
  out.values(stats_.fed);
  out.value(stats_.retries);
  out.value(stats_.deferrals);
  out.value(pending_.has_value());
  const Candidate c = pending_.value_or(Candidate{});
  out.value(c.component);
  out.value(c.shape);
  out.value(c.scale);
  out.value(c.mass);
  out.value(c.inertia);
  out.value(owing_);
  out.value(max_bounding_radius_);
}

void Feeder::load(ByteReader& in) {
  std::istringstream rng(in.text());
  rng >> rng_;
  if (!rng) throw CorruptData("feed '" + feed_.name + "': its random stream does not read");
  in.values(stats_.fed);
  if (stats_.fed.size() != feed_.mix.size())
    throw CorruptData("feed '" + feed_.name + "': its mix has changed");
  in.value(stats_.retries);
  in.value(stats_.deferrals);
  const bool pending = in.value<bool>();
  Candidate c;
  in.value(c.component);
  in.value(c.shape);
  in.value(c.scale);
  in.value(c.mass);
  in.value(c.inertia);
  if (c.component < 0 || std::size_t(c.component) >= feed_.mix.size() || c.shape < 0 ||
      std::size_t(c.shape) >= model_->shapes.size())
    throw CorruptData("feed '" + feed_.name + "': its pending particle does not fit the scene");
  pending_ = pending ? std::optional<Candidate>(c) : std::nullopt;
  in.value(owing_);
  in.value(max_bounding_radius_);
  neighbours_valid_ = false;
}

double Feeder::uniform() { return uniform01(rng_); }

// Random, lying flat, or the shape's principal frame as it is.
Quat Feeder::orientation(const Candidate& c) {
  if (!feed_.lie_flat) return feed_.random_orientation ? random_orientation() : Quat::Identity();
  const Vec3& inertia = model_->shapes.at(std::size_t(c.shape)).unit_inertia;
  int k = 0;
  for (int a = 1; a < 3; ++a)
    if (inertia[a] > inertia[k]) k = a;
  const Quat turn(Eigen::AngleAxisd(feed_.random_orientation ? 2.0 * kPi * uniform() : 0.0,
                                    Vec3::Unit(k)));
  return Quat::FromTwoVectors(Vec3::Unit(k), *feed_.lie_flat) * turn;
}

// Shoemake's uniform random rotation.
Quat Feeder::random_orientation() {
  const double u1 = uniform(), u2 = 2.0 * kPi * uniform(), u3 = 2.0 * kPi * uniform();
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  return Quat(b * std::cos(u3), a * std::sin(u2), a * std::cos(u2), b * std::sin(u3));
}

}  // namespace ces::feed
