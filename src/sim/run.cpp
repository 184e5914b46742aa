// The run: the World of the compiled scene stepped to the end time (or,
// with time.until: collected, until its feed is accounted for; or until a
// signal or an error), observed by the outputs as it goes, then every
// output written from what was accumulated.
#include "sim/run.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <utility>

#include "common/clock.hpp"
#include "common/process.hpp"
#include "output/collected_log.hpp"
#include "output/distribution_svg.hpp"
#include "output/energy.hpp"
#include "output/field_picture.hpp"
#include "output/files.hpp"
#include "output/format.hpp"
#include "output/report.hpp"
#include "output/step_log.hpp"
#include "output/summary.hpp"
#include "output/tables.hpp"
#include "output/trajectories.hpp"
#include "sim/checkpoint.hpp"
#include "sim/output_folder.hpp"
#include "sim/stop.hpp"
#include "sim/threads.hpp"
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

// Progress on stderr: on a terminal one line, redrawn at most five times a
// second; in a log, a line every `interval` seconds of wall time.
class Progress {
 public:
  Progress(bool terminal, double interval) : terminal_(terminal), interval_(interval) {}
  ~Progress() {
    if (drawn_) std::fputs("\r\033[K", stderr);
  }
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // A run until collected ends when its particles are: time.end is only its
  // cap, and an estimate from it would be far off.
  void update(const World& world, const Simulation& sim, double wall) {
    if (!due(wall)) return;
    last_ = wall;
    drawn_ = terminal_;
    char time[96];
    if (sim.until_collected) {
      std::snprintf(time, sizeof time, "t %.4g s (until collected, at most %.4g s)  wall %.1f s",
                    world.time(), sim.end_time, wall);
    } else {
      const double done = world.time() / sim.end_time;
      const double eta = done > 0 ? wall * (1.0 - done) / done : 0.0;
      std::snprintf(time, sizeof time, "t %.4g / %.4g s  wall %.1f s  ETA %.0f s", world.time(),
                    sim.end_time, wall, eta);
    }
    // The step's own counts, as steps.csv has them (before its collection).
    const StepStats& last = world.last_step();
    std::fprintf(stderr, "%s%s  particles %zu  contacts %zu%s",
                 terminal_ ? "\r\033[K" : "progress: ", time, last.particles, last.contacts,
                 terminal_ ? "" : "\n");
    std::fflush(stderr);
  }

 private:
  bool due(double wall) const {
    if (terminal_) return wall - last_ >= 0.2;
    return interval_ > 0.0 && wall >= last_ + interval_;
  }

  bool terminal_;
  double interval_;
  bool drawn_ = false;
  double last_ = 0.0;  // wall time of the last line
};

// The outputs that watch the run as it goes; they only read the world.
class Observers : public StepObserver {
 public:
  Observers(const Simulation& sim, const fs::path& dir, const World& world, output::Start start)
      : sim_(sim),
        steps_(sim.output.steps_csv ? dir / "steps.csv" : fs::path(),
               sim.model->solver.max_iterations, start),
        collected_(sim, dir, start),
        trajectories_(dir, sim, shape_sizes(sim), start),
        energy_(sim, world.state()),
        section_(sim.model->step) {}

  void after(Stage stage, const World& world) override { energy_.after(stage, world.state()); }

  void end_of_step(const World& world) override {
    const StepStats& s = world.last_step();
    if (s.step_above_rayleigh_limit && !rayleigh_warned_) {  // now, not only at the end
      rayleigh_warned_ = true;
      std::fprintf(stderr, "warning: t = %s s: %s\n", output::format_number(s.time).c_str(),
                   output::rayleigh_warning(sim_.model->step, s.rayleigh_time, 0).c_str());
    }
    steps_.record(s);
    if (const collect::Collection* c = world.collection()) collected_.record(*c);
    trajectories_.observe(world.state());
    section_.observe(world.state());
  }

  void start(const World& world) {  // the frames at t = 0
    trajectories_.observe(world.state());
    section_.observe(world.state());
  }
  void finish(const World& world) { section_.finish(world.state()); }  // the run's last state
  void close() {
    steps_.close();
    collected_.close();
    trajectories_.close();
  }
  void save(ByteWriter& out) {
    steps_.save(out);
    collected_.save(out);
    trajectories_.save(out);
    energy_.save(out);
    section_.save(out);
    out.value(rayleigh_warned_);
  }
  void load(ByteReader& in) {
    steps_.load(in);
    collected_.load(in);
    trajectories_.load(in);
    energy_.load(in);
    section_.load(in);
    in.value(rayleigh_warned_);
  }
  // Written as the run goes, relative to its folder.
  std::vector<std::string> files() const {
    std::vector<std::string> out = trajectories_.files();
    if (sim_.output.steps_csv) out.push_back("steps.csv");
    return out;
  }
  output::SolverSummary solver() const { return steps_.summary(); }
  const output::EnergyBalance& energy() const { return energy_.balance(); }
  std::size_t frames() const { return trajectories_.frames(); }
  const output::CrossSection& section() const { return section_; }

 private:
  const Simulation& sim_;
  output::StepLog steps_;
  output::CollectedLog collected_;
  output::TrajectoryWriter trajectories_;
  output::EnergyLedger energy_;
  output::CrossSection section_;
  bool rayleigh_warned_ = false;
};

// What summary.json says until the run writes why it ended.
constexpr const char* kNoEnd =
    "no end recorded: the run is still going, or its process was killed (SIGKILL, out of "
    "memory) or its machine stopped";

class Runner {
 public:
  // resume: the body of a checkpoint of this scene, or none for a new run.
  Runner(const Simulation& sim, const RunOptions& options, std::optional<std::string> resume);
  RunResult run();

 private:
  void start();
  void read_checkpoint_body();
  void write_field_picture();
  void step_to_end();
  bool caller_stops(bool last);
  void checkpoint();
  void write_outputs();
  void publish(output::RunRecord& r);
  void write_summary(const output::RunRecord& r);
  void write_report(const output::RunRecord& r, const std::string& distribution_svg);
  std::vector<std::string> files() const;
  double wall() const { return wall_before_ + seconds_since(start_); }
  // The largest peak resident set of the run's processes so far (bytes).
  double peak_memory() const { return std::max(peak_before_, peak_resident_bytes()); }
  output::RunRecord record() const;
  void tally_feeds(output::RunRecord& r) const;
  void tally_active(output::RunRecord& r) const;

  const Simulation& sim_;
  RunOptions options_;
  std::optional<std::string> resume_;
  Clock::time_point start_ = Clock::now();
  OutputFolder folder_;
  fs::path dir_;  // the folder written while the run goes: folder_.work()
  World world_;
  Observers observers_;
  ThreadGovernor threads_;
  std::uint64_t checkpoint_steps_;  // steps between checkpoints; 0: none
  std::size_t checkpoint_bytes_ = 0;  // the state in the last checkpoint
  double output_seconds_ = 0.0;  // the output stage's, and the writing before and after the steps
  double wall_before_ = 0.0;     // the wall time of a resumed run's earlier processes
  double peak_before_ = 0.0;     // bytes: their largest peak resident set
  double watched_at_ = 0.0;      // wall time of the caller's last on_progress
  int stop_signal_ = 0;          // the signal that stopped the steps
  bool complete_ = false;
  std::string reason_ = kNoEnd;
};

fs::path output_dir(const Simulation& sim, const RunOptions& options) {
  return options.out_dir.empty() ? fs::path(sim.output.dir) : fs::path(options.out_dir);
}

// The thread count the caller or the scene fixes, else up to every core,
// chosen as the run goes.
ThreadGovernor governor(const Simulation& sim, const RunOptions& options) {
  const int fixed = options.threads > 0 ? options.threads : sim.model->threads;
  return ThreadGovernor(fixed > 0 ? fixed : omp_get_max_threads(), fixed == 0);
}

output::Start start_of(const std::optional<std::string>& resume) {
  return resume ? output::Start::Resume : output::Start::Fresh;
}

Runner::Runner(const Simulation& sim, const RunOptions& options, std::optional<std::string> resume)
    : sim_(sim),
      options_(options),
      resume_(std::move(resume)),
      folder_(output_dir(sim, options), start_of(resume_)),
      dir_(folder_.work()),
      world_(sim),
      observers_(sim, dir_, world_, start_of(resume_)),
      threads_(governor(sim, options)),
      checkpoint_steps_(sim.output.checkpoint_every > 0.0
                            ? std::uint64_t(std::max(
                                  1.0, std::round(sim.output.checkpoint_every / sim.model->step)))
                            : 0) {}

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

void Runner::read_checkpoint_body() {
  ByteReader in(*resume_);
  world_.load(in);
  observers_.load(in);
  in.value(wall_before_);
  in.value(output_seconds_);
  in.value(peak_before_);
  if (!in.at_end()) throw CorruptData("the checkpoint holds more than this scene's run");
  checkpoint_bytes_ = resume_->size();  // the next checkpoint's buffer is reserved from it
}

// A new run writes what it knows before its first step; a resumed one
// reads its checkpoint back.
void Runner::start() {
  if (resume_) {
    read_checkpoint_body();
    resume_.reset();  // the world holds the state now; the bytes would stay for the whole run
    return;
  }
  if (!sim_.resolved_yaml.empty())
    output::write_file_atomic(dir_ / "scene.resolved.yaml", sim_.resolved_yaml);
  // A summary from the start: a run killed outright still says it did not finish.
  output::write_file_atomic(dir_ / "summary.json", output::summary_json(record()));
  write_field_picture();
  observers_.start(world_);
}

RunResult Runner::run() {
  const StopSignals signals;
  try {
    start();
    step_to_end();
  } catch (const std::bad_alloc&) {
    reason_ = "error after " + std::to_string(world_.step_count()) + " steps (t = " +
              output::format_number(world_.time()) + " s): out of memory with " +
              std::to_string(world_.particles().size()) + " particles in the run";
  } catch (const std::exception& e) {
    reason_ = "error after " + std::to_string(world_.step_count()) +
              " steps (t = " + output::format_number(world_.time()) + " s): " + e.what();
  }
  write_outputs();
  return {complete_, complete_ ? std::string() : reason_,
          (complete_ ? folder_.dir() : dir_).string(), stop_signal_};
}

void Runner::step_to_end() {
  const auto steps = std::uint64_t(std::llround(sim_.end_time / sim_.model->step));
  Progress progress(options_.progress && !options_.quiet,
                    options_.quiet ? 0.0 : options_.progress_interval);
  while (world_.step_count() < steps) {
    if (g_stop_signal != 0) {
      stop_signal_ = g_stop_signal;
      reason_ = g_stop_signal == SIGINT ? "interrupted by SIGINT" : "interrupted by SIGTERM";
      return;
    }
    omp_set_num_threads(threads_.next());
    const auto t0 = Clock::now();
    output_seconds_ += world_.step(&observers_).seconds[Stage::Output];
    threads_.took(seconds_since(t0));
    if (checkpoint_steps_ > 0 && world_.step_count() % checkpoint_steps_ == 0) checkpoint();
    progress.update(world_, sim_, seconds_since(start_));
    const bool collected = sim_.until_collected && feed_accounted_for(world_);
    const bool last = collected || world_.step_count() >= steps;
    if (caller_stops(last) && !last) {
      reason_ = "stopped by the caller";
      return;
    }
    if (collected) break;
  }
  if (sim_.until_collected && !feed_accounted_for(world_)) {
    reason_ = cap_message(sim_, world_);
    return;
  }
  complete_ = true;
}

// The caller's on_progress, when due: true when it asks the run to stop.
bool Runner::caller_stops(bool last) {
  if (!options_.on_progress) return false;
  const double wall = seconds_since(start_);
  if (wall - watched_at_ < options_.on_progress_every && !last) return false;
  watched_at_ = wall;
  const auto t0 = Clock::now();
  // At the last step the run ends now, whatever time.end says.
  const double end = last ? world_.time() : sim_.end_time;
  const bool stop = options_.on_progress(
      {world_.time(), end, world_.step_count(), world_.particles().size(), wall});
  output_seconds_ += seconds_since(t0);
  return stop;
}

// The whole state, then a summary that says how far the run got.
void Runner::checkpoint() {
  const auto t0 = Clock::now();
  // Room for the last checkpoint's state and an eighth: growing by
  // doubling, the buffer would copy itself and hold up to twice the state.
  ByteWriter body;
  body.reserve(checkpoint_bytes_ + checkpoint_bytes_ / 8);
  world_.save(body);
  observers_.save(body);
  // The run's wall time and output stage so far, which the other stages'
  // tallies (observers_) carry on their own: a resumed run's summary counts
  // every process it took.
  body.value(wall());
  body.value(output_seconds_);
  body.value(peak_memory());
  checkpoint_bytes_ = body.bytes().size();
  write_checkpoint(dir_ / "checkpoint.bin",
                   {sim_.scene_path, sim_.scene_hash, sim_.resolved_yaml, std::move(body).take()});
  output::write_file_atomic(dir_ / "summary.json", output::summary_json(record()));
  output_seconds_ += seconds_since(t0);
}

std::vector<std::string> Runner::files() const {
  std::vector<std::string> out = {"summary.json", "report.html", "bins.csv", "products.csv",
                                  "crossings.csv", "lost.csv"};
  if (!sim_.resolved_yaml.empty()) out.push_back("scene.resolved.yaml");
  if (sim_.output.distribution_svg) out.push_back("distribution.svg");
  if (sim_.output.field && sim_.electrostatics) out.insert(out.end(), {"field.csv", "field.svg"});
  const std::vector<std::string> observed = observers_.files();
  out.insert(out.end(), observed.begin(), observed.end());
  return out;
}

// Every output of a run that ended, complete or not; a complete run's move
// into the output folder (OutputFolder).
void Runner::write_outputs() {
  const auto t0 = Clock::now();
  output::RunRecord r = record();
  // Each failure names its file; a later one adds to the reason rather than
  // replacing it, so a disk that fills up mid-run still names the file that
  // failed first.
  auto failed = [&](const std::exception& e) {
    reason_ = r.reason = complete_ ? std::string("cannot write the outputs: ") + e.what()
                                   : reason_ + "; " + e.what();
    complete_ = r.complete = false;
  };
  std::string distribution;
  try {
    const collect::Collection& c = *world_.collection();
    output::write_file_atomic(dir_ / "bins.csv", output::bins_csv(sim_, c, r.materials));
    output::write_file_atomic(dir_ / "products.csv",
                              output::products_csv(sim_, r.products, r.materials));
    if (sim_.output.distribution_svg) {
      distribution = output::distribution_svg(sim_, c, r.materials);
      output::write_file_atomic(dir_ / "distribution.svg", distribution);
    }
    observers_.close();
  } catch (const std::exception& e) {
    failed(e);
  }
  r.solver.seconds[Stage::Output] += seconds_since(t0);
  r.wall = wall();
  output::add_warnings(r);
  try {
    observers_.finish(world_);
    write_report(r, distribution);
  } catch (const std::exception& e) {
    failed(e);
  }
  write_summary(r);
  if (complete_) publish(r);
  if (!options_.quiet) output::print_report(r, stdout);
}

// A complete run's files move into the output folder. When a move fails,
// the summary left in the work folder says so, instead of "complete". Once
// summary.json has moved, every result is in place: a failure after it only
// leaves the work folder behind, which the next run clears.
void Runner::publish(output::RunRecord& r) {
  try {
    folder_.publish(r.files);
  } catch (const std::exception& e) {
    if (fs::exists(dir_ / "summary.json")) {
      complete_ = r.complete = false;
      reason_ = r.reason = e.what();
      write_summary(r);
      return;
    }
  }
  r.out_dir = folder_.dir().string();
}

// report.html, from what summary.json will say but its last figures (the
// output stage's time, written after the report).
void Runner::write_report(const output::RunRecord& r, const std::string& distribution_svg) {
  std::string field_svg;
  if (std::ifstream in{dir_ / "field.svg", std::ios::binary})
    field_svg.assign(std::istreambuf_iterator<char>(in), {});
  output::write_file_atomic(dir_ / "report.html",
                            output::report_html(sim_, output::summary_json(r), distribution_svg,
                                                field_svg, observers_.section()));
}

// summary.json, last: "complete" is on disk only once everything else is.
// On a full disk the new file cannot be made; the old one is then
// overwritten where it lies (its blocks are freed first), so it still says
// why the run stopped.
void Runner::write_summary(const output::RunRecord& r) {
  const std::string text = output::summary_json(r);
  try {
    output::write_file_atomic(dir_ / "summary.json", text);
  } catch (const output::IoError& e) {
    std::FILE* f = std::fopen((dir_ / "summary.json").c_str(), "w");
    const bool written = f && std::fwrite(text.data(), 1, text.size(), f) == text.size();
    if (f) std::fclose(f);
    if (!written)
      std::fprintf(stderr, "ces-sim: cannot write %s: %s\n", (dir_ / "summary.json").c_str(),
                   e.what());
  }
}

output::RunRecord Runner::record() const {
  output::RunRecord r;
  r.sim = &sim_;
  r.collection = world_.collection();
  r.out_dir = dir_.string();
  r.files = files();
  r.complete = complete_;
  r.reason = complete_ ? std::string() : reason_;
  r.steps = world_.step_count();
  r.time = world_.time();
  r.threads = threads_.max_threads();
  r.threads_adaptive = threads_.adaptive();
  r.steps_at_threads = threads_.steps_at();
  r.wall = wall();
  r.peak_memory = peak_memory();
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
  Runner runner(sim, options, std::nullopt);
  return runner.run();
}

Checkpoint find_checkpoint(const std::string& dir) { return read_checkpoint(checkpoint_file(dir)); }

RunResult resume(const Simulation& sim, Checkpoint checkpoint, const std::string& dir,
                 RunOptions options) {
  if (sim.scene_hash != checkpoint.scene_hash)
    throw CorruptData("the scene rebuilt from the checkpoint in " + dir +
                      " differs from the one that wrote it");
  options.out_dir = dir;
  Runner runner(sim, options, std::move(checkpoint.body));
  return runner.run();
}

}  // namespace ces
