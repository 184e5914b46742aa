// Runs a compiled Simulation: builds the World of its stages, steps it to
// the end with the observers that write the output folder, checkpoints it
// when the scene asks, and resumes it from a checkpoint.
#pragma once
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

#include "sim/checkpoint.hpp"
#include "spec/simulation.hpp"

namespace ces {

// Where a run is, for a caller that watches it (RunOptions::on_progress).
struct RunProgress {
  double time = 0.0;          // simulated (s)
  double end_time = 0.0;      // the scene's end time (s); at the last step, the time now
                              // (a run until collected ends before time.end)
  std::uint64_t steps = 0;    // steps taken
  std::size_t particles = 0;  // particles in the run
  double wall = 0.0;          // wall time since the run started (s)
};

struct RunOptions {
  std::string out_dir;   // overrides Simulation::output.dir when not empty
  bool progress = false; // a progress line on stderr, redrawn in place (a terminal)
  bool quiet = false;    // no end-of-run report on stdout
  // Called between steps once on_progress_every seconds of wall time have
  // passed since its last call, and after the last step (with until:
  // collected, the step that accounts for the last particle). Returning
  // true stops the run before its next step; it then ends incomplete,
  // "stopped by the caller". Its time counts in the output stage.
  std::function<bool(const RunProgress&)> on_progress = {};
  double on_progress_every = 1.0;
  int threads = 0;  // worker threads, as --threads; 0: the scene's (Model::threads)
  // s of wall time: otherwise a progress line on stderr this often (a log); 0: none.
  double progress_interval = 0.0;
};

struct RunResult {
  bool complete = false;
  std::string reason;    // why not complete ("interrupted by SIGINT", error text)
  std::string out_dir;   // where the outputs are: DIR, or DIR/partial for a run not complete
  int signal = 0;        // SIGINT or SIGTERM when one stopped the run, else 0
};

// A new run of the scene into options.out_dir (or the scene's output.dir):
// written into DIR/partial as it goes, moved into DIR when complete
// (sim/output_folder.hpp).
RunResult run(const Simulation& sim, const RunOptions& options);

// The checkpoint of the unfinished run in DIR (DIR/partial/checkpoint.bin).
// Throws output::IoError when there is none, CorruptData when it is damaged.
Checkpoint find_checkpoint(const std::string& dir);

// Continues that run: sim is its scene, rebuilt by the caller from the
// checkpoint's scene_path and resolved_yaml (scene::load_text). The
// results are the bytes the run would have written had it not stopped.
// The checkpoint is taken over: its state is freed once the run holds it.
RunResult resume(const Simulation& sim, Checkpoint checkpoint, const std::string& dir,
                 RunOptions options);

}  // namespace ces
