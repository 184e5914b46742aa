// The runner below the command line: feeders, collectors and the domain, the
// exact particle balance, and the output files (atomic, complete: false on
// an interrupted run). Simulations are built in C++ here; the command line
// and scene files are covered by cli_test.cpp.
#include "support.hpp"
#include "sim/run.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>
#include <tuple>

#include "collect/collection.hpp"
#include "common/process.hpp"
#include "common/tally.hpp"
#include "feed/feeder.hpp"
#include "output/compare.hpp"
#include "output/files.hpp"
#include "output/tables.hpp"
#include "sim/world.hpp"

namespace ces {
namespace {

namespace fs = std::filesystem;

constexpr int kCopper = 0, kFr4 = 1, kSteel = 2;

// Copper, FR-4 and steel; shape 0 a unit-diameter sphere, shape 1 a
// three-sphere flake (size 2 at scale 1); no gravity unless asked.
std::shared_ptr<Model> make_model(Vec3 gravity = Vec3::Zero()) {
  auto m = std::make_shared<Model>();
  m->step = 1e-3;
  m->gravity = gravity;
  m->materials = MaterialTable(
      {{"copper", 8960, 0.3, 0.0}, {"fr4", 1850, 0.4, 0.0}, {"steel", 7800, 0.3, 0.0}}, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {0.5}));
  m->shapes.push_back(
      make_particle_shape({Vec3(-0.5, 0, 0), Vec3::Zero(), Vec3(0.5, 0, 0)}, {0.5, 0.5, 0.5}));
  return m;
}

FeedComponent component(int material, double fraction, double dmin, double dmax, int shape = 0) {
  FeedComponent c;
  c.material = material;
  c.mass_fraction = fraction;
  c.size = dmin == dmax ? feed::SizeDistribution::constant(dmin)
                        : feed::SizeDistribution::uniform(dmin, dmax, feed::Basis::number);
  c.shape = shape;
  c.shape_size = shape == 0 ? 1.0 : 2.0;
  return c;
}

Feed make_feed(const std::string& name, geo::Aabb region, std::vector<FeedComponent> mix) {
  Feed f;
  f.name = name;
  f.region = region;
  f.mix = std::move(mix);
  return f;
}

geo::Aabb box(Vec3 lo, Vec3 hi) { return geo::Aabb{lo, hi}; }

// Heaviest particle a component can make (a sphere of diameter dmax).
double sphere_mass(double density, double d) { return density * kPi / 6.0 * d * d * d; }

// Runs a World with feeders for n steps; calls check(world, feeders) after each.
template <class Check>
void run_feeders(std::shared_ptr<Model> model, const std::vector<Feed>& feeds, int steps,
                 Check check, std::uint64_t seed = 1) {
  World world(model);
  for (const Feed& f : feeds) world.add_feed(f, seed);
  for (int i = 0; i < steps; ++i) {
    world.step();
    check(world, world.feeders());
  }
}

using ces::test::fresh_dir;
using ces::test::read_text;

TEST(RunFeeder, MassRateTracksRateTimesTimeWithinOneParticle) {
  Feed f = make_feed("hopper", box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.05)),
                     {component(kFr4, 1.0, 0.5e-3, 1.5e-3)});
  f.mass_rate = 2e-3;  // 2 g/s: a few particles per step
  f.start = 0.02;
  f.duration = 0.1;
  const double heaviest = sphere_mass(1850, 1.5e-3);
  double last = 0;
  run_feeders(make_model(), {f}, 150, [&](const World& w, const auto& feeders) {
    const double elapsed = std::clamp(w.time() - f.start, 0.0, f.duration);
    const double fed = feeders[0].stats().total().kg();
    EXPECT_LE(std::abs(fed - f.mass_rate * elapsed), heaviest) << "t = " << w.time();
    last = fed;
  });
  EXPECT_NEAR(last, f.mass_rate * f.duration, heaviest);
}

TEST(RunFeeder, CountRateTracksRateTimesTimeWithinOneParticle) {
  Feed f = make_feed("counter", box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.05)),
                     {component(kCopper, 1.0, 1e-3, 1e-3)});
  f.count_rate = 1234.5;
  run_feeders(make_model(), {f}, 100, [&](const World& w, const auto& feeders) {
    const double fed = double(feeders[0].stats().total().count);
    EXPECT_LE(std::abs(fed - f.count_rate * w.time()), 1.0) << "t = " << w.time();
    EXPECT_EQ(w.particles().size(), feeders[0].stats().total().count);
  });
}

TEST(RunFeeder, MixMassFractionsConvergeWithinOneParticle) {
  Feed f = make_feed("mix", box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.05)),
                     {component(kCopper, 0.3, 0.5e-3, 1.2e-3), component(kFr4, 0.7, 0.5e-3, 2e-3)});
  f.mass_rate = 5e-3;
  const double heaviest = std::max(sphere_mass(8960, 1.2e-3), sphere_mass(1850, 2e-3));
  run_feeders(make_model(), {f}, 100, [&](const World&, const auto& feeders) {
    const feed::FeedStats& s = feeders[0].stats();
    const double total = s.total().kg();
    EXPECT_LE(std::abs(s.fed[0].kg() - 0.3 * total), heaviest);
    EXPECT_LE(std::abs(s.fed[1].kg() - 0.7 * total), heaviest);
  });
}

// Distance between two particles' surfaces (negative: overlap), sphere by sphere.
double clearance(const Model& m, const Particles& p, std::size_t a, std::size_t b) {
  const ParticleShape &sa = m.shapes[std::size_t(p.shape[a])],
                      &sb = m.shapes[std::size_t(p.shape[b])];
  double gap = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < sa.centers.size(); ++i)
    for (std::size_t j = 0; j < sb.centers.size(); ++j) {
      const Vec3 ca = p.position[a] + p.orientation[a] * (p.scale[a] * sa.centers[i]);
      const Vec3 cb = p.position[b] + p.orientation[b] * (p.scale[b] * sb.centers[j]);
      gap = std::min(gap, (ca - cb).norm() - p.scale[a] * sa.radii[i] - p.scale[b] * sb.radii[j]);
    }
  return gap;
}

double body_clearance(const Model& m, const World& w, const Particles& p, std::size_t a) {
  const ParticleShape& s = m.shapes[std::size_t(p.shape[a])];
  double gap = std::numeric_limits<double>::infinity();
  std::vector<geo::SurfaceHit> hits;
  for (std::size_t k = 0; k < m.bodies.size(); ++k)
    for (std::size_t i = 0; i < s.centers.size(); ++i) {
      const Vec3 c = p.position[a] + p.orientation[a] * (p.scale[a] * s.centers[i]);
      hits.clear();
      geo::query(m.bodies[k].shape, w.bodies().pose[k].inverse_apply(c), 1.0, hits);
      for (const auto& h : hits) gap = std::min(gap, h.distance - p.scale[a] * s.radii[i]);
    }
  return gap;
}

TEST(RunFeeder, SpawnsWithoutOverlapAndCountsRetriesAndDeferrals) {
  auto model = make_model();
  RigidBody wall;  // a steel slab through the middle of the feed region
  wall.name = "wall";
  wall.shape = geo::Box{Vec3(0.002, 0.02, 0.02)};
  wall.material = kSteel;
  model->bodies.push_back(wall);
  // A crowded region: flakes of 2-3 mm into 1 cm^3, fed much faster than they fit.
  Feed f = make_feed("crowd", box(Vec3(-0.005, -0.005, -0.005), Vec3(0.005, 0.005, 0.005)),
                     {component(kFr4, 0.5, 1e-3, 1.5e-3, 1), component(kCopper, 0.5, 1e-3, 1e-3)});
  f.count_rate = 20000;
  f.max_attempts = 10;
  World world(model);
  world.add_feed(f, 7);
  // Every particle added this step keeps clear of bodies and of all others.
  struct Clearances : StepObserver {
    const Model& model;
    std::size_t checked = 0;
    explicit Clearances(const Model& m) : model(m) {}
    void after(Stage stage, const World& w) override {
      if (stage != Stage::Feed) return;
      const Particles& p = w.particles();
      for (std::size_t a = checked; a < p.size(); ++a) {
        EXPECT_GE(body_clearance(model, w, p, a), 0.0) << "particle " << p.id[a];
        for (std::size_t b = 0; b < a; ++b)
          EXPECT_GE(clearance(model, p, a, b), 0.0) << p.id[a] << " vs " << p.id[b];
      }
      checked = p.size();
    }
  } clearances(*model);
  for (int i = 0; i < 10; ++i) world.step(&clearances);
  EXPECT_GT(world.particles().size(), 20u);
  const feed::FeedStats& stats = world.feeders()[0].stats();
  EXPECT_GT(stats.retries, 0u);
  EXPECT_GT(stats.deferrals, 0u);
}

// (position, scale, material) of every particle left of x = 0.
std::multiset<std::tuple<double, double, double, double, int>> left_particles(const World& w) {
  std::multiset<std::tuple<double, double, double, double, int>> out;
  const Particles& p = w.particles();
  for (std::size_t i = 0; i < p.size(); ++i)
    if (p.position[i].x() < 0)
      out.insert(
          {p.position[i].x(), p.position[i].y(), p.position[i].z(), p.scale[i], p.material[i]});
  return out;
}

TEST(RunFeeder, AddingAFeedLeavesAnotherFeedsParticlesUnchanged) {
  const Feed left =
      make_feed("left", box(Vec3(-0.2, -0.05, -0.05), Vec3(-0.1, 0.05, 0.05)),
                {component(kCopper, 0.4, 0.5e-3, 1e-3), component(kFr4, 0.6, 0.5e-3, 2e-3)});
  Feed right = left;
  right.name = "right";
  right.region = box(Vec3(0.1, -0.05, -0.05), Vec3(0.2, 0.05, 0.05));
  Feed l = left, r = right;
  l.mass_rate = r.mass_rate = 3e-3;
  World alone(make_model()), both(make_model());
  std::multiset<std::tuple<double, double, double, double, int>> a, b;
  run_feeders(make_model(), {l}, 30, [&](const World& w, const auto&) { a = left_particles(w); });
  run_feeders(make_model(), {r, l}, 30,
              [&](const World& w, const auto&) { b = left_particles(w); });
  EXPECT_GT(a.size(), 10u);
  EXPECT_EQ(a, b);
  // Streams differ by feed name and by scene seed.
  EXPECT_NE(feed::stream_seed(1, "left"), feed::stream_seed(1, "right"));
  EXPECT_NE(feed::stream_seed(1, "left"), feed::stream_seed(2, "left"));
  EXPECT_EQ(feed::stream_seed(1, "left"), feed::stream_seed(1, "left"));
}

// A placement retry (here: a slab through the feed region, which the
// particles drawn inside it must avoid) draws more numbers, but only from
// the particle's own stream: the particles after it are the same as
// without the slab, and those placed at their first attempt are placed
// where they were. Runs of one scene at other settings therefore feed the
// same particles.
TEST(RunFeeder, ARetryLeavesTheParticlesAfterItUnchanged) {
  const Feed f = [] {
    Feed f = make_feed("f", box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.05)),
                       {component(kCopper, 0.4, 0.5e-3, 1e-3), component(kFr4, 0.6, 0.5e-3, 2e-3)});
    f.count_rate = 10000;
    return f;
  }();
  auto fed = [&](bool slab) {
    auto model = make_model();
    if (slab) {
      RigidBody wall;
      wall.name = "wall";
      wall.shape = geo::Box{Vec3(0.02, 0.06, 0.06)};
      wall.material = kSteel;
      model->bodies.push_back(wall);
    }
    World world(model);
    world.add_feed(f, 3);
    for (int i = 0; i < 10; ++i) world.step();
    EXPECT_EQ(world.feeders()[0].stats().retries > 0, slab);
    return world.particles();
  };
  const Particles plain = fed(false), dodged = fed(true);
  ASSERT_EQ(plain.size(), dodged.size());
  ASSERT_GT(plain.size(), 20u);
  std::size_t same_place = 0;
  for (std::size_t i = 0; i < plain.size(); ++i) {
    EXPECT_EQ(plain.scale[i], dodged.scale[i]) << "particle " << i;
    EXPECT_EQ(plain.material[i], dodged.material[i]) << "particle " << i;
    same_place += plain.position[i] == dodged.position[i];
  }
  // The slab takes two fifths of the region's width: most first attempts
  // miss it.
  EXPECT_GT(same_place, plain.size() / 3);
  EXPECT_LT(same_place, plain.size());
}

// A simulation with one collector plane y = 0 (normal +y), ten 1 cm bins on
// [0, 0.1) along x and two products, and a domain box.
Simulation collector_sim() {
  Simulation sim;
  sim.name = "collector";
  sim.model = make_model();
  Collector c;
  c.name = "tray";
  c.point = Vec3::Zero();
  c.normal = Vec3::UnitY();
  c.axis = Vec3::UnitX();
  c.from = 0.0;
  c.to = 0.1;
  c.bins = 10;
  c.products = {{"near", 0.0, 0.05}, {"far", 0.05, 0.1}};
  sim.collectors.push_back(c);
  sim.domain = box(Vec3(-0.5, -0.5, -0.5), Vec3(0.5, 0.5, 0.5));
  sim.feeds.push_back(
      make_feed("f", box(Vec3::Zero(), Vec3::Zero()),
                {component(kCopper, 0.5, 1e-3, 1e-3), component(kFr4, 0.5, 1e-3, 1e-3)}));
  return sim;
}

TEST(RunCollection, BinsProductsCrossingsAndLosses) {
  const Simulation sim = collector_sim();
  World world(sim.model);
  world.set_collection(sim.collectors, sim.domain, shape_sizes(sim));
  const collect::Collection& collection = *world.collection();
  const Vec3 down(0, -1, 0);
  // Falling at 1 m/s from y = 0.1005: they cross y = 0 at t = 0.1005 s, mid-step.
  for (double x : {0.005, 0.0125, 0.0175, 0.055, 0.095})
    world.add_particle(0, 1e-3, kCopper, Vec3(x, 0.1005, 0), Quat::Identity(), down);
  world.add_particle(0, 1e-3, kFr4, Vec3(0.045, 0.1005, 0), Quat::Identity(), down);
  world.add_particle(0, 1e-3, kFr4, Vec3(0.2, 0.1005, 0), Quat::Identity(), down);  // outside bins
  world.add_particle(0, 1e-3, kFr4, Vec3(0.02, -0.1, 0), Quat::Identity(),
                     -down);  // from below: not collected
  world.add_particle(0, 1e-3, kCopper, Vec3(0.45, 0.3, 0), Quat::Identity(),
                     Vec3(1, 0, 0));  // leaves the domain
  world.add_particle(0, 1e-3, kCopper, Vec3(0.3, 0.3, 0), Quat::Identity(),
                     Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0));
  // The collection keeps only the last step's records; a run's observer
  // writes each step's away (output::CollectedLog).
  std::vector<collect::Crossing> crossings;
  std::vector<collect::Loss> losses;
  for (int i = 0; i < 150; ++i) {
    world.step();
    crossings.insert(crossings.end(), collection.crossings().begin(), collection.crossings().end());
    losses.insert(losses.end(), collection.losses().begin(), collection.losses().end());
  }

  EXPECT_TRUE(collection.crossings().empty());  // none in the last step: not kept since
  ASSERT_EQ(crossings.size(), 7u);
  for (const collect::Crossing& c : crossings) {
    EXPECT_NEAR(c.time, 0.1005, 1e-12);
    EXPECT_NEAR(c.position.y(), 0.0, 1e-12);
    EXPECT_NEAR(c.diameter, 1e-3, 1e-15);
  }
  const collect::CollectorTallies& t = collection.collectors()[0];
  const std::size_t nm = collection.material_count();
  EXPECT_EQ(t.bins[0 * nm + kCopper].count, 1u);
  EXPECT_EQ(t.bins[1 * nm + kCopper].count, 2u);
  EXPECT_EQ(t.bins[5 * nm + kCopper].count, 1u);
  EXPECT_EQ(t.bins[9 * nm + kCopper].count, 1u);
  EXPECT_EQ(t.bins[4 * nm + kFr4].count, 1u);
  EXPECT_EQ(t.outside[kFr4].count, 1u);
  EXPECT_EQ(t.products[0 * nm + kCopper].count, 3u);
  EXPECT_EQ(t.products[1 * nm + kCopper].count, 2u);
  EXPECT_EQ(t.products[0 * nm + kFr4].count, 1u);
  EXPECT_EQ(t.total[kCopper].mass, 5 * to_mass_units(sphere_mass(8960, 1e-3) * 1.0));
  // Crossings sorted by (time, id): equal times, so by id.
  for (std::size_t k = 1; k < crossings.size(); ++k)
    EXPECT_LT(crossings[k - 1].id, crossings[k].id);

  ASSERT_EQ(losses.size(), 2u);
  EXPECT_EQ(collection.lost(collect::LossReason::LeftDomain)[kCopper].count, 1u);
  EXPECT_EQ(collection.lost(collect::LossReason::NonFinite)[kCopper].count, 1u);
  EXPECT_EQ(world.particles().size(), 1u);  // the one rising from below
  // The squared masses behind the products' standard errors: three copper
  // particles in the near product; seven settled, two of them lost.
  const double copper = sphere_mass(8960, 1e-3);
  EXPECT_NEAR(t.product_squares[0 * nm + kCopper], 3 * copper * copper, 1e-12 * copper * copper);
  EXPECT_NEAR(collection.settled_squares(kCopper), 7 * copper * copper, 1e-12 * copper * copper);
}

// Equal masses: the standard error of a share is the binomial's, with the
// sample variance's n - 1; none where the sample shows no spread.
TEST(RunProducts, StandardErrorOfEqualMassesIsTheBinomial) {
  const double m = 2e-6;
  const std::uint64_t n = 40, k = 10;
  const double se = output::ratio_standard_error(k * m, n * m, k * m * m, n * m * m, n);
  EXPECT_NEAR(se, std::sqrt(0.25 * 0.75 / 39.0), 1e-12);
  EXPECT_EQ(output::ratio_standard_error(n * m, n * m, n * m * m, n * m * m, n), 0.0);  // all
  EXPECT_EQ(output::ratio_standard_error(0.0, n * m, 0.0, n * m * m, n), 0.0);          // none
  EXPECT_EQ(output::ratio_standard_error(m, m, m * m, m * m, 1), 0.0);  // one particle
  EXPECT_EQ(output::ratio_standard_error(0.0, 0.0, 0.0, 0.0, 0), 0.0);  // no particle
}

// The standard error a single sample gives matches the spread of the share
// over many samples: 4000 feeds of 400 particles, masses lognormal (sigma
// 0.8, as the measured PCB particles' spread), each in the part with a
// probability that grows with its mass (0.5 to 0.9), so that mass and
// fate go together as on the drum. Tolerance 5 %: the spread over 4000
// samples is itself known to about 1.1 %, the mean of the errors to less.
TEST(RunProducts, StandardErrorMatchesTheSpreadOverFeeds) {
  std::mt19937_64 rng(12345);
  std::lognormal_distribution<double> mass(std::log(1e-6), 0.8);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  constexpr int kFeeds = 4000, kParticles = 400;
  double sum = 0.0, sum2 = 0.0, se2 = 0.0;
  for (int f = 0; f < kFeeds; ++f) {
    double part = 0.0, whole = 0.0, q_part = 0.0, q_whole = 0.0;
    for (int i = 0; i < kParticles; ++i) {
      const double m = mass(rng);
      const double p = 0.5 + 0.4 * std::min(1.0, m / 3e-6);
      whole += m;
      q_whole += m * m;
      if (u(rng) < p) {
        part += m;
        q_part += m * m;
      }
    }
    const double r = part / whole;
    sum += r;
    sum2 += r * r;
    const double se = output::ratio_standard_error(part, whole, q_part, q_whole, kParticles);
    se2 += se * se;
  }
  const double mean = sum / kFeeds;
  const double spread = std::sqrt((sum2 / kFeeds - mean * mean) * kFeeds / (kFeeds - 1.0));
  const double predicted = std::sqrt(se2 / kFeeds);
  EXPECT_NEAR(predicted / spread, 1.0, 0.05) << predicted << " vs " << spread;
}

nlohmann::json read_json(const fs::path& p) { return nlohmann::json::parse(read_text(p)); }

// A small run: gravity, a feed above a collector, a domain that loses the
// particles thrown sideways, an end time that leaves some in flight.
Simulation small_run(const fs::path& dir) {
  Simulation sim = collector_sim();
  sim.model = make_model(Vec3(0, -9.81, 0));
  sim.seed = 3;
  sim.end_time = 0.15;
  sim.output.dir = dir.string();
  sim.output.trajectories.every = 0.05;
  sim.output.trajectories.csv = true;
  sim.domain =
      box(Vec3(-0.5, -0.5, -0.5), Vec3(0.08, 0.5, 0.5));  // particles past x = 0.08 are lost
  Feed& f = sim.feeds[0];
  f.region = box(Vec3(0.0, 0.05, -0.01), Vec3(0.1, 0.06, 0.01));
  f.mass_rate = 1e-3;
  f.velocity = Vec3(0, -0.5, 0);
  f.velocity_spread = 0.1;
  sim.resolved_yaml = "name: small\n";
  return sim;
}

TEST(RunBalance, FedEqualsCollectedPlusLostPlusActiveExactly) {
  const fs::path dir = fresh_dir("balance");
  const RunResult r = run(small_run(dir), {.out_dir = "", .progress = false, .quiet = true});
  ASSERT_TRUE(r.complete) << r.reason;
  const nlohmann::json s = read_json(dir / "summary.json");
  const nlohmann::json& b = s["balance"];
  EXPECT_TRUE(b["exact"].get<bool>());
  const auto count = [&](const char* k) { return b[k]["count"].get<std::uint64_t>(); };
  EXPECT_GT(count("collected"), 0u);
  EXPECT_GT(count("lost"), 0u);
  EXPECT_GT(count("active"), 0u);
  EXPECT_EQ(count("fed"), count("collected") + count("lost") + count("active"));
  for (const char* m : {"copper", "fr4"}) {
    const nlohmann::json& mb = b["materials"][m];
    EXPECT_EQ(mb["fed"]["count"].get<std::uint64_t>(),
              mb["collected"]["count"].get<std::uint64_t>() +
                  mb["lost"]["count"].get<std::uint64_t>() +
                  mb["active"]["count"].get<std::uint64_t>());
  }
  EXPECT_EQ(b["lost_by_reason"]["left domain"]["count"].get<std::uint64_t>(), count("lost"));
  EXPECT_TRUE(s["complete"].get<bool>());
  EXPECT_EQ(s["steps"].get<int>(), 150);
  EXPECT_EQ(s["seed"].get<int>(), 3);
}

// summary.json's peak memory is this process's peak resident set while it
// ran: no less than what the process held before the run, no more than
// its peak after it.
TEST(RunSummary, PeakMemoryIsTheProcessPeakDuringTheRun) {
  const fs::path dir = fresh_dir("peak_memory");
  const double before = resident_bytes();
  const RunResult r = run(small_run(dir), {.out_dir = "", .progress = false, .quiet = true});
  const double after = peak_resident_bytes();
  ASSERT_TRUE(r.complete) << r.reason;
  ASSERT_GT(before, 0.0);  // Linux: /proc/self/status says
  const double peak = read_json(dir / "summary.json")["peak_memory_mib"].get<double>() * (1 << 20);
  EXPECT_GE(peak, before);
  EXPECT_LE(peak, after);

  // Each step's resident memory lies within the same bounds: not below the
  // process's before the run (less the 0.1 MiB it is rounded to), not above
  // the run's peak.
  const output::Table steps = output::read_table(dir / "steps.csv");
  const std::size_t c = steps.column("resident_mib", dir / "steps.csv");
  ASSERT_FALSE(steps.rows.empty());
  for (const auto& row : steps.rows) {
    const double resident = std::stod(row[c]) * (1 << 20);
    EXPECT_GE(resident, before - 0.05 * (1 << 20)) << row[0];
    EXPECT_LE(resident, peak + 0.05 * (1 << 20)) << row[0];
  }
}

// A particle's mass in the exact tally: as llround gives it below 9.2 kg,
// and past that (where llround wraps) still the mass, to a double's
// precision.
TEST(RunBalance, TheTallyHoldsEveryMassAFeedMayMake) {
  for (const double kg : {1e-18, 3.7e-9, 4.02929489e-05, 9.0})
    EXPECT_EQ(to_mass_units(kg), MassUnits(std::llround(kg / kMassUnit))) << kg;
  for (const double kg : {22.0893233, 1e3, kMaxParticleMass}) {
    EXPECT_NEAR(to_kg(to_mass_units(kg)), kg, 1e-15 * kg) << kg;
    Tally t;
    for (int k = 0; k < 10'000'000; k += 1'000'000) t.add(to_mass_units(kg));
    EXPECT_NEAR(t.kg(), 10 * kg, 1e-15 * 10 * kg) << kg;
  }
  EXPECT_FALSE(tally_holds(0.5e-18));
  EXPECT_FALSE(tally_holds(2e9));
  EXPECT_FALSE(tally_holds(std::numeric_limits<double>::quiet_NaN()));
}

TEST(RunOutputs, WritesEveryFileAtomicallyWithNoTemporariesLeft) {
  const fs::path dir = fresh_dir("files");
  ASSERT_TRUE(run(small_run(dir), {.out_dir = "", .progress = false, .quiet = true}).complete);
  for (const char* name : {"summary.json", "bins.csv", "products.csv", "crossings.csv", "lost.csv",
                           "steps.csv", "scene.resolved.yaml", "distribution.svg",
                           "trajectories.pvd", "trajectories.csv", "trajectories/frame_000003.vtp"})
    EXPECT_TRUE(fs::exists(dir / name)) << name;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    EXPECT_NE(e.path().extension(), ".tmp") << e.path();
  EXPECT_EQ(read_text(dir / "scene.resolved.yaml"), "name: small\n");
  // 150 steps + header.
  const std::string steps = read_text(dir / "steps.csv");
  EXPECT_EQ(std::count(steps.begin(), steps.end(), '\n'), 151);

  // An uncommitted file leaves nothing; a committed one replaces the old bytes.
  const fs::path p = dir / "atomic.txt";
  {
    output::AtomicFile f(p);
    f.write("half");
  }
  EXPECT_FALSE(fs::exists(p));
  EXPECT_FALSE(fs::exists(dir / "atomic.txt.tmp"));
  output::write_file_atomic(p, "old");
  output::write_file_atomic(p, "new");
  EXPECT_EQ(read_text(p), "new");
  EXPECT_THROW(output::write_file_atomic(dir / "no_such_dir" / "x", "x"), output::IoError);
}

TEST(RunOutputs, SameSeedGivesIdenticalTables) {
  const fs::path a = fresh_dir("same_a"), b = fresh_dir("same_b");
  ASSERT_TRUE(run(small_run(a), {.out_dir = "", .progress = false, .quiet = true}).complete);
  ASSERT_TRUE(run(small_run(b), {.out_dir = "", .progress = false, .quiet = true}).complete);
  for (const char* name : {"bins.csv", "products.csv", "crossings.csv", "lost.csv",
                           "trajectories.csv", "trajectories/frame_000002.vtp"})
    EXPECT_EQ(read_text(a / name), read_text(b / name)) << name;
  EXPECT_TRUE(output::compare_outputs(a, b, {}).agree());
}

TEST(RunOutputs, ErrorMidRunKeepsOutputsAsideAndSaysIncomplete) {
  const fs::path dir = fresh_dir("error"), partial = dir / "partial";
  Simulation sim = small_run(dir);
  // A second feed that starts at 50 ms and makes impossible particles: its
  // hook throws mid-run.
  Feed broken = sim.feeds[0];
  broken.name = "broken";
  broken.start = 0.05;
  broken.mix[0].shape_size = 0.0;
  broken.mix[1].shape_size = 0.0;
  sim.feeds.push_back(broken);
  const RunResult r = run(sim, {.out_dir = "", .progress = false, .quiet = true});
  EXPECT_FALSE(r.complete);
  EXPECT_NE(r.reason.find("broken"), std::string::npos) << r.reason;
  EXPECT_EQ(r.out_dir, partial.string());
  const nlohmann::json s = read_json(partial / "summary.json");
  EXPECT_FALSE(s["complete"].get<bool>());
  EXPECT_EQ(s["reason"].get<std::string>(), r.reason);
  // Its first particle is drawn by the step from 49 to 50 ms, which fails.
  EXPECT_EQ(s["steps"].get<int>(), 49);
  EXPECT_TRUE(s["balance"]["exact"].get<bool>());
  for (const char* name : {"bins.csv", "products.csv", "crossings.csv", "steps.csv"})
    EXPECT_TRUE(fs::exists(partial / name)) << name;
  EXPECT_FALSE(fs::exists(dir / "summary.json"));
}

TEST(RunOutputs, SignalStopsTheRunBetweenStepsAndSaysIncomplete) {
  const fs::path dir = fresh_dir("signal"), partial = dir / "partial";
  Simulation sim = small_run(dir);
  sim.end_time = 1e4;  // would run for a very long time
  // SIGTERM arrives during step 5's watch, as from another process: the
  // handler only marks it, and the run stops before step 6.
  RunOptions options{.out_dir = "", .progress = false, .quiet = true};
  options.on_progress_every = 0.0;
  options.on_progress = [](const RunProgress& p) {
    if (p.steps == 5) std::raise(SIGTERM);
    return false;
  };
  const RunResult r = run(sim, options);
  EXPECT_FALSE(r.complete);
  EXPECT_EQ(r.reason, "interrupted by SIGTERM");
  EXPECT_EQ(r.signal, SIGTERM);
  const nlohmann::json s = read_json(partial / "summary.json");
  EXPECT_FALSE(s["complete"].get<bool>());
  EXPECT_EQ(s["reason"].get<std::string>(), "interrupted by SIGTERM");
  EXPECT_EQ(s["steps"].get<int>(), 5);
  EXPECT_TRUE(fs::exists(partial / "bins.csv"));
}

// A watch due after every step sees each step once, in order; the one that
// asks to stop ends the run there, incomplete, and the summary says so.
TEST(RunOutputs, CallerWatchesEveryStepAndStopsTheRun) {
  const fs::path dir = fresh_dir("watch"), partial = dir / "partial";
  std::vector<RunProgress> seen;
  RunOptions options{.out_dir = "", .progress = false, .quiet = true};
  options.on_progress_every = 0.0;
  options.on_progress = [&](const RunProgress& p) {
    seen.push_back(p);
    return p.steps == 40;
  };
  const RunResult r = run(small_run(dir), options);
  EXPECT_FALSE(r.complete);
  EXPECT_EQ(r.reason, "stopped by the caller");
  EXPECT_EQ(r.signal, 0);
  ASSERT_EQ(seen.size(), 40u);
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].steps, k + 1);
    EXPECT_DOUBLE_EQ(seen[k].end_time, 0.15);
    EXPECT_NEAR(seen[k].time, 0.001 * double(k + 1), 1e-12);
  }
  EXPECT_GT(seen.back().particles, 0u);
  EXPECT_FALSE(fs::exists(dir / "bins.csv"));
  EXPECT_TRUE(fs::exists(partial / "bins.csv"));
  const nlohmann::json s = read_json(partial / "summary.json");
  EXPECT_EQ(s["reason"].get<std::string>(), "stopped by the caller");
  EXPECT_EQ(s["steps"].get<int>(), 40);
}

// Due once a second of wall time, the watch still sees the last step.
TEST(RunOutputs, CallerWatchSeesTheLastStep) {
  const fs::path dir = fresh_dir("watch_end");
  std::vector<std::uint64_t> steps;
  RunOptions options{.out_dir = "", .progress = false, .quiet = true};
  options.on_progress_every = 1e9;
  options.on_progress = [&](const RunProgress& p) {
    steps.push_back(p.steps);
    return true;  // too late to stop anything
  };
  const RunResult r = run(small_run(dir), options);
  EXPECT_TRUE(r.complete) << r.reason;
  EXPECT_EQ(steps, std::vector<std::uint64_t>{150});
}

// With until: collected the run ends before time.end: the caller's last
// call comes at the step that ends it and says the run ends there (a
// progress bar reaches its end), and returning true then stops nothing.
TEST(RunOutputs, CallerWatchSeesTheRunEndWhenCollected) {
  const fs::path dir = fresh_dir("watch_collected");
  Simulation sim = small_run(dir);
  sim.end_time = 1.0;
  sim.until_collected = true;
  sim.feeds[0].duration = 0.02;
  std::vector<RunProgress> seen;
  RunOptions options{.out_dir = "", .progress = false, .quiet = true};
  options.on_progress_every = 1e9;
  options.on_progress = [&](const RunProgress& p) {
    seen.push_back(p);
    return true;
  };
  const RunResult r = run(sim, options);
  EXPECT_TRUE(r.complete) << r.reason;
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_LT(seen[0].time, 0.5);
  EXPECT_EQ(seen[0].end_time, seen[0].time);
}

// The caller's thread count wins over the scene's, as --threads does.
TEST(RunOutputs, CallerFixesTheThreadCount) {
  const fs::path dir = fresh_dir("threads");
  Simulation sim = small_run(dir);
  sim.model->threads = 1;
  RunOptions options{.out_dir = "", .progress = false, .quiet = true};
  options.threads = 2;
  ASSERT_TRUE(run(sim, options).complete);
  const nlohmann::json s = read_json(dir / "summary.json");
  EXPECT_EQ(s["threads"].get<int>(), 2);
  EXPECT_EQ(s["threads_chosen"]["by"].get<std::string>(), "fixed");
}

TEST(RunCompare, WassersteinOfShiftedSamplesIsTheShift) {
  EXPECT_DOUBLE_EQ(output::wasserstein1({{0.0, 1.0}}, {{0.002, 5.0}}), 0.002);
  EXPECT_NEAR(output::wasserstein1({{0, 1}, {1, 1}}, {{0.5, 1}, {1.5, 1}}), 0.5, 1e-15);
  EXPECT_NEAR(output::wasserstein1({{0, 1}, {1, 3}}, {{0, 1}, {1, 3}}), 0.0, 0.0);
  // Mass-weighted: moving a quarter of the mass by 1 costs 0.25.
  EXPECT_NEAR(output::wasserstein1({{0, 3}, {1, 1}}, {{0, 1}}), 0.25, 1e-15);
}

TEST(RunCompare, FlagsChangedCellsBeyondTolerance) {
  const fs::path a = fresh_dir("cmp_a"), b = fresh_dir("cmp_b");
  ASSERT_TRUE(run(small_run(a), {.out_dir = "", .progress = false, .quiet = true}).complete);
  Simulation other = small_run(b);
  other.seed = 4;
  ASSERT_TRUE(run(other, {.out_dir = "", .progress = false, .quiet = true}).complete);
  const output::CompareResult strict = output::compare_outputs(a, b, {});
  EXPECT_FALSE(strict.agree());
  const output::CompareResult loose = output::compare_outputs(a, b, {1000, 1.0, 1000.0});
  EXPECT_TRUE(loose.agree()) << loose.differences.front();
  EXPECT_THROW(output::compare_outputs(a, a / "missing", {}), output::IoError);
}

// Two output folders whose tables are written here: `b` moves 1 mg of
// copper from bin 0 to bin 1 (a quarter of the collector's 4 mg of copper)
// and two FR-4 particles between the bins, and changes a grade by 0.03.
void write_tidy_folders(const fs::path& a, const fs::path& b) {
  const std::string crossings =
      "id,time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,along_m,diameter_m,mass_kg,material,charge_c,"
      "collector,bin,product\n"
      "0,0.1,0,0,0,0,-1,0,0.005,0.001,0.001,copper,0,tray,0,near\n";
  const char* bins_a =
      "collector,bin,from_m,to_m,material,count,mass_kg\n"
      "tray,0,0,0.01,copper,3,0.003\n"
      "tray,0,0,0.01,fr4,10,0.001\n"
      "tray,1,0.01,0.02,copper,1,0.001\n"
      "tray,1,0.01,0.02,fr4,10,0.001\n";
  const char* bins_b =
      "collector,bin,from_m,to_m,material,count,mass_kg\n"
      "tray,0,0,0.01,copper,3,0.002\n"
      "tray,0,0,0.01,fr4,8,0.001\n"
      "tray,1,0.01,0.02,copper,1,0.002\n"
      "tray,1,0.01,0.02,fr4,12,0.001\n";
  const char* products_a =
      "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery,grade_se,recovery_se\n"
      "tray,near,0,0.02,copper,4,0.004,0.5,1,0.1,0\n"
      "tray,near,0,0.02,fr4,20,0.004,0.5,1,0.1,0\n";
  const char* products_b =
      "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery,grade_se,recovery_se\n"
      "tray,near,0,0.02,copper,4,0.004,0.53,1,0.1,0\n"
      "tray,near,0,0.02,fr4,20,0.004,0.47,1,0.1,0\n";
  for (const auto& [dir, bins, products] :
       {std::tuple{a, bins_a, products_a}, std::tuple{b, bins_b, products_b}}) {
    output::write_file_atomic(dir / "bins.csv", bins);
    output::write_file_atomic(dir / "products.csv", products);
    output::write_file_atomic(dir / "crossings.csv", crossings);
  }
}

bool mentions(const output::CompareResult& r, const std::string& text) {
  for (const std::string& d : r.differences)
    if (d.find(text) != std::string::npos) return true;
  return false;
}

// The tidy tables: a row is named by its collector, bin or product and
// material; a mass tolerance is a fraction of that material's mass over the
// collector's rows (copper: 4 mg in both bins), not of the whole table's.
TEST(RunCompare, TidyTablesRowByRowWithMassScaledPerMaterial) {
  const fs::path a = fresh_dir("tidy_a"), b = fresh_dir("tidy_b");
  write_tidy_folders(a, b);
  EXPECT_TRUE(output::compare_outputs(a, a, {}).agree());
  const output::CompareResult strict = output::compare_outputs(a, b, {});
  EXPECT_EQ(strict.differences.size(), 6u);  // 2 copper masses, 2 FR-4 counts, 2 grades
  EXPECT_TRUE(mentions(strict, "bins.csv: tray bin 0 copper mass_kg: 0.003 vs 0.002"));
  EXPECT_TRUE(mentions(strict, "bins.csv: tray bin 1 fr4 count: 10 vs 12"));
  EXPECT_TRUE(mentions(strict, "products.csv: tray product near fr4 grade: 0.5 vs 0.47"));
  // 1 mg is 0.25 of the copper (and 0.125 of all the mass): 0.2 is not enough.
  const output::CompareResult masses = output::compare_outputs(a, b, {2, 0.2, 0.0});
  EXPECT_EQ(masses.differences.size(), 2u);
  EXPECT_TRUE(mentions(masses, "copper mass_kg"));
  EXPECT_TRUE(output::compare_outputs(a, b, {2, 0.3, 0.0}).agree());
  EXPECT_FALSE(output::compare_outputs(a, b, {1, 0.3, 0.0}).agree());

  // Rows in another order are other rows.
  output::write_file_atomic(b / "bins.csv",
                            "collector,bin,from_m,to_m,material,count,mass_kg\n"
                            "tray,0,0,0.01,fr4,10,0.001\n"
                            "tray,0,0,0.01,copper,3,0.003\n"
                            "tray,1,0.01,0.02,copper,1,0.001\n"
                            "tray,1,0.01,0.02,fr4,10,0.001\n");
  EXPECT_TRUE(mentions(output::compare_outputs(a, b, {1000, 1.0, 1000.0}),
                       "bins.csv: tray bin 0 copper vs tray bin 0 fr4: rows differ"));
}

}  // namespace
}  // namespace ces
