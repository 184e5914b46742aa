// The thread count of each step, when the user did not fix it.
//
// A run gives the same bits with any thread count (docs/architecture.md), so
// the count may change from one step to the next. On a machine whose cores
// are shared with other busy processes, a worker that loses its core holds
// up every fork and barrier of the step, and the threads waiting for it spin:
// two threads then run many times slower than one. So the governor times
// steps at its current count and at a neighbouring one (half or double), in
// adjacent pairs so that both see the same work, and keeps the faster. It
// probes again after a period that doubles while its choice holds (and is
// long enough that a probe costs the run a few per cent at most), so a quiet
// machine pays almost nothing and a machine that gets busy (or quiet) is
// followed: a step much slower than the typical one at the current count
// starts a probe at once.
#pragma once
#include <cstdint>
#include <vector>

namespace ces {

class ThreadGovernor {
 public:
  // With adaptive false: max_threads, always. Adaptive: from one thread,
  // since on a busy machine a step with more can cost many steps' time,
  // where starting at one thread on a quiet machine costs a few steps.
  ThreadGovernor(int max_threads, bool adaptive);

  // The thread count for the next step.
  int next() const { return probing_ ? probe_count() : current_; }
  // The wall time of the step just taken at next().
  void took(double seconds);

  int max_threads() const { return max_; }
  bool adaptive() const { return adaptive_; }
  // Steps taken at each thread count (index = count).
  const std::vector<std::uint64_t>& steps_at() const { return steps_at_; }

 private:
  int probe_count() const { return (probe_step_ % 2 == 0) ? candidate_ : current_; }
  void start_probe();
  // ratio: the candidate's time over the current count's in the probe.
  void decide(bool switch_to_candidate, double ratio);

  int max_;
  bool adaptive_;
  int current_;
  std::vector<std::uint64_t> steps_at_;
  std::uint64_t until_probe_;  // steps before the next probe
  std::uint64_t period_;       // steps between probes
  bool probing_ = false;
  bool try_fewer_ = true;      // which neighbour the next probe tries
  int candidate_ = 1;
  int probe_step_ = 0;         // steps taken in this probe (candidate, current, ...)
  double candidate_seconds_ = 0.0, current_seconds_ = 0.0;
  double typical_ = 0.0;       // s: the typical step at the current count; 0: none yet
};

}  // namespace ces
