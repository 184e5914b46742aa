// Runs a compiled Simulation: builds the World of its stages, steps it to
// the end with the observers that write the output folder, checkpoints it
// when the scene asks, and resumes it from a checkpoint.
#pragma once
#include <string>

#include "sim/checkpoint.hpp"
#include "spec/simulation.hpp"

namespace ces {

struct RunOptions {
  std::string out_dir;   // overrides Simulation::output.dir when not empty
  bool progress = false; // a progress line on stderr
  bool quiet = false;    // no end-of-run report on stdout
};

struct RunResult {
  bool complete = false;
  std::string reason;    // why not complete ("interrupted by SIGINT", error text)
  std::string out_dir;   // where the outputs are: DIR, or DIR/partial for a run not complete
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
RunResult resume(const Simulation& sim, const Checkpoint& checkpoint, const std::string& dir,
                 RunOptions options);

}  // namespace ces
