// ces_bench: the performance targets measured in one run.
//
//   ces_bench [--quick] [--out DIR] [--scene SCENE [--scene-set KEY=VALUE]...]
//             [--no-scene] [--ces-sim PATH]
//   ces_bench --bed SPHERES THREADS     one bed only (A/B of a solver change)
//
// - solver contact-iterations per second per core against contact count
//   (packed beds of ~1e3 to ~1e6 contacts) and the time per step by stage;
// - the 1-to-2-thread speed-up at ~1e5 contacts;
// - cost per particle as the particle count doubles;
// - peak memory per particle and per contact, and 1e6 particles' peak;
// - grid against Bullet broadphase;
// - with --scene, a scene end to end through ces-sim (wall time, stages).
// Writes DIR/bench.csv (one row per figure) and DIR/report.md (the figures
// against the targets of bench/README.md), and prints the report.
// --quick runs smaller sizes (under a minute) and, unless --scene-set is
// given, the scene to 0.1 s only; its figures are for checking the bench.
// --no-scene cancels an earlier --scene (bench/run passes one).
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <utility>

#include "bench.hpp"

namespace {

using namespace bench;
using Sizes = std::vector<std::size_t>;

struct Options {
  bool quick = false;
  std::string out = "bench/out", scene, ces_sim;
  std::vector<std::string> scene_sets;
};

struct Plan {
  Sizes sweep;                 // ~1e3 to ~1e6 contacts (about 3 per sphere)
  std::size_t speedup = 0;     // ~1e5 contacts
  Sizes growth;                // N, 2N, 4N, ...
  std::size_t memory = 0;      // the per-particle and per-contact probes
  bool million = false;        // measure 1e6 spheres (else extrapolate)
  Sizes broadphase;
  double work = 0;             // contact-iterations per bed measurement, at least
};

constexpr int kIterations = 100;

Plan plan(bool quick) {
  if (quick) return {{340, 1000, 3400, 10000, 34000}, 34000, {8500, 17000, 34000}, 10000, false,
                     {10000}, 1e7};
  return {{340, 1000, 3400, 10000, 34000, 100000, 340000}, 34000, {25000, 50000, 100000, 200000},
          100000, true, {10000, 100000}, 5e7};
}

// Beds measured once per (spheres, threads), shared by the sections.
class Beds {
 public:
  explicit Beds(double work) : work_(work) {}
  const BedRun& get(std::size_t n, int threads) {
    auto it = done_.find({n, threads});
    if (it != done_.end()) return it->second;
    return done_.emplace(std::pair{n, threads}, measure(n, threads)).first->second;
  }
  // One round of the speed-up's pair: 1 and 2 threads back to back, the
  // order turned every other round so neither side always runs second.
  void round(std::size_t n, int index, std::vector<BedRun>& one, std::vector<BedRun>& two) {
    if (index % 2 == 0) one.push_back(measure(n, 1));
    two.push_back(measure(n, 2));
    if (index % 2 == 1) one.push_back(measure(n, 1));
  }
  // What a later get() returns for (n, threads).
  void keep(std::size_t n, int threads, const BedRun& b) {
    done_.insert_or_assign(std::pair{n, threads}, b);
  }

 private:
  BedRun measure(std::size_t n, int threads) const {
    std::fprintf(stderr, "bed of %zu spheres, %d thread(s) ... ", n, threads);
    const BedRun b = measure_bed(n, threads, kIterations, work_);
    const ces::StageTimes& t = b.stages;
    std::fprintf(stderr,
                 "%zu contacts, %d steps of %.3g s, %.1f M contact-it/s/core (ms: broad %.3g, "
                 "narrow %.3g, assemble %.3g, solve %.3g, safeguards %.3g, integrate %.3g)\n",
                 b.contacts, b.steps, b.wall, b.rate_per_core() / 1e6, 1e3 * t[ces::Stage::Broadphase],
                 1e3 * t[ces::Stage::Narrowphase], 1e3 * t[ces::Stage::Assemble], 1e3 * t[ces::Stage::Solve],
                 1e3 * t[ces::Stage::Safeguards], 1e3 * t[ces::Stage::Integrate]);
    return b;
  }
  double work_;
  std::map<std::pair<std::size_t, int>, BedRun> done_;
};

BedRun median(std::vector<BedRun> runs) {
  std::sort(runs.begin(), runs.end(),
            [](const BedRun& a, const BedRun& b) { return a.wall < b.wall; });
  return runs[runs.size() / 2];
}

// The speed-up's rounds are spread over the whole bench, one between each of
// its sections: a VM's second core can run short for a minute, so rounds
// taken together sample one phase, and rounds spread out sample the machine.
constexpr int kSpeedupRounds = 5;

class Speedup {
 public:
  Speedup(Beds& beds, const Plan& p, Results& r) : beds_(beds), n_(p.speedup), r_(r) {}
  void round() {
    if (r_.machine.procs < 2 || taken_ == kSpeedupRounds) return;
    beds_.round(n_, taken_++, r_.rounds_one, r_.rounds_two);
    beds_.keep(n_, 1, median(r_.rounds_one));  // the sweep's point, until finish()
  }
  // The rest of the rounds, then each side's median (by wall time) stands for
  // the bed, in the sweep too.
  void finish() {
    while (r_.machine.procs > 1 && taken_ < kSpeedupRounds) round();
    if (r_.rounds_one.empty()) {
      r_.one = beds_.get(n_, 1);
      return;
    }
    r_.one = median(r_.rounds_one);
    r_.two = median(r_.rounds_two);
    for (auto* beds : {&r_.sweep, &r_.growth})
      for (BedRun& b : *beds)
        if (b.particles == n_) b = r_.one;
  }

 private:
  Beds& beds_;
  std::size_t n_;
  Results& r_;
  int taken_ = 0;
};

void measure_sweep(const Plan& p, Beds& beds, Results& r) {
  for (std::size_t n : p.sweep) r.sweep.push_back(beds.get(n, 1));
}

void measure_growth(const Plan& p, Beds& beds, Results& r) {
  for (std::size_t n : p.growth) r.growth.push_back(beds.get(n, 1));
}

// Base + N per particle + contacts per contact, contacts per particle as packed.
MemoryProbe extrapolate_million(const MemoryProbe& sparse, const MemoryProbe& packed) {
  MemoryProbe m;
  m.particles = 1000000;
  m.contacts = std::size_t(double(packed.contacts) / packed.particles * m.particles);
  const double per_particle = sparse.growth() / sparse.particles;
  const double per_contact = (packed.growth() - sparse.growth()) / packed.contacts;
  m.base = sparse.base;
  m.peak = m.base + per_particle * m.particles + per_contact * m.contacts;
  m.ok = sparse.ok && packed.ok;
  return m;
}

void measure_memory(const Plan& p, Results& r) {
  const std::string exe = self_exe();
  const int threads = r.machine.procs;
  std::fprintf(stderr, "memory probes: %zu spheres apart and packed%s\n", p.memory,
               p.million ? ", 1e6 packed" : "");
  r.sparse = probe_memory(exe, p.memory, false, threads);
  r.packed = probe_memory(exe, p.memory, true, threads);
  r.million_measured = p.million;
  r.million = p.million ? probe_memory(exe, 1000000, true, threads)
                        : extrapolate_million(r.sparse, r.packed);
}

void measure_scene(const Options& o, Results& r) {
  std::vector<std::string> sets = o.scene_sets;
  // The scene runs until its particles are collected, with time.end as a
  // cap it fails at: a shortened run ends at time.end instead.
  if (o.quick && sets.empty()) sets = {"time.end=0.1s", "time.until=end"};
  std::string ces_sim = o.ces_sim;
  if (ces_sim.empty())  // build/bench/ces_bench -> build/ces-sim
    ces_sim = (std::filesystem::path(self_exe()).parent_path().parent_path() / "ces-sim").string();
  std::fprintf(stderr, "scene %s through %s ...\n", o.scene.c_str(), ces_sim.c_str());
  r.scene = run_scene(ces_sim, o.scene, sets, o.out + "/scene", r.machine.procs);
  if (!r.scene->error.empty()) std::fprintf(stderr, "scene: %s\n", r.scene->error.c_str());
}

int usage() {
  std::fprintf(stderr,
               "usage: ces_bench [--quick] [--out DIR] [--scene SCENE [--scene-set KEY=VALUE]...] "
               "[--no-scene] [--ces-sim PATH]\n       ces_bench --bed SPHERES THREADS\n");
  return 2;
}

bool parse(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--quick") o.quick = true;
    else if (a == "--out" && has_value) o.out = argv[++i];
    else if (a == "--scene" && has_value) o.scene = argv[++i];
    else if (a == "--no-scene") o.scene.clear();
    else if (a == "--scene-set" && has_value) o.scene_sets.push_back(argv[++i]);
    else if (a == "--ces-sim" && has_value) o.ces_sim = argv[++i];
    else return false;
  }
  return true;
}

void write_outputs(const Options& o, Results& r) {
  std::filesystem::create_directories(o.out);
  write_csv(r, o.out + "/bench.csv");
  const std::string text = report(r);
  std::ofstream(o.out + "/report.md") << text;
  std::fputs(text.c_str(), stdout);
  std::printf("\nwrote %s/bench.csv and %s/report.md\n", o.out.c_str(), o.out.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  // Internal: the memory probe runs in a fresh process (memory.cpp).
  if (argc == 5 && std::string(argv[1]) == "--probe-memory")
    return run_memory_probe(std::stoul(argv[2]), std::string(argv[3]) == "packed",
                            std::stoi(argv[4]));
  if (argc == 4 && std::string(argv[1]) == "--bed") {
    Beds(5e7).get(std::stoul(argv[2]), std::stoi(argv[3]));
    return 0;
  }
  Options o;
  if (!parse(argc, argv, o)) return usage();
  const auto t0 = Clock::now();
  Results r;
  r.quick = o.quick;
  r.iterations = kIterations;
  r.machine = read_machine();
  const Plan p = plan(o.quick);
  r.bandwidth_start = measure_bandwidth(r.machine.procs);
  Beds beds(p.work);
  Speedup speedup(beds, p, r);
  speedup.round();
  measure_sweep(p, beds, r);
  speedup.round();
  measure_growth(p, beds, r);
  speedup.round();
  measure_memory(p, r);
  for (std::size_t n : p.broadphase) r.broadphase.push_back(measure_broadphase(n));
  speedup.round();
  if (!o.scene.empty()) measure_scene(o, r);
  speedup.finish();
  r.bandwidth_end = measure_bandwidth(r.machine.procs);
  r.seconds = since(t0);
  const CpuClock end = read_cpu_clock(), &start = r.machine.cpu_start;
  r.machine.others_cores = ((end.all - start.all) - (end.own - start.own)) / r.seconds;
  write_outputs(o, r);
  return 0;
}
