// ces_bench's pieces: what each measurement returns, and the functions that
// take them. bench.cpp decides what to measure; output.cpp writes the CSV and
// the report from a Results.
#pragma once
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "sim/world.hpp"

namespace bench {

using Clock = std::chrono::steady_clock;
inline double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// ---- packed beds (beds.cpp) ------------------------------------------------

// A bed stepped `steps` times after one warm-up step. Times are per step.
struct BedRun {
  std::size_t particles = 0, contacts = 0;
  int threads = 1, iterations = 0, steps = 0;  // iterations: the cap asked for
  double solver_iterations = 0;                 // mean per step, as run
  double contact_iterations = 0;                // mean per step: contacts x iterations
  ces::StageTimes stages;  // mean per step, as the World timed them
  double wall = 0;         // mean per step, timed around World::step()
  // Contact-iterations (one contact in one solver iteration) per second of
  // solve time per thread.
  double rate_per_core() const;
  double other() const { return wall - stages.total(); }  // untimed by the stages
};

// Builds a simple-cubic bed of n touching 1 mm spheres on a plane (about 3
// contacts per sphere) and steps it, put back to its start after every step;
// `work` (contact-iterations) sets the step count, from 2 to 200.
BedRun measure_bed(std::size_t n, int threads, int iterations, double work);

// The pieces: a model (ground plane, one sphere shape, APGD at `iterations`
// with tolerance 0, so every step runs them all: throughput, not convergence)
// and a lattice of n spheres of radius r at a pitch of `pitch` diameters
// (1: touching; 1.5: a 0.5-diameter gap, beyond the contact envelope).
std::shared_ptr<ces::Model> bed_model(int iterations, int threads);
void fill_bed(ces::World& w, std::size_t n, double r, double pitch);

// ---- memory (memory.cpp) ---------------------------------------------------

struct MemoryProbe {
  std::size_t particles = 0, contacts = 0;
  bool packed = true;
  double base = 0;  // bytes resident before the bed is built (VmRSS)
  double peak = 0;  // bytes, peak resident over the run (VmHWM)
  bool ok = false;
  double growth() const { return peak - base; }
};

// Runs `exe --probe-memory N packed|sparse` in a fresh process, so the peak is
// that bed's alone, and reads what it prints.
MemoryProbe probe_memory(const std::string& exe, std::size_t n, bool packed, int threads);
// The child's side: build, step, print "particles contacts base peak".
int run_memory_probe(std::size_t n, bool packed, int threads);

// The machine's memory bandwidth: STREAM's triad a = b + 3 c over three
// 64 MiB arrays (twice the L3), best of 5, counted as STREAM counts it
// (24 bytes an element). The bench takes it at its start and end: a VM's
// bandwidth moves with its neighbours, and the beds past the cache with it,
// so two runs' solver figures compare only beside their bandwidths.
struct Bandwidth {
  double one = 0, two = 0;  // bytes/s at 1 and 2 threads (0: not measured)
};
double measure_triad(int threads);
Bandwidth measure_bandwidth(int procs);

// ---- broadphase (broadphase.cpp) -------------------------------------------

struct BroadphaseRun {
  std::size_t particles = 0;
  std::size_t grid_pairs = 0, bullet_pairs = 0;
  double grid = 0, bullet = 0;  // seconds per update
  bool have_bullet = false;
};
BroadphaseRun measure_broadphase(std::size_t n);

// ---- a scene, end to end (scene.cpp) ---------------------------------------

struct SceneRun {
  std::string path, name, out_dir;
  std::vector<std::string> sets;  // --set overrides given to ces-sim
  int exit_code = -1;
  bool complete = false;
  int threads = 0;
  double simulated = 0;
  double process_wall = 0;  // seconds, measured around the process
  double wall_total = 0;    // seconds, as summary.json reports it
  std::vector<std::pair<std::string, double>> stages;  // summary.json wall_time_s.stages
  double iterations_mean = 0;
  std::size_t steps = 0, particles_max = 0, contacts_max = 0;
  // Bytes: its summary's peak_memory_mib, the process's VmHWM. (wait4's
  // ru_maxrss would also count the bench's pages the child held between
  // fork and exec.)
  double peak_rss = 0;
  std::string error;
  double stage(const std::string& name) const;
  double step_seconds() const;  // every stage but output
};
SceneRun run_scene(const std::string& ces_sim, const std::string& scene,
                   const std::vector<std::string>& sets, const std::string& out_dir, int threads);

// ---- processes (process.cpp) -----------------------------------------------

struct ProcessResult {
  int exit_code = -1;  // -1: could not start or killed
  std::string out;     // stdout, when captured
  double wall = 0;     // seconds
};
ProcessResult run_process(const std::vector<std::string>& argv, bool capture);
std::string self_exe();

// ---- results and their outputs (output.cpp) --------------------------------

// CPU seconds used by every process on the machine and by this one with its
// children: over the bench, their difference is what others took.
struct CpuClock {
  double all = 0, own = 0;
};
CpuClock read_cpu_clock();

struct Machine {
  std::string cpu, build, date;
  int procs = 1;
  double mem_gib = 0;
  CpuClock cpu_start;
  double others_cores = 0;  // CPU seconds others took over the bench, per second
};
Machine read_machine();

struct Results {
  bool quick = false;
  Machine machine;
  int iterations = 0;
  std::vector<BedRun> sweep;   // 1 thread, contacts ~1e3 .. ~1e6
  BedRun one, two;             // the speed-up point (~1e5 contacts), 1 and 2 threads
  std::vector<BedRun> rounds_one, rounds_two;  // its rounds (one, two: medians)
  std::vector<BedRun> growth;  // N, 2N, 4N, ... at 1 thread
  MemoryProbe sparse, packed, million;
  bool million_measured = false;
  std::vector<BroadphaseRun> broadphase;
  std::optional<SceneRun> scene;
  Bandwidth bandwidth_start, bandwidth_end;
  double seconds = 0;  // the whole bench
};
void write_csv(const Results& r, const std::string& path);
std::string report(const Results& r);

}  // namespace bench
