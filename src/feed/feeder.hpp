// A feeder: the feed stage of one feed, which adds its particles to the state.
//
// Rate: the fed amount (mass or count) tracks rate * elapsed time; a particle
// is added while doing so brings the fed amount closer to the target, so the
// fed amount stays within half a particle of it and the fractional particle
// carries over to the next step.
// Mix: each particle's component is the one whose fed mass is furthest below
// its share of the total, so the fed mass fractions converge to the mix
// fractions without randomness.
// Placement: uniform in the region with a uniform random orientation, free of
// machine bodies (at their pose now) and of particles; after max_attempts
// failures the particle waits for the next step (a deferral).
// Randomness: each particle draws from its own std::mt19937_64, seeded from
// (scene seed, feed name, the particle's place in the feed's order), so
// adding or changing a feed never changes another feed's particles, and a
// placement retry (which depends on where earlier particles went) never
// changes the particles after it: runs of one scene at other settings feed
// the same particles, and their products differ by what the settings do.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <random>
#include <string_view>
#include <vector>

#include "common/serial.hpp"
#include "common/tally.hpp"
#include "feed/feed.hpp"
#include "geometry/shapes.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces::feed {

// splitmix64(seed ^ splitmix64(FNV-1a 64 of the name)): fixed across
// platforms and standard libraries.
std::uint64_t stream_seed(std::uint64_t scene_seed, std::string_view feed_name);

struct FeedStats {
  std::vector<Tally> fed;  // per mix component
  std::uint64_t retries = 0;       // placement attempts that overlapped something
  std::uint64_t deferrals = 0;     // particles moved to a later step
  Tally total() const;
};

class Feeder {
 public:
  Feeder(const Feed& feed, std::uint64_t scene_seed, const Model& model);

  // Feeds the step that starts at state.time: adds particles to the state.
  void feed(State& state);

  const Feed& feed() const { return feed_; }
  const FeedStats& stats() const { return stats_; }
  // What rate * elapsed asks for by time t: kg for mass-rate feeds, particles
  // for count-rate feeds.
  double target(double t) const;
  // The fed amount in the same unit as target().
  double fed_amount() const;
  // The feed's time is over at t and the last step placed everything it owed.
  bool finished(double t) const;

  // What the feed carries from one step to the next (its random stream,
  // tallies, the particle drawn but not yet placed, whether it owes one),
  // for checkpoints.
  void save(ByteWriter& out) const;
  void load(ByteReader& in);

 private:
  struct Candidate {
    int component = 0;
    int shape = 0;  // Model::shapes index
    double scale = 1.0;
    double mass = 0.0;
    Vec3 inertia = Vec3::Zero();  // principal
  };

  Candidate draw_candidate();
  int choose_component() const;
  bool place(State& state, const Candidate& c);
  bool overlaps_bodies(const State& state, const Candidate& c, const Vec3& x, const Quat& q);
  bool overlaps_particles(const State& state, const Candidate& c, const Vec3& x,
                          const Quat& q) const;
  void find_neighbours(const State& state);
  void grid_neighbours(const Particles& p);
  // neighbours_ by cell of grid_, cells at least `reach` wide.
  void sort_neighbours(const Particles& p, double reach);
  template <class Fn>
  void for_each_neighbour_near(const Vec3& x, Fn&& fn) const;
  double uniform();
  Quat orientation(const Candidate& c);
  Quat random_orientation();

  Feed feed_;
  const Model* model_;
  std::uint64_t stream_;  // stream_seed of this feed
  std::mt19937_64 rng_;   // the stream of the particle being drawn or placed
  FeedStats stats_;
  std::optional<Candidate> pending_;     // drawn but not yet placed
  double max_bounding_radius_ = 0.0;     // of any particle this feed can draw
  std::vector<std::size_t> neighbours_;  // particles that may touch the region
  // Those found by find_neighbours (the first `gridded` of neighbours_) by
  // cell of a grid over the region, its cells at least as wide as a
  // candidate's reach to a neighbour: a candidate is checked against those
  // in the 27 cells around its own, not against all (thousands where the
  // feed lays a monolayer). Those placed since are checked one by one, up
  // to as many as the grid holds (place()); cells of their own would make
  // a one-step feed linear.
  struct Grid {
    Vec3 min = Vec3::Zero();
    double inv_cell = 0.0;
    std::array<std::size_t, 3> cells{};
    std::vector<std::size_t> start, entry;  // cell c's particles: entry[start[c] .. start[c + 1])
    std::vector<std::size_t> fill;          // scratch
    std::size_t gridded = 0;
    // x's cell along axis k, or `shift` cells past it, clamped to the grid.
    std::size_t coord(const Vec3& x, int k, double shift = 0.0) const;
  } grid_;
  static constexpr std::size_t kUngriddedMost = 4096;  // placed since, checked one by one
  bool neighbours_valid_ = false;        // found this step
  bool owing_ = false;                   // the last step deferred a particle
  std::vector<geo::SurfaceHit> hits_;    // scratch for body queries
};

}  // namespace ces::feed
