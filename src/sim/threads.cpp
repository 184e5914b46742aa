#include "sim/threads.hpp"

#include <algorithm>
#include <cmath>

namespace ces {
namespace {

// The first probe comes after a few steps (the first steps create the
// threads); later ones after a period that doubles from kFirstPeriod up to
// kLongestPeriod while the choice holds.
constexpr std::uint64_t kFirstProbe = 2, kFirstPeriod = 64, kLongestPeriod = 16384;
// A probe whose candidate was slower by a factor r wasted about r - 1 steps;
// the next probe waits at least kOverheadSteps times that, so probing costs
// the run at most about 1 / kOverheadSteps of its time.
constexpr double kOverheadSteps = 20.0;
// Between probes, a step this many times slower than the typical step at
// the current count starts a probe at once: another process took a core.
constexpr double kSuddenlySlower = 4.0;
// The typical step: a running mean of log(seconds) over about this many steps.
constexpr double kTypicalSteps = 16.0;
// A probe takes at most this many pairs of steps; it stops after one pair
// when the candidate is clearly slower or faster (a clearly slower one can
// cost tens of steps' time on a busy machine).
constexpr int kMaxPairs = 4;
constexpr double kClearlySlower = 2.0, kClearlyFaster = 0.5;
// After all pairs the candidate must be this much faster to be kept: equal
// times keep the current count, and more threads must gain clearly (steps
// with too little work to share run alike on any count, within noise).
constexpr double kGainFewer = 0.9, kGainMore = 0.75;

}  // namespace

ThreadGovernor::ThreadGovernor(int max_threads, bool adaptive)
    : max_(std::max(1, max_threads)),
      adaptive_(adaptive && max_ > 1),
      current_(adaptive_ ? 1 : max_),
      steps_at_(std::size_t(max_) + 1, 0),
      until_probe_(kFirstProbe),
      period_(kFirstPeriod) {}

void ThreadGovernor::took(double seconds) {
  ++steps_at_[std::size_t(next())];
  if (!adaptive_) return;
  if (!probing_) {
    const bool sudden = typical_ > 0.0 && current_ > 1 && seconds > kSuddenlySlower * typical_;
    typical_ = typical_ > 0.0 ? std::exp(std::log(typical_) +
                                         (std::log(std::max(seconds, 1e-9)) - std::log(typical_)) /
                                             kTypicalSteps)
                              : std::max(seconds, 1e-9);
    if (sudden || --until_probe_ == 0) start_probe();
    return;
  }
  (probe_step_ % 2 == 0 ? candidate_seconds_ : current_seconds_) += seconds;
  if (++probe_step_ % 2 != 0) return;  // a pair is complete after its second step
  const double ratio = candidate_seconds_ / std::max(current_seconds_, 1e-12);
  if (ratio > kClearlySlower) return decide(false, ratio);
  if (ratio < kClearlyFaster) return decide(true, ratio);
  const double gain = candidate_ < current_ ? kGainFewer : kGainMore;
  if (probe_step_ == 2 * kMaxPairs) decide(ratio < gain, ratio);
}

void ThreadGovernor::start_probe() {
  const int fewer = std::max(1, current_ / 2), more = std::min(max_, 2 * current_);
  if (fewer == current_) try_fewer_ = false;
  if (more == current_) try_fewer_ = true;
  candidate_ = try_fewer_ ? fewer : more;
  try_fewer_ = !try_fewer_;
  probing_ = true;
  probe_step_ = 0;
  candidate_seconds_ = current_seconds_ = 0.0;
}

void ThreadGovernor::decide(bool switch_to_candidate, double ratio) {
  probing_ = false;
  // The loser's time over the winner's: what probing the loser again costs.
  const double loss = switch_to_candidate ? 1.0 / std::max(ratio, 1e-12) : ratio;
  const auto wasted = std::uint64_t(std::ceil(kOverheadSteps * std::max(0.0, loss - 1.0)));
  if (switch_to_candidate) {
    current_ = candidate_;
    typical_ = 0.0;  // another count: its own typical step
    period_ = kFirstPeriod;
  } else {
    period_ = 2 * period_;
  }
  period_ = std::min(kLongestPeriod, std::max(period_, wasted));
  until_probe_ = period_;
}

}  // namespace ces
