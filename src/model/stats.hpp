// What a step measured about itself: its solve, its penetrations, what the
// safeguards did and the wall time of each stage. Written by the step,
// read by the observers (steps.csv, the summary).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ces {

// The stages of a step, in the order they run (sim/world.hpp).
enum class Stage {
  Feed, Broadphase, Narrowphase, Forces, Assemble, Solve, Safeguards, Integrate, Collect, Output
};
inline constexpr std::size_t kStageCount = std::size_t(Stage::Output) + 1;
inline constexpr std::array<std::string_view, kStageCount> kStageNames = {
    "feed",     "broadphase", "narrowphase", "forces",  "assemble",
    "solve",    "safeguards", "integrate",   "collect", "output"};

// Wall time per stage (s).
struct StageTimes {
  std::array<double, kStageCount> seconds{};
  double& operator[](Stage s) { return seconds[std::size_t(s)]; }
  double operator[](Stage s) const { return seconds[std::size_t(s)]; }
  StageTimes& operator+=(const StageTimes& o) {
    for (std::size_t i = 0; i < kStageCount; ++i) seconds[i] += o.seconds[i];
    return *this;
  }
  double total() const {
    double t = 0.0;
    for (const double s : seconds) t += s;
    return t;
  }
};

struct SolveStats {
  int iterations = 0;
  double residual = 0.0;  // RMS over rows of the projected-gradient residual (m/s)
  bool converged = false;
};

struct StepStats {
  std::uint64_t step = 0;
  double time = 0.0;  // at the end of the step
  std::size_t particles = 0;
  std::size_t contacts = 0;
  std::size_t asleep = 0;  // particles asleep on a body at the end (dynamics/sleep.hpp)
  SolveStats solver;
  double max_penetration = 0.0;           // m, at the start of the step
  double max_penetration_relative = 0.0;  // / radius of the smaller sphere
  // The same over contacts with walls only (static and kinematic bodies):
  // above 1, a sphere's centre is past a wall's surface (into the drum,
  // through a plate).
  double max_wall_penetration_relative = 0.0;
  // m: the deepest a yielding surface (Material::compliance, a brush's
  // bristles) gives under a particle. Not an overlap: the surface bends
  // by it, so it is kept out of the two above.
  double max_yield = 0.0;
  double joint_drift = 0.0;               // m, at the start of the step
  // The safeguards (dynamics/safeguards.hpp): when the solve stopped at its
  // cap, the factor its contact impulses were scaled by so as not to create
  // energy (1: kept); on every step, the wall rows left violated that the
  // wall guard finished.
  double impulse_scale = 1.0;
  std::size_t wall_corrections = 0;
  // Bodies whose wall rows the guard's first sweeps left violated and whose
  // sweeps went on, body by body, until they held; and of them, those still
  // violated after the sweeps' cap.
  std::size_t walls_finished = 0, walls_unfinished = 0;
  // Bodies whose wall impulses were scaled down to take the relaxed cone's
  // lift back.
  std::size_t sliding_releases = 0;
  // Clumps in contact whose spin was limited.
  std::size_t spin_limited = 0;
  // Particles stopped at a wall their step would have crossed beyond the
  // envelope their contacts were listed within (dynamics/unlisted_walls.hpp).
  std::size_t unlisted_wall_stops = 0;
  // Particles whose drag would have turned them round against the air
  // within the step, held to stopping them (fields/drag.cpp).
  std::size_t drag_held = 0;
  // DEM only: the smallest particle's Rayleigh time (s; 0 under DVI), and
  // whether the step exceeds 20 % of it (explicit contact is then unreliable).
  double rayleigh_time = 0.0;
  bool step_above_rayleigh_limit = false;
  StageTimes seconds;
};

}  // namespace ces
