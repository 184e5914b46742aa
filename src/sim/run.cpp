// The run: a World with the feeds as pre-step hooks and the collectors as a
// post-step hook, stepped to the end time (or until a signal or an error),
// then every output written from what was accumulated.
#include "sim/run.hpp"

#include <omp.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "dynamics/world.hpp"
#include "feed/feeder.hpp"
#include "fields/stages.hpp"
#include "output/collection.hpp"
#include "output/distribution_svg.hpp"
#include "output/energy.hpp"
#include "output/field_picture.hpp"
#include "output/files.hpp"
#include "output/format.hpp"
#include "output/step_log.hpp"
#include "output/summary.hpp"
#include "output/tables.hpp"
#include "output/trajectories.hpp"

namespace ces {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The signal that asked the run to stop; 0 while none did. The loop checks
// it between steps, so a stop never leaves a half-done step behind.
volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void request_stop(int signal) { g_stop_signal = signal; }

// SIGINT and SIGTERM handlers for the lifetime of a run.
class StopSignals {
 public:
  StopSignals() {
    g_stop_signal = 0;
    struct sigaction action = {};
    action.sa_handler = request_stop;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &old_int_);
    sigaction(SIGTERM, &action, &old_term_);
  }
  ~StopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ = {};
  struct sigaction old_term_ = {};
};

// Removes what an earlier run left under the names this run writes, so a
// folder never mixes two runs (a stale summary.json saying complete, say).
void clear_previous_outputs(const fs::path& dir) {
  for (const char* name : {"summary.json", "bins.csv", "products.csv", "crossings.csv", "lost.csv",
                           "steps.csv", "scene.resolved.yaml", "distribution.svg", "field.csv",
                           "field.svg", "trajectories.pvd", "trajectories.csv"}) {
    fs::remove(dir / name);
    fs::remove(dir / (std::string(name) + ".tmp"));
  }
  if (!fs::is_directory(dir / "trajectories")) return;
  for (const fs::directory_entry& e : fs::directory_iterator(dir / "trajectories"))
    if (e.path().extension() == ".vtp" && e.path().stem().string().starts_with("frame_"))
      fs::remove(e.path());
}

fs::path prepare_output_dir(const Simulation& sim, const RunOptions& options) {
  const fs::path dir = options.out_dir.empty() ? sim.output.dir : options.out_dir;
  try {
    fs::create_directories(dir);
    clear_previous_outputs(dir);
  } catch (const fs::filesystem_error& e) {
    throw output::IoError("cannot prepare the output folder " + dir.string() + ": " +
                          e.code().message());
  }
  return dir;
}

// One progress line on stderr, redrawn at most five times a second.
class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled) {}
  ~Progress() {
    if (drawn_) std::fputs("\r\033[K", stderr);
  }
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  void update(const World& world, double end_time, double wall) {
    if (!enabled_ || wall - last_ < 0.2) return;
    last_ = wall;
    drawn_ = true;
    const double done = world.time() / end_time;
    const double eta = done > 0 ? wall * (1.0 - done) / done : 0.0;
    std::fprintf(
        stderr, "\r\033[Kt %.4g / %.4g s  wall %.1f s  ETA %.0f s  particles %zu  contacts %zu",
        world.time(), end_time, wall, eta, world.particles().size(), world.contacts().size());
    std::fflush(stderr);
  }

 private:
  bool enabled_;
  bool drawn_ = false;
  double last_ = -1.0;
};

class Runner {
 public:
  Runner(const Simulation& sim, const RunOptions& options);
  RunResult run();

 private:
  void add_physics();
  void write_field_picture();
  void step_to_end();
  void observe(const StepStats& s, double wall);
  void write_outputs();
  output::RunRecord record() const;
  void tally_feeds(output::RunRecord& r) const;
  void tally_active(output::RunRecord& r) const;

  const Simulation& sim_;
  RunOptions options_;
  Clock::time_point start_ = Clock::now();
  fs::path dir_;
  World world_;
  std::vector<std::unique_ptr<feed::Feeder>> feeders_;  // hooks point at them
  output::Collection collection_;
  output::StepLog steps_;
  output::TrajectoryWriter trajectories_;
  output::OwnTimes own_;
  output::EnergyLedger energy_;
  bool rayleigh_warned_ = false;
  std::uint64_t steps_done_ = 0;
  bool complete_ = false;
  std::string reason_ = "running";
};

Runner::Runner(const Simulation& sim, const RunOptions& options)
    : sim_(sim),
      options_(options),
      dir_(prepare_output_dir(sim, options)),
      world_(sim.model),
      collection_(sim, output::shape_sizes(sim)),
      steps_(sim.output.steps_csv ? dir_ / "steps.csv" : fs::path(),
             sim.model->solver.max_iterations),
      trajectories_(dir_, sim, output::shape_sizes(sim)),
      energy_(sim, world_) {
  // Hook order matters: the ledger measures after the feeds and on both
  // sides of the collectors (output/energy.hpp).
  for (const Feed& f : sim.feeds) {
    feed::Feeder* feeder =
        feeders_.emplace_back(std::make_unique<feed::Feeder>(f, sim.seed, *sim.model)).get();
    world_.add_pre_step([this, feeder](World& w) {
      const auto t0 = Clock::now();
      (*feeder)(w);
      own_.feed += seconds_since(t0);
    });
  }
  world_.add_pre_step([this](World& w) { energy_.after_feeds(w); });
  world_.add_post_step([this](World& w) {
    energy_.before_collectors(w);
    const auto t0 = Clock::now();
    collection_(w);
    own_.collect += seconds_since(t0);
    energy_.after_collectors(w);
  });
  add_physics();
}

// Only what the scene asked for (DESIGN.md §1): no air, no drag stage; no
// electrostatics section, no field model and no charging pass.
void Runner::add_physics() {
  if (sim_.drag) fields::add_drag_stage(world_, *sim_.drag);
  if (sim_.electrostatics) fields::add_electrostatics_stage(world_, *sim_.electrostatics);
}

// A property of the machine, not of the run: written first, so an
// interrupted run still has it.
void Runner::write_field_picture() {
  if (!sim_.output.field || !sim_.electrostatics) return;
  const auto t0 = Clock::now();
  const output::FieldGrid grid = output::sample_field(sim_);
  output::write_file_atomic(dir_ / "field.csv", output::field_csv(grid));
  output::write_file_atomic(dir_ / "field.svg", output::field_svg(sim_, grid));
  own_.output += seconds_since(t0);
}

RunResult Runner::run() {
  const StopSignals signals;
  if (!sim_.resolved_yaml.empty())
    output::write_file_atomic(dir_ / "scene.resolved.yaml", sim_.resolved_yaml);
  // A summary from the start: a run killed outright still says it did not finish.
  output::write_file_atomic(dir_ / "summary.json", output::summary_json(record()));
  write_field_picture();
  step_to_end();
  write_outputs();
  return {complete_, complete_ ? std::string() : reason_, dir_.string()};
}

void Runner::step_to_end() {
  const auto steps = std::uint64_t(std::llround(sim_.end_time / sim_.model->step));
  Progress progress(options_.progress && !options_.quiet);
  try {
    trajectories_.observe(world_);  // the frame at t = 0
    while (steps_done_ < steps) {
      if (g_stop_signal != 0) {
        reason_ = g_stop_signal == SIGINT ? "interrupted by SIGINT" : "interrupted by SIGTERM";
        return;
      }
      const auto t0 = Clock::now();
      const StepStats& s = world_.step();
      ++steps_done_;
      observe(s, seconds_since(t0));
      progress.update(world_, sim_.end_time, seconds_since(start_));
    }
    complete_ = true;
  } catch (const std::exception& e) {
    reason_ = "error after " + std::to_string(steps_done_) +
              " steps (t = " + output::format_number(world_.time()) + " s): " + e.what();
  }
}

void Runner::observe(const StepStats& s, double wall) {
  if (s.step_above_rayleigh_limit && !rayleigh_warned_) {  // now, not only at the end
    rayleigh_warned_ = true;
    std::fprintf(stderr, "warning: t = %s s: %s\n", output::format_number(s.time).c_str(),
                 output::rayleigh_warning(sim_.model->step, s.rayleigh_time, 0).c_str());
  }
  const auto t0 = Clock::now();
  steps_.record(s, wall);
  trajectories_.observe(world_);
  own_.output += seconds_since(t0);
}

void Runner::write_outputs() {
  const auto t0 = Clock::now();
  collection_.sort_records();
  output::RunRecord r = record();
  output::write_file_atomic(dir_ / "bins.csv", output::bins_csv(sim_, collection_, r.materials));
  output::write_file_atomic(dir_ / "products.csv",
                            output::products_csv(sim_, r.products, r.materials));
  output::write_file_atomic(dir_ / "crossings.csv", output::crossings_csv(sim_, collection_));
  output::write_file_atomic(dir_ / "lost.csv", output::lost_csv(sim_, collection_));
  if (sim_.output.distribution_svg)
    output::write_file_atomic(dir_ / "distribution.svg",
                              output::distribution_svg(sim_, collection_, r.materials));
  steps_.commit();
  trajectories_.commit();
  r.own.output += seconds_since(t0);
  r.wall = seconds_since(start_);
  output::add_warnings(r);
  // Last, so "complete" is only on disk once everything else is.
  output::write_file_atomic(dir_ / "summary.json", output::summary_json(r));
  if (!options_.quiet) output::print_report(r, stdout);
}

output::RunRecord Runner::record() const {
  output::RunRecord r;
  r.sim = &sim_;
  r.collection = &collection_;
  r.out_dir = dir_.string();
  r.complete = complete_;
  r.reason = complete_ ? std::string() : reason_;
  r.steps = steps_done_;
  r.time = world_.time();
  r.threads = sim_.model->threads > 0 ? sim_.model->threads : omp_get_max_threads();
  r.wall = seconds_since(start_);
  r.own = own_;
  r.solver = steps_.summary();
  r.energy = energy_.balance();
  r.frames = trajectories_.frames();
  r.materials = output::fed_materials(sim_);
  r.products = output::product_results(sim_, collection_, r.materials);
  tally_feeds(r);
  tally_active(r);
  return r;
}

void Runner::tally_feeds(output::RunRecord& r) const {
  r.fed.resize(sim_.model->materials.materials().size());
  for (const auto& feeder : feeders_) {
    const feed::FeedStats& s = feeder->stats();
    const Feed& f = feeder->feed();
    for (std::size_t c = 0; c < f.mix.size(); ++c)
      r.fed[std::size_t(f.mix[c].material)] += s.fed[c];
    r.feeds.push_back({f.name, f.mass_rate > 0.0, feeder->target(world_.time()), s.total(),
                       s.retries, s.deferrals});
  }
}

// Particles still in the run: rounded exactly as when they were fed.
void Runner::tally_active(output::RunRecord& r) const {
  r.active.resize(sim_.model->materials.materials().size());
  const Particles& p = world_.particles();
  for (std::size_t i = 0; i < p.size(); ++i)
    r.active[std::size_t(p.material[i])].add(output::to_mass_units(p.mass[i]));
}

}  // namespace

RunResult run(const Simulation& sim, const RunOptions& options) {
  Runner runner(sim, options);
  return runner.run();
}

}  // namespace ces
