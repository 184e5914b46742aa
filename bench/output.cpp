// The CSV (one row per figure: measure, particles, contacts, threads, value,
// unit) and the report against the performance targets (bench/README.md).
#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <set>
#include <sstream>

#include "bench.hpp"

#ifndef CES_BENCH_BUILD_TYPE
#define CES_BENCH_BUILD_TYPE "unknown"
#endif

namespace bench {

// ---- the machine -----------------------------------------------------------

namespace {

std::string file_value(const char* path, const std::string& key) {
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key, 0) == 0) {
      const std::size_t colon = line.find(':');
      if (colon == std::string::npos) return "";
      return line.substr(line.find_first_not_of(" \t", colon + 1));
    }
  return "";
}

std::string utc_now() {
  char s[32];
  const std::time_t t = std::time(nullptr);
  std::strftime(s, sizeof s, "%Y-%m-%d %H:%M UTC", std::gmtime(&t));
  return s;
}

}  // namespace

CpuClock read_cpu_clock() {
  CpuClock c;
  std::ifstream in("/proc/stat");
  std::string cpu;
  in >> cpu;  // the first line sums all CPUs
  // user nice system idle iowait irq softirq steal: all but idle and iowait
  // were taken by someone (steal: by other guests of the host).
  double ticks[8] = {};
  for (double& t : ticks) in >> t;
  const double hz = double(sysconf(_SC_CLK_TCK));
  c.all = (ticks[0] + ticks[1] + ticks[2] + ticks[5] + ticks[6] + ticks[7]) / hz;
  for (const int who : {RUSAGE_SELF, RUSAGE_CHILDREN}) {
    rusage u{};
    getrusage(who, &u);
    c.own += double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
             1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
  }
  return c;
}

Machine read_machine() {
  Machine m;
  m.cpu = file_value("/proc/cpuinfo", "model name");
  std::ifstream l3("/sys/devices/system/cpu/cpu0/cache/index3/size");
  if (std::string size; l3 >> size) m.cpu += " (L3 " + size + ")";
  m.procs = omp_get_num_procs();
  const std::string kb = file_value("/proc/meminfo", "MemTotal");
  m.mem_gib = kb.empty() ? 0 : std::stod(kb) / (1024.0 * 1024.0);
  m.build = std::string(CES_BENCH_BUILD_TYPE) + ", GCC " + __VERSION__;
#ifndef __OPTIMIZE__
  m.build += " (NOT OPTIMIZED: figures meaningless)";
#endif
  const char* wait = std::getenv("OMP_WAIT_POLICY");
  m.build += std::string(", OMP_WAIT_POLICY=") + (wait ? wait : "(unset)");
  m.date = utc_now();
  m.cpu_start = read_cpu_clock();
  return m;
}

// ---- the CSV ---------------------------------------------------------------

namespace {

struct Csv {
  std::ofstream out;
  void row(const std::string& measure, std::size_t particles, std::size_t contacts, int threads,
           double value, const char* unit) {
    char line[256];
    std::snprintf(line, sizeof line, "%s,%zu,%zu,%d,%.6g,%s\n", measure.c_str(), particles,
                  contacts, threads, value, unit);
    out << line;
  }
};

// The speed-up, whole step and solve: the median over the rounds of each
// round's ratio. A round's 1- and 2-thread beds run back to back, in one
// phase of the machine; the rounds are spread over the bench.
struct Speedups {
  double step = 0, solve = 0;
};

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v.size() % 2 ? v[v.size() / 2]
                                      : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

Speedups speedups(const Results& r) {
  std::vector<double> step, solve;
  for (std::size_t i = 0; i < r.rounds_two.size(); ++i) {
    step.push_back(r.rounds_one[i].wall / r.rounds_two[i].wall);
    solve.push_back(r.rounds_one[i].stages[ces::Stage::Solve] / r.rounds_two[i].stages[ces::Stage::Solve]);
  }
  return {median_of(step), median_of(solve)};
}

void bed_rows(Csv& c, const BedRun& b) {
  auto row = [&](const char* m, double v, const char* unit) {
    c.row(m, b.particles, b.contacts, b.threads, v, unit);
  };
  row("solver_contact_iterations_per_s_per_core", b.rate_per_core(), "1/s");
  row("solver_iterations_per_step", b.solver_iterations, "1");
  row("stage_broadphase", b.stages[ces::Stage::Broadphase], "s/step");
  row("stage_narrowphase", b.stages[ces::Stage::Narrowphase], "s/step");
  row("stage_assemble", b.stages[ces::Stage::Assemble], "s/step");
  row("stage_solve", b.stages[ces::Stage::Solve], "s/step");
  row("stage_safeguards", b.stages[ces::Stage::Safeguards], "s/step");
  row("stage_integrate", b.stages[ces::Stage::Integrate], "s/step");
  row("stage_other", b.other(), "s/step");
  row("step_total", b.wall, "s/step");
  row("step_over_solve", b.wall / b.stages[ces::Stage::Solve], "ratio");
}

std::vector<const BedRun*> distinct_beds(const Results& r) {
  std::vector<const BedRun*> all;
  std::set<std::pair<std::size_t, int>> seen;
  auto add = [&](const BedRun& b) {
    if (b.steps > 0 && seen.insert({b.particles, b.threads}).second) all.push_back(&b);
  };
  for (const BedRun& b : r.sweep) add(b);
  add(r.one);
  add(r.two);
  for (const BedRun& b : r.growth) add(b);
  return all;
}

void growth_rows(Csv& c, const std::vector<BedRun>& g) {
  for (std::size_t i = 0; i < g.size(); ++i) {
    const BedRun& b = g[i];
    c.row("step_per_particle", b.particles, b.contacts, b.threads, b.wall / b.particles, "s");
    if (i == 0) continue;
    const BedRun& a = g[i - 1];
    c.row("growth_step_per_particle", b.particles, b.contacts, b.threads,
          (b.wall / b.particles) / (a.wall / a.particles), "ratio");
    c.row("growth_solve_per_particle", b.particles, b.contacts, b.threads,
          (b.stages[ces::Stage::Solve] / b.particles) / (a.stages[ces::Stage::Solve] / a.particles), "ratio");
  }
}

double bytes_per_particle(const Results& r) { return r.sparse.growth() / r.sparse.particles; }
double bytes_per_contact(const Results& r) {
  return (r.packed.growth() - r.sparse.growth()) / double(r.packed.contacts);
}

void memory_rows(Csv& c, const Results& r, int threads) {
  const MemoryProbe &s = r.sparse, &p = r.packed, &m = r.million;
  c.row("memory_peak_sparse", s.particles, s.contacts, threads, s.peak, "B");
  c.row("memory_peak_packed", p.particles, p.contacts, threads, p.peak, "B");
  c.row("memory_bytes_per_particle", s.particles, s.contacts, threads, bytes_per_particle(r),
        "B/particle");
  c.row("memory_bytes_per_contact", p.particles, p.contacts, threads, bytes_per_contact(r),
        "B/contact");
  c.row(r.million_measured ? "memory_peak_1e6" : "memory_peak_1e6_extrapolated", m.particles,
        m.contacts, threads, m.peak, "B");
}

void scene_rows(Csv& c, const SceneRun& s) {
  auto row = [&](const std::string& m, double v, const char* unit) {
    c.row(m, s.particles_max, s.contacts_max, s.threads, v, unit);
  };
  row("scene_process_wall", s.process_wall, "s");
  row("scene_wall_total", s.wall_total, "s");
  for (const auto& [name, seconds] : s.stages) row("scene_stage_" + name, seconds, "s");
  row("scene_step_over_solve", s.step_seconds() / s.stage("solve"), "ratio");
  row("scene_simulated_time", s.simulated, "s");
  row("scene_iterations_mean", s.iterations_mean, "1");
  row("scene_peak_rss", s.peak_rss, "B");
}

}  // namespace

void write_csv(const Results& r, const std::string& path) {
  Csv c{std::ofstream(path)};
  c.out << "measure,particles,contacts,threads,value,unit\n";
  for (const BedRun* b : distinct_beds(r)) bed_rows(c, *b);
  if (r.two.steps > 0) {
    const Speedups up = speedups(r);
    c.row("speedup_solve_1_to_2", r.two.particles, r.two.contacts, 2, up.solve, "ratio");
    c.row("speedup_step_1_to_2", r.two.particles, r.two.contacts, 2, up.step, "ratio");
  }
  growth_rows(c, r.growth);
  if (r.sparse.ok && r.packed.ok) memory_rows(c, r, r.machine.procs);
  for (const BroadphaseRun& b : r.broadphase) {
    c.row("broadphase_grid", b.particles, b.grid_pairs, 1, b.grid, "s");
    if (b.have_bullet)
      c.row("broadphase_bullet_dbvt", b.particles, b.bullet_pairs, 1, b.bullet, "s");
  }
  if (r.scene && r.scene->wall_total > 0) scene_rows(c, *r.scene);
  for (const auto& [name, bw] : {std::pair{"memory_bandwidth_triad_start", r.bandwidth_start},
                                 std::pair{"memory_bandwidth_triad_end", r.bandwidth_end}}) {
    c.row(name, 0, 0, 1, bw.one, "B/s");
    if (bw.two > 0) c.row(name, 0, 0, 2, bw.two, "B/s");
  }
  c.row("bench_wall", 0, 0, r.machine.procs, r.seconds, "s");
  c.row("others_cores", 0, 0, r.machine.procs, r.machine.others_cores, "cores");
}

// ---- the report ------------------------------------------------------------

namespace {

std::string f(const char* format, double v) {
  char s[64];
  std::snprintf(s, sizeof s, format, v);
  return s;
}
std::string mega(double v) { return f("%.1f M", v / 1e6); }
std::string ms(double s) { return f(s >= 0.1 ? "%.0f" : "%.3g", s * 1e3); }
std::string gib(double b) { return f("%.2f GiB", b / (1024.0 * 1024.0 * 1024.0)); }
std::string count(std::size_t n) { return std::to_string(n); }
std::string verdict(bool met) { return met ? "met" : "**NOT met**"; }

bool scene_full(const Results& r) {
  return r.scene && r.scene->sets.empty() && r.scene->complete && r.scene->wall_total > 0;
}

// Why the scene's targets cannot be judged.
std::string scene_missing(const Results& r) {
  if (!r.scene) return "not run";
  if (!r.scene->error.empty()) return "failed: " + r.scene->error;
  if (!r.scene->sets.empty()) return "shortened run only";
  return "incomplete run";
}

void header(std::ostream& o, const Results& r) {
  const Machine& m = r.machine;
  o << "# ces-sim bench, " << m.date << (r.quick ? " (--quick)" : "") << "\n\n"
    << "Machine: " << m.cpu << ", " << m.procs << " CPUs, " << f("%.0f", m.mem_gib)
    << " GiB. Build: " << m.build << ". The bench took " << f("%.0f", r.seconds)
    << " s; other processes (and other guests of the host) took " << f("%.2f", m.others_cores)
    << " cores on average meanwhile.\n";
  auto bandwidth = [&](const Bandwidth& bw) {
    return f("%.1f", bw.one / 1e9) + " GB/s on 1 thread" +
           (bw.two > 0 ? ", " + f("%.1f", bw.two / 1e9) + " on 2" : std::string());
  };
  o << "\nMemory bandwidth (STREAM triad over 3 x 64 MiB, best of 5), which moves with the "
       "VM's neighbours and the beds past the cache with it: "
    << bandwidth(r.bandwidth_start) << " at the start, " << bandwidth(r.bandwidth_end)
    << " at the end.\n";
  if (m.others_cores > 0.1)
    o << "\n**The machine was busy: figures are not representative. Re-run on a quiet "
         "machine.**\n";
  o << "\nBeds: simple-cubic packs of touching 1 mm spheres on a plane (about 3 contacts per "
       "sphere), APGD at "
    << r.iterations
    << " iterations per step with the tolerance at 0 (throughput, not convergence). A "
       "contact-iteration is one contact in one solver iteration.\n";
}

// The targets (bench/README.md), each used for its label and its verdict.
constexpr double kRatePerCore = 50e6;  // contact-iterations per second per core at 1e5 contacts
constexpr double kStepOverSolve = 1.5;
constexpr double kSpeedup = 1.8;                            // 1 to 2 threads, whole step
constexpr double kSceneSeconds = 120;                       // ces_pcb, the process run to its end
constexpr double kMillionBytes = 4.0 * 1024 * 1024 * 1024;  // peak, 1e6 particles packed

const std::string kStepTarget = "whole step <= " + f("%g", kStepOverSolve) + "x solve";
const std::string kMemoryTarget = "1e6 particles < " + f("%g", kMillionBytes / (1 << 30)) + " GiB";

void row(std::ostream& o, const std::string& target, const std::string& figure,
         const std::string& status) {
  o << "| " << target << " | " << figure << " | " << status << " |\n";
}

void solver_target(std::ostream& o, const Results& r) {
  const double rate = r.one.rate_per_core();
  std::string figure = mega(rate) + " (1 thread, " + count(r.one.contacts) + " contacts";
  if (r.two.steps > 0) figure += "; 2 threads: " + mega(r.two.rate_per_core()) + "/core";
  row(o, "solver >= " + f("%g", kRatePerCore / 1e6) + " M contact-it/s/core at 1e5 contacts",
      figure + ")", verdict(rate >= kRatePerCore));
}

void step_target(std::ostream& o, const Results& r) {
  const std::string bed = f("%.2f", r.one.wall / r.one.stages[ces::Stage::Solve]) + "x";
  if (!scene_full(r)) {
    const std::string at = " at a fixed " + std::to_string(r.iterations) + " iterations";
    row(o, kStepTarget, "bed: " + bed + at, "not judged: scene " + scene_missing(r));
    return;
  }
  const double k = r.scene->step_seconds() / r.scene->stage("solve");
  row(o, kStepTarget, f("%.2f", k) + "x in " + r.scene->name + " (bed: " + bed + ")",
      verdict(k <= kStepOverSolve));
}

void speedup_target(std::ostream& o, const Results& r) {
  const std::string target = "1-to-2-thread speed-up >= " + f("%g", kSpeedup);
  if (r.two.steps == 0) {
    row(o, target, "one CPU only", "not judged");
    return;
  }
  const Speedups up = speedups(r);
  row(o, target,
      "whole step " + f("%.2f", up.step) + ", solve " + f("%.2f", up.solve) + " (" +
          count(r.one.contacts) + " contacts; medians of " + std::to_string(r.rounds_two.size()) +
          " rounds spread over the bench)",
      verdict(up.step >= kSpeedup));
}

// The rounds the 1e5 bed's figures are the medians of.
void rounds(std::ostream& o, const Results& r) {
  if (r.rounds_one.empty()) return;
  std::string rates_one, rates_two, ratios;
  for (std::size_t i = 0; i < r.rounds_two.size(); ++i) {
    const BedRun &one = r.rounds_one[i], &two = r.rounds_two[i];
    const std::string sep = i ? ", " : "";
    rates_one += sep + mega(one.rate_per_core());
    rates_two += sep + mega(two.rate_per_core());
    ratios += sep + f("%.2f", one.wall / two.wall);
  }
  o << "\nThe " << count(r.one.contacts) << "-contact bed, measured in " << r.rounds_two.size()
    << " rounds at 1 and 2 threads back to back, one round between each two sections of the "
       "bench (the figures above are the medians): "
    << rates_one << " on 1 thread; " << rates_two << " per core on 2; whole-step speed-ups "
    << ratios << ".\n";
}

void scene_target(std::ostream& o, const Results& r) {
  const std::string limit = " < " + f("%g", kSceneSeconds / 60) + " min";
  if (!scene_full(r)) {
    row(o, "ces_pcb, run to its end," + limit, scene_missing(r), "not judged");
    return;
  }
  // The simulated time, not time.end: a scene run until its particles are
  // collected ends before its time.end, which is only a cap.
  const SceneRun& s = *r.scene;
  row(o, s.name + " (" + f("%.3g", s.simulated) + " s simulated)" + limit,
      f("%.0f", s.process_wall) + " s", verdict(s.process_wall < kSceneSeconds));
}

void memory_target(std::ostream& o, const Results& r) {
  const MemoryProbe& m = r.million;
  if (!m.ok) {
    row(o, kMemoryTarget, "the memory probe failed", "not judged");
    return;
  }
  row(o, kMemoryTarget,
      gib(m.peak) + " peak, packed bed, " + count(m.contacts) + " contacts" +
          (r.million_measured ? " (measured)" : " (**extrapolated** from the probes below)"),
      verdict(m.peak <= kMillionBytes));
}

void target_rows(std::ostream& o, const Results& r) {
  o << "\n## Targets\n\n| target | figure | status |\n|---|---|---|\n";
  solver_target(o, r);
  step_target(o, r);
  speedup_target(o, r);
  scene_target(o, r);
  memory_target(o, r);
  rounds(o, r);
}

void sweep_table(std::ostream& o, const Results& r) {
  o << "\n## Solver throughput and time per step by stage (ms) against contact count\n\n"
       "| spheres | contacts | M contact-it/s/core | broad | narrow | assemble | solve | "
       "safeguards | integrate | other | step (ms) | step/solve |\n"
       "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  std::vector<const BedRun*> rows;
  for (const BedRun& b : r.sweep) rows.push_back(&b);
  if (r.two.steps > 0) rows.push_back(&r.two);
  for (const BedRun* b : rows) {
    const ces::StageTimes& s = b->stages;
    o << "| " << b->particles << (b->threads > 1 ? " (2 threads)" : "") << " | " << b->contacts
      << " | " << f("%.1f", b->rate_per_core() / 1e6) << " | " << ms(s[ces::Stage::Broadphase]) << " | "
      << ms(s[ces::Stage::Narrowphase]) << " | " << ms(s[ces::Stage::Assemble]) << " | " << ms(s[ces::Stage::Solve]) << " | "
      << ms(s[ces::Stage::Safeguards]) << " | " << ms(s[ces::Stage::Integrate]) << " | "
      << ms(b->other()) << " | " << ms(b->wall) << " | "
      << f("%.2f", b->wall / s[ces::Stage::Solve]) << " |\n";
  }
  o << "\nOne thread unless marked. Other: the step's wall time not in any stage.\n";
}

void growth_table(std::ostream& o, const Results& r) {
  o << "\n## Cost as the particle count doubles (1 thread; linear: ratio 1)\n\n"
       "| spheres | step us/particle | ratio to half | solve ratio to half |\n|---|---|---|---|\n";
  for (std::size_t i = 0; i < r.growth.size(); ++i) {
    const BedRun& b = r.growth[i];
    o << "| " << b.particles << " | " << f("%.3g", 1e6 * b.wall / b.particles) << " | ";
    if (i == 0) {
      o << "- | - |\n";
      continue;
    }
    const BedRun& a = r.growth[i - 1];
    o << f("%.2f", (b.wall / b.particles) / (a.wall / a.particles)) << " | "
      << f("%.2f", (b.stages[ces::Stage::Solve] / b.particles) / (a.stages[ces::Stage::Solve] / a.particles)) << " |\n";
  }
}

void memory_section(std::ostream& o, const Results& r) {
  if (!r.sparse.ok || !r.packed.ok) {
    o << "\n## Memory\n\nThe memory probes failed.\n";
    return;
  }
  o << "\n## Memory (peak resident set of a fresh process, minus its size before the bed)\n\n"
    << "- per particle: " << f("%.0f", bytes_per_particle(r)) << " B (" << r.sparse.particles
    << " spheres apart, no contacts)\n"
    << "- per contact: " << f("%.0f", bytes_per_contact(r)) << " B (the same count packed, "
    << r.packed.contacts << " contacts, minus the above)\n"
    << "- 1e6 spheres packed: " << gib(r.million.peak) << " peak resident"
    << (r.million_measured ? ", measured"
                           : ", extrapolated: base + N x per particle + contacts x per contact")
    << "\n";
}

void broadphase_table(std::ostream& o, const Results& r) {
  o << "\n## Broadphase on a loose random cloud (ms per update)\n\n"
       "| spheres | grid, rebuilt | Bullet dbvt, incremental |\n|---|---|---|\n";
  for (const BroadphaseRun& b : r.broadphase)
    o << "| " << b.particles << " | " << ms(b.grid) << " | "
      << (b.have_bullet ? ms(b.bullet) : std::string("-")) << " |\n";
}

void scene_section(std::ostream& o, const SceneRun& s) {
  o << "\n## Scene " << s.path;
  for (const std::string& set : s.sets) o << " --set " << set;
  o << " (" << s.threads << " threads)\n\n";
  if (!s.error.empty()) o << "Error: " << s.error << "\n\n";
  if (s.wall_total <= 0) return;
  o << f("%.3g", s.simulated) << " s simulated in " << s.steps << " steps: "
    << f("%.1f", s.process_wall) << " s process wall, " << f("%.1f", s.wall_total)
    << " s in the run loop; up to " << s.particles_max << " particles and " << s.contacts_max
    << " contacts; " << f("%.1f", s.iterations_mean) << " solver iterations per step on average; "
    << "peak resident " << gib(s.peak_rss) << ".\n\n| stage | s | share |\n|---|---|---|\n";
  for (const auto& [name, seconds] : s.stages)
    o << "| " << name << " | " << f("%.2f", seconds) << " | "
      << f("%.0f %%", 100 * seconds / s.wall_total) << " |\n";
  o << "\nStep (all stages but output) / solve: " << f("%.2f", s.step_seconds() / s.stage("solve"))
    << "; whole run loop / solve: " << f("%.2f", s.wall_total / s.stage("solve")) << ".\n";
}

}  // namespace

std::string report(const Results& r) {
  std::ostringstream o;
  header(o, r);
  target_rows(o, r);
  sweep_table(o, r);
  growth_table(o, r);
  memory_section(o, r);
  broadphase_table(o, r);
  if (r.scene) scene_section(o, *r.scene);
  return o.str();
}

}  // namespace bench
