// The run: the World of the compiled scene stepped to the end time (or,
// with time.until: collected, until its feed is accounted for; or until a
// signal or an error), observed by the outputs as it goes, then every
// output written from what was accumulated.
#include "sim/run.hpp"

#include <omp.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "common/clock.hpp"
#include "output/distribution_svg.hpp"
#include "output/energy.hpp"
#include "output/field_picture.hpp"
#include "output/files.hpp"
#include "output/format.hpp"
#include "output/step_log.hpp"
#include "output/summary.hpp"
#include "output/tables.hpp"
#include "output/trajectories.hpp"
#include "sim/stop.hpp"
#include "sim/world.hpp"

namespace ces {
namespace {

namespace fs = std::filesystem;

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

// The outputs that watch the run as it goes; they only read the world.
class Observers : public StepObserver {
 public:
  Observers(const Simulation& sim, const fs::path& dir, const World& world)
      : sim_(sim),
        steps_(sim.output.steps_csv ? dir / "steps.csv" : fs::path(),
               sim.model->solver.max_iterations),
        trajectories_(dir, sim, shape_sizes(sim)),
        energy_(sim, world.state()) {}

  void after(Stage stage, const World& world) override { energy_.after(stage, world.state()); }

  void end_of_step(const World& world) override {
    const StepStats& s = world.last_step();
    if (s.step_above_rayleigh_limit && !rayleigh_warned_) {  // now, not only at the end
      rayleigh_warned_ = true;
      std::fprintf(stderr, "warning: t = %s s: %s\n", output::format_number(s.time).c_str(),
                   output::rayleigh_warning(sim_.model->step, s.rayleigh_time, 0).c_str());
    }
    steps_.record(s);
    trajectories_.observe(world.state());
  }

  void start(const World& world) { trajectories_.observe(world.state()); }  // the frame at t = 0
  void commit() {
    steps_.commit();
    trajectories_.commit();
  }
  output::SolverSummary solver() const { return steps_.summary(); }
  const output::EnergyBalance& energy() const { return energy_.balance(); }
  std::size_t frames() const { return trajectories_.frames(); }

 private:
  const Simulation& sim_;
  output::StepLog steps_;
  output::TrajectoryWriter trajectories_;
  output::EnergyLedger energy_;
  bool rayleigh_warned_ = false;
};

class Runner {
 public:
  Runner(const Simulation& sim, const RunOptions& options);
  RunResult run();

 private:
  void write_field_picture();
  void step_to_end();
  void write_outputs();
  output::RunRecord record() const;
  void tally_feeds(output::RunRecord& r) const;
  void tally_active(output::RunRecord& r) const;

  const Simulation& sim_;
  RunOptions options_;
  Clock::time_point start_ = Clock::now();
  fs::path dir_;
  World world_;
  Observers observers_;
  double output_seconds_ = 0.0;  // the output stage's, and the writing before and after the steps
  bool complete_ = false;
  std::string reason_ = "running";
};

Runner::Runner(const Simulation& sim, const RunOptions& options)
    : sim_(sim),
      options_(options),
      dir_(prepare_output_dir(sim, options)),
      world_(sim),
      observers_(sim, dir_, world_) {}

// A property of the machine, not of the run: written first, so an
// interrupted run still has it.
void Runner::write_field_picture() {
  if (!sim_.output.field || !sim_.electrostatics) return;
  const auto t0 = Clock::now();
  const output::FieldGrid grid = output::sample_field(sim_);
  output::write_file_atomic(dir_ / "field.csv", output::field_csv(grid));
  output::write_file_atomic(dir_ / "field.svg", output::field_svg(sim_, grid));
  output_seconds_ += seconds_since(t0);
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
    observers_.start(world_);
    while (world_.step_count() < steps) {
      if (g_stop_signal != 0) {
        reason_ = g_stop_signal == SIGINT ? "interrupted by SIGINT" : "interrupted by SIGTERM";
        return;
      }
      output_seconds_ += world_.step(&observers_).seconds[Stage::Output];
      progress.update(world_, sim_.end_time, seconds_since(start_));
      if (sim_.until_collected && feed_accounted_for(world_)) break;
    }
    if (sim_.until_collected && !feed_accounted_for(world_)) {
      reason_ = cap_message(sim_, world_);
      return;
    }
    complete_ = true;
  } catch (const std::exception& e) {
    reason_ = "error after " + std::to_string(world_.step_count()) +
              " steps (t = " + output::format_number(world_.time()) + " s): " + e.what();
  }
}

void Runner::write_outputs() {
  const auto t0 = Clock::now();
  output::RunRecord r = record();
  const collect::Collection& c = *world_.collection();
  output::write_file_atomic(dir_ / "bins.csv", output::bins_csv(sim_, c, r.materials));
  output::write_file_atomic(dir_ / "products.csv",
                            output::products_csv(sim_, r.products, r.materials));
  output::write_file_atomic(dir_ / "crossings.csv", output::crossings_csv(sim_, c));
  output::write_file_atomic(dir_ / "lost.csv", output::lost_csv(sim_, c));
  if (sim_.output.distribution_svg)
    output::write_file_atomic(dir_ / "distribution.svg",
                              output::distribution_svg(sim_, c, r.materials));
  observers_.commit();
  r.solver.seconds[Stage::Output] += seconds_since(t0);
  r.wall = seconds_since(start_);
  output::add_warnings(r);
  // Last, so "complete" is only on disk once everything else is.
  output::write_file_atomic(dir_ / "summary.json", output::summary_json(r));
  if (!options_.quiet) output::print_report(r, stdout);
}

output::RunRecord Runner::record() const {
  output::RunRecord r;
  r.sim = &sim_;
  r.collection = world_.collection();
  r.out_dir = dir_.string();
  r.complete = complete_;
  r.reason = complete_ ? std::string() : reason_;
  r.steps = world_.step_count();
  r.time = world_.time();
  r.threads = sim_.model->threads > 0 ? sim_.model->threads : omp_get_max_threads();
  r.wall = seconds_since(start_);
  r.solver = observers_.solver();
  // The steps' own, complete only once each step returned, and the writing
  // outside them.
  r.solver.seconds[Stage::Output] = output_seconds_;
  r.energy = observers_.energy();
  r.frames = observers_.frames();
  r.materials = output::fed_materials(sim_);
  r.products = output::product_results(sim_, *r.collection, r.materials);
  tally_feeds(r);
  tally_active(r);
  return r;
}

void Runner::tally_feeds(output::RunRecord& r) const {
  r.fed.resize(sim_.model->materials.materials().size());
  for (const feed::Feeder& feeder : world_.feeders()) {
    const feed::FeedStats& s = feeder.stats();
    const Feed& f = feeder.feed();
    for (std::size_t c = 0; c < f.mix.size(); ++c)
      r.fed[std::size_t(f.mix[c].material)] += s.fed[c];
    r.feeds.push_back({f.name, f.mass_rate > 0.0, feeder.target(world_.time()), s.total(),
                       s.retries, s.deferrals});
  }
}

// Particles still in the run: rounded exactly as when they were fed.
void Runner::tally_active(output::RunRecord& r) const {
  r.active.resize(sim_.model->materials.materials().size());
  const Particles& p = world_.particles();
  for (std::size_t i = 0; i < p.size(); ++i)
    r.active[std::size_t(p.material[i])].add(to_mass_units(p.mass[i]));
}

}  // namespace

RunResult run(const Simulation& sim, const RunOptions& options) {
  Runner runner(sim, options);
  return runner.run();
}

}  // namespace ces
