// `ces-sim study`: error against run time.
//
// A study runs one scene over every combination of --vary axes (each a list
// of --set values), each case a normal run in DIR/case_K, and measures every
// run against a reference: the finest case (DVI before DEM, smallest
// time.step, then smallest solver.tolerance and penetration_tolerance, then
// largest solver.max_iterations) or a given output folder. Errors are what users
// care about: the landing distribution per "material at collector"
// (Wasserstein-1, mm), products' grade and recovery (max abs difference) and
// the particle mass balance. Results: DIR/study.csv, DIR/study.svg (error vs
// wall time, log-log, a line per solver method) and a table on stdout.
//
// Cases run as separate processes (this binary, fork/exec), at most `jobs`
// at once, so they are independent and can also be spread over machines
// with --list-cases / --case K. A case whose folder already holds a complete
// run of the same command line is not run again: after a job array, the
// study command without --case only measures.
#pragma once
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace ces::study {

using Sets = std::vector<std::pair<std::string, std::string>>;

// One --vary. Keys joined by ':' vary together, each value giving one per
// key: "contact.model:time.step=dvi:1ms,dem:5us" is two cases, not four.
// That is how DVI and DEM share a plot: DEM needs a step a hundred times
// smaller, and a grid over both would run each model at the other's steps.
struct Axis {
  std::string key;
  std::vector<std::string> values;
};
// "key.path=v1,v2,..." or "k1:k2=a1:a2,b1:b2"; throws std::invalid_argument.
Axis parse_axis(const std::string& spec);
// The --vary axes, each key on one of them only.
std::vector<Axis> parse_axes(const std::vector<std::string>& specs);

struct Case {
  std::size_t index = 0;
  Sets sets;  // one per axis, in axis order
};
// Every combination; the last axis varies fastest.
std::vector<Case> make_cases(const std::vector<Axis>& axes);

// Who runs the cases: this process (fork/exec, `jobs` at a time), GNU
// parallel (`jobs` at a time, then this process measures), or a Slurm job
// array (a script written into the study folder; measuring is the same
// command without --scheduler, once the array has run).
enum class Scheduler { Local, Parallel, Slurm };
Scheduler parse_scheduler(const std::string& name);  // throws std::invalid_argument

struct Options {
  std::string scene;
  Scheduler scheduler = Scheduler::Local;
  std::vector<Axis> axes;
  Sets base_sets;                      // the user's own --set, applied first
  std::vector<std::string> base_unsets;  // the user's own --unset, before any --set
  std::vector<std::string> include_paths;  // --include-path, passed on to every case
  std::optional<std::uint64_t> seed;
  std::optional<int> threads;          // per case; default: cores / jobs
  std::filesystem::path out_dir = "study";
  std::filesystem::path reference;     // empty: the finest case
  int jobs = 0;                        // 0: the number of cores
  std::optional<std::size_t> only_case;
  std::string binary = "/proc/self/exe";
};

// The ces-sim arguments (after the program name) that run case c, but for
// --threads: each machine picks its own, and results do not depend on it
// (bitwise), so a case run elsewhere still counts as the same case.
std::vector<std::string> case_arguments(const Options& o, const Case& c);

struct Errors {
  std::map<std::string, double> w1_mm;  // per "material at collector"; inf: collected in one only
  double w1_max_mm = 0.0;
  double grade = 0.0,
         recovery = 0.0;  // max abs difference over products, on the reference's main material
  bool balance_exact = false;           // this run's fed = collected + lost + active
};
// Throws output::IoError when a folder lacks a table.
Errors measure(const std::filesystem::path& run, const std::filesystem::path& reference);

// One line per case: "K  --set a=1 --set b=2".
std::string list_cases(const Options& o);
// Runs the study (or only its case o.only_case); returns a process exit code:
// 0 all cases complete, 3 some case failed.
int run(const Options& o);

}  // namespace ces::study
