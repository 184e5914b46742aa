// Per-step records: steps.csv, and the solver statistics of the summary
// (iterations, residual percentiles, steps at the iteration cap, penetration).
#pragma once
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "common/serial.hpp"
#include "model/stats.hpp"
#include "output/files.hpp"

namespace ces::output {

struct SolverSummary {
  std::uint64_t steps = 0;
  std::uint64_t solved_steps = 0;  // steps with constraint rows to solve
  double iterations_mean = 0.0;    // over solved steps
  int iterations_max = 0;
  double residual_median = 0.0;  // RMS residual per solved step (m/s)
  double residual_p95 = 0.0;
  double residual_max = 0.0;
  std::uint64_t steps_at_cap = 0;  // stopped at max_iterations, not converged
  std::uint64_t steps_non_finite = 0;  // the solver met no finite residual (not in the percentiles)
  double max_penetration = 0.0;    // m
  double max_penetration_relative = 0.0;
  double max_wall_penetration_relative = 0.0;  // contacts with static and kinematic bodies only
  double max_yield = 0.0;  // m, yielding surfaces (StepStats::max_yield)
  // Steps stopped at the cap whose impulses were scaled down so as not to
  // create energy, and wall rows the wall guard finished (dynamics/safeguards.hpp).
  std::uint64_t steps_impulses_scaled = 0;
  std::uint64_t wall_corrections = 0;
  // Bodies whose wall rows the guard finished body by body, and those it
  // could not (dynamics/safeguards.cpp), summed over steps.
  std::uint64_t walls_finished = 0, walls_unfinished = 0;
  std::uint64_t sliding_releases = 0;  // bodies released from their lift, summed over steps
  std::uint64_t spin_limited = 0;      // clumps in contact whose spin was capped, summed over steps
  std::uint64_t unlisted_wall_stops = 0;  // particles stopped at unlisted walls, summed over steps
  std::uint64_t drag_held =
      0;  // particles whose drag was held (fields/drag.cpp), summed over steps
  double max_joint_drift = 0.0;  // m
  // DEM: the smallest Rayleigh time met (s; inf: none, e.g. under DVI) and
  // the steps longer than 20 % of that step's Rayleigh time.
  double rayleigh_time_min = std::numeric_limits<double>::infinity();
  std::uint64_t steps_above_rayleigh_limit = 0;
  std::size_t max_particles = 0;
  std::size_t max_contacts = 0;
  std::size_t max_asleep = 0;
  StageTimes seconds;  // summed over steps
};

class StepLog {
 public:
  // An empty path: statistics only, no steps.csv.
  StepLog(const std::filesystem::path& steps_csv, int max_iterations, Start start = Start::Fresh);

  // steps.csv's wall_s: the step's stages before the output stage that
  // records it.
  void record(const StepStats& s);
  SolverSummary summary() const;
  // steps.csv complete on the disk (the run's end).
  void close();

  // The sums so far and steps.csv's length, for checkpoints; load() cuts
  // steps.csv back to the length it records and appends from there.
  void save(ByteWriter& out);
  void load(ByteReader& in);

 private:
  std::filesystem::path path_;
  AppendFile file_;
  int max_iterations_;
  SolverSummary sum_;
  std::uint64_t iterations_total_ = 0;
  std::vector<double> residuals_;  // solved steps
};

}  // namespace ces::output
