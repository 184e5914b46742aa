#include "output/step_log.hpp"

#include <algorithm>
#include <cmath>

#include "common/process.hpp"
#include "output/format.hpp"

namespace ces::output {
namespace {

// Nearest-rank percentile of sorted values.
double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  const auto rank = std::size_t(std::ceil(p * double(sorted.size())));
  return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
}

}  // namespace

StepLog::StepLog(const std::filesystem::path& steps_csv, int max_iterations, Start start)
    : path_(steps_csv), max_iterations_(max_iterations) {
  if (steps_csv.empty() || start == Start::Resume) return;
  file_ = AppendFile(steps_csv);
  file_.write(
      "step,time_s,particles,contacts,asleep,iterations,residual_mps,max_penetration_m,"
      "max_penetration_rel,max_wall_penetration_rel,wall_s,resident_mib\n");
}

void StepLog::record(const StepStats& s) {
  ++sum_.steps;
  if (s.solver.iterations > 0) {
    ++sum_.solved_steps;
    iterations_total_ += std::uint64_t(s.solver.iterations);
    sum_.iterations_max = std::max(sum_.iterations_max, s.solver.iterations);
    if (std::isfinite(s.solver.residual))
      residuals_.push_back(s.solver.residual);
    else
      ++sum_.steps_non_finite;
    if (s.solver.iterations >= max_iterations_ && !s.solver.converged) ++sum_.steps_at_cap;
  }
  sum_.max_penetration = std::max(sum_.max_penetration, s.max_penetration);
  sum_.max_penetration_relative =
      std::max(sum_.max_penetration_relative, s.max_penetration_relative);
  sum_.max_wall_penetration_relative =
      std::max(sum_.max_wall_penetration_relative, s.max_wall_penetration_relative);
  sum_.max_yield = std::max(sum_.max_yield, s.max_yield);
  if (s.impulse_scale < 1.0) ++sum_.steps_impulses_scaled;
  sum_.wall_corrections += s.wall_corrections;
  sum_.walls_finished += s.walls_finished;
  sum_.walls_unfinished += s.walls_unfinished;
  sum_.sliding_releases += s.sliding_releases;
  sum_.spin_limited += s.spin_limited;
  sum_.unlisted_wall_stops += s.unlisted_wall_stops;
  sum_.drag_held += s.drag_held;
  sum_.max_joint_drift = std::max(sum_.max_joint_drift, s.joint_drift);
  if (s.rayleigh_time > 0.0) sum_.rayleigh_time_min = std::min(sum_.rayleigh_time_min, s.rayleigh_time);
  if (s.step_above_rayleigh_limit) ++sum_.steps_above_rayleigh_limit;
  sum_.max_particles = std::max(sum_.max_particles, s.particles);
  sum_.max_contacts = std::max(sum_.max_contacts, s.contacts);
  sum_.max_asleep = std::max(sum_.max_asleep, s.asleep);
  sum_.seconds += s.seconds;
  if (!file_.is_open()) return;
  std::string text;
  CsvWriter row(text);
  row << s.step << s.time << s.particles << s.contacts << s.asleep << s.solver.iterations
      << s.solver.residual << s.max_penetration << s.max_penetration_relative
      << s.max_wall_penetration_relative << s.seconds.total()
      << std::round(resident_bytes() / (1 << 20) * 10.0) / 10.0;
  row.end_row();
  file_.write(text);
}

SolverSummary StepLog::summary() const {
  SolverSummary s = sum_;
  if (s.solved_steps > 0) s.iterations_mean = double(iterations_total_) / double(s.solved_steps);
  std::vector<double> sorted = residuals_;
  std::sort(sorted.begin(), sorted.end());
  s.residual_median = percentile(sorted, 0.5);
  s.residual_p95 = percentile(sorted, 0.95);
  s.residual_max = sorted.empty() ? 0.0 : sorted.back();
  return s;
}

void StepLog::close() { file_.close(); }

void StepLog::save(ByteWriter& out) {
  out.value(sum_);
  out.value(iterations_total_);
  out.values(residuals_);
  out.value(file_.flush());
}

void StepLog::load(ByteReader& in) {
  in.value(sum_);
  in.value(iterations_total_);
  in.values(residuals_);
  const auto length = in.value<std::uint64_t>();
  if (!path_.empty()) file_ = AppendFile(path_, length);
}

}  // namespace ces::output
