// summary.json and the end-of-run report on stdout.
#pragma once
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "collect/collection.hpp"
#include "output/energy.hpp"
#include "output/step_log.hpp"
#include "output/tables.hpp"
#include "common/tally.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

struct FeedRecord {
  std::string name;
  bool by_mass = true;  // mass rate (kg/s), else count rate (1/s)
  double target = 0.0;  // what the rate asked for by the end (kg or count)
  Tally fed;
  std::uint64_t retries = 0;
  std::uint64_t deferrals = 0;
};

// Everything a run reports, gathered by sim/run.cpp.
struct RunRecord {
  const Simulation* sim = nullptr;
  const Collection* collection = nullptr;
  std::string out_dir;
  bool complete = false;
  std::string reason;
  std::uint64_t steps = 0;
  double time = 0.0;  // simulated (s)
  int threads = 1;              // the most a step may use
  bool threads_adaptive = false;  // chosen step by step (sim/threads.hpp)
  std::vector<std::uint64_t> steps_at_threads;  // index = thread count
  double wall = 0.0;  // s
  double peak_memory = 0.0;  // bytes: the largest peak resident set of the run's processes
  SolverSummary solver;
  EnergyBalance energy;
  std::vector<FeedRecord> feeds;
  std::vector<Tally> fed, active;  // per Model material
  std::vector<int> materials;      // the reported ones (fed_materials)
  std::vector<ProductResult> products;
  std::size_t frames = 0;
  std::vector<std::string> warnings;
  std::vector<std::string> files;  // the run's outputs, relative to its folder
};

// What a user should look at twice: solver caps, deep overlaps, deferred or
// missing feed, lost particles. Appends to record.warnings.
void add_warnings(RunRecord& record);

// The DEM stability warning: `step` above 20 % of `rayleigh_time` (s), met
// in `steps` steps (0: said as the run goes).
std::string rayleigh_warning(double step, double rayleigh_time, std::uint64_t steps);

std::string summary_json(const RunRecord& record);
void print_report(const RunRecord& record, std::FILE* out);

}  // namespace ces::output
