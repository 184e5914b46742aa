// The thread governor (sim/threads.hpp) on synthetic step times: which
// count it settles on, and how many steps its probes spend on the loser.
#include <gtest/gtest.h>

#include <functional>

#include "sim/threads.hpp"

namespace ces {
namespace {

// Runs n steps whose time is seconds(count, step); returns the governor.
ThreadGovernor run(int max_threads, int n, const std::function<double(int, int)>& seconds) {
  ThreadGovernor g(max_threads, true);
  for (int step = 0; step < n; ++step) g.took(seconds(g.next(), step));
  return g;
}

// A quiet machine: two threads halve the step. The first probe (after two
// steps) moves to two threads, and at most one step in fifty runs on one.
TEST(ThreadGovernor, QuietMachineMovesToAllThreads) {
  const ThreadGovernor g = run(2, 2000, [](int threads, int) { return 0.01 / threads; });
  EXPECT_GE(g.steps_at()[2], 1960u);
  EXPECT_LE(g.steps_at()[1], 40u);
}

// Both cores busy with other work: a step on two threads costs a hundred on
// one. The probes cost at most about 1/20 of the run (kOverheadSteps).
TEST(ThreadGovernor, BusyMachineStaysOnOneThread) {
  const ThreadGovernor g =
      run(2, 20000, [](int threads, int) { return threads == 1 ? 0.01 : 1.0; });
  const double probe_cost = double(g.steps_at()[2]) * 1.0;
  const double run_cost = double(g.steps_at()[1]) * 0.01;
  EXPECT_LE(probe_cost, 0.06 * run_cost) << g.steps_at()[2] << " steps on two threads";
}

// The machine gets busy half way: the first slow step on two threads starts
// a probe, and the governor is on one thread within a probe's pair.
TEST(ThreadGovernor, FollowsAMachineThatGetsBusy) {
  int first_slow_step = -1, steps_at_two_after = 0;
  ThreadGovernor g(2, true);
  for (int step = 0; step < 4000; ++step) {
    const int threads = g.next();
    const bool busy = step >= 2000;
    if (busy && threads == 2) {
      if (first_slow_step < 0) first_slow_step = step;
      ++steps_at_two_after;
    }
    g.took(busy ? (threads == 1 ? 0.01 : 1.0) : 0.01 / threads);
  }
  ASSERT_GE(first_slow_step, 2000);
  EXPECT_EQ(g.next(), 1);
  EXPECT_LE(steps_at_two_after, 3);  // the slow step, and the probe's second step
}

// Steps with too little work to share take the same time on any count: the
// governor stays where it started (one thread) instead of chasing noise.
TEST(ThreadGovernor, EqualTimesKeepOneThread) {
  const ThreadGovernor g =
      run(2, 3000, [](int threads, int step) { return 0.001 * (1.0 + 0.05 * ((step + threads) % 3)); });
  EXPECT_GE(g.steps_at()[1], 2900u);
}

// A fixed count (--threads, or adaptive off) is never changed.
TEST(ThreadGovernor, FixedCountStays) {
  ThreadGovernor g(2, false);
  for (int step = 0; step < 500; ++step) g.took(g.next() == 2 ? 1.0 : 0.01);
  EXPECT_EQ(g.steps_at()[2], 500u);
  EXPECT_FALSE(g.adaptive());
}

}  // namespace
}  // namespace ces
