// Runs a compiled Simulation: builds the World, attaches feeds, collectors,
// the domain and the observers that write the output folder.
#pragma once
#include <string>

#include "spec/simulation.hpp"

namespace ces {

struct RunOptions {
  std::string out_dir;   // overrides Simulation::output.dir when not empty
  bool progress = false; // a progress line on stderr, redrawn in place (a terminal)
  // s of wall time: otherwise a progress line on stderr this often (a log); 0: none.
  double progress_interval = 0.0;
  bool quiet = false;    // no end-of-run report on stdout
};

struct RunResult {
  bool complete = false;
  std::string reason;    // why not complete ("interrupted by SIGINT", error text)
  std::string out_dir;
};

RunResult run(const Simulation& sim, const RunOptions& options);

}  // namespace ces
