// ces-sim: the command line. Its commands and options are those declared
// in main() (and study's in add_study_command), its exit codes kExitCodes:
// both are what --help prints, and what the README documents.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <limits>
#include <new>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/path.hpp"
#include "dynamics/isa.hpp"
#include "output/compare.hpp"
#include "output/files.hpp"
#include "scene/scene.hpp"
#include "scene/schema_doc.hpp"
#include "sim/run.hpp"
#include "study/study.hpp"

namespace {

constexpr int kSuccess = 0, kMismatch = 1, kBadInput = 2, kRunFailed = 3, kInternalError = 4;

constexpr const char* kExitCodes =
    "Exit codes:\n"
    "  0  success; compare: the folders agree\n"
    "  1  compare: the folders differ\n"
    "  2  bad input (scene diagnostics on stderr, one per line; bad arguments; tables compare\n"
    "     cannot read; a checkpoint resume refuses)\n"
    "  3  run failed or interrupted (partial outputs kept, summary.json complete: false), or\n"
    "     out of memory\n"
    "  4  internal error\n";

// A command-line mistake the parser cannot see (a --set without '=').
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Args {
  std::string scene;
  std::string out_dir;
  std::vector<std::string> sets;
  std::vector<std::string> unsets;
  std::vector<std::string> include_paths;
  std::optional<std::uint64_t> seed;
  std::optional<int> threads;
  bool quiet = false;
  bool markdown = false;  // schema: the Markdown reference instead of the JSON Schema
  std::string dir_a, dir_b;
  ces::output::CompareOptions tolerances;
};

// Numbers on the command line, checked as written: CLI11's own checks let
// NaN through, wrap a negative count into a huge one, read a leading 0 as
// octal (and 0x as hex), and print their bounds with 310 digits.
constexpr std::uint64_t kNoMost = std::numeric_limits<std::uint64_t>::max();

// A whole number in decimal digits from `least` to `most`.
CLI::Validator whole_number(std::uint64_t least, std::uint64_t most = kNoMost) {
  const std::string what =
      "a whole number " + (most == kNoMost
                               ? ">= " + std::to_string(least)
                               : "from " + std::to_string(least) + " to " + std::to_string(most));
  return CLI::Validator(
      [least, most, what](std::string& text) -> std::string {
        std::uint64_t n = 0;
        const char* end = text.data() + text.size();
        const auto [at, error] = std::from_chars(text.data(), end, n);
        const bool octal_looking = text.size() > 1 && text[0] == '0';
        const bool ok =
            error == std::errc() && at == end && !octal_looking && n >= least && n <= most;
        return ok ? "" : "got '" + text + "', expected " + what;
      },
      what);
}

// A finite number at least `least`.
CLI::Validator number_at_least(double least) {
  const std::string what = "a number >= " + std::to_string(int(least));
  return CLI::Validator(
      [least, what](std::string& text) -> std::string {
        char* end = nullptr;
        const double x = std::strtod(text.c_str(), &end);
        const bool ok = end != text.c_str() && *end == '\0' && std::isfinite(x) && x >= least;
        return ok ? "" : "got '" + text + "', expected " + what;
      },
      what);
}

// An output folder: an empty one would silently mean the scene's own.
const CLI::Validator kFolder(
    [](std::string& text) { return text.empty() ? "got '', expected a folder" : ""; }, "DIR");

// Whether the word after `word` is its value ("-o", "--threads", "-qo"):
// not after a flag, a value written in ("--threads=2", "-odir"), or an
// option CLI11 will refuse.
bool takes_next(const CLI::App& app, const std::string& word) {
  if (word.find('=') != std::string::npos) return false;
  if (word.rfind("--", 0) == 0) {
    const CLI::Option* option = app.get_option_no_throw(word);
    return option && option->get_items_expected_min() > 0;
  }
  for (std::size_t k = 1; k < word.size(); ++k) {  // "-qo": flags, then perhaps one with a value
    const CLI::Option* option = app.get_option_no_throw(std::string("-") + word[k]);
    if (!option) return false;
    if (option->get_items_expected_min() > 0) return k + 1 == word.size();
  }
  return false;
}

// The first word on the command line that is neither an option nor an
// option's value, read as CLI11 reads it: the command, or the scene. (Every
// option takes at most one value: add_scene_options.)
std::string first_word(const CLI::App& app, int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word == "--") return i + 1 < argc ? argv[i + 1] : "";
    if (word.empty() || word.front() != '-') return word;
    if (takes_next(app, word)) ++i;  // its value
  }
  return "";
}

// A first word that is neither a command nor a file is a mistyped command
// more often than a missing scene ("valdate s.yaml"); CLI11 alone would
// take it as the scene and complain about what follows.
std::optional<std::string> unknown_command(const CLI::App& app, int argc, char** argv) {
  std::vector<std::string> commands;
  for (const CLI::App* command : app.get_subcommands([](const CLI::App*) { return true; }))
    commands.push_back(command->get_name());
  const std::string word = first_word(app, argc, argv);
  const bool name_like =
      !word.empty() && word.front() != '-' && word.find_first_of("./\\") == std::string::npos;
  std::error_code ec;
  if (!name_like || std::filesystem::exists(word, ec)) return std::nullopt;
  if (std::find(commands.begin(), commands.end(), word) != commands.end()) return std::nullopt;
  std::string names;
  for (const std::string& name : commands) names += (names.empty() ? "" : ", ") + name;
  return "'" + word + "' is neither a command (" + names + ") nor a scene file";
}

// The repeatable options take one value each time they are given: CLI11
// would otherwise take every word up to the next option, the scene too
// ("--set k=v scene.yaml").
void add_scene_options(CLI::App& app, Args& args) {
  app.add_option("--set", args.sets, "Override a scene value before validation: key.path=value")
      ->type_name("K=V")
      ->allow_extra_args(false);
  app.add_option("--unset", args.unsets,
                 "Remove a scene key or list item before the --set values: key.path")
      ->type_name("K")
      ->allow_extra_args(false);
  app.add_option("--seed", args.seed, "Random seed (wins over the scene's)")
      ->check(whole_number(0, std::numeric_limits<std::int64_t>::max()));  // the scene's bound
  app.add_option("--threads", args.threads, "Worker threads")
      ->check(whole_number(1, 1024));
  app.add_option("--include-path", args.include_paths,
                 "A folder includes may come from besides the scene's own (repeatable)")
      ->type_name("DIR")
      ->check(CLI::ExistingDirectory)
      ->allow_extra_args(false);
}

ces::scene::LoadOptions load_options(const Args& args) {
  ces::scene::LoadOptions o;
  for (const std::string& s : args.sets) {
    const auto eq = s.find('=');
    if (eq == std::string::npos || eq == 0)
      throw UsageError("--set " + s + ": expected key.path=value");
    o.overrides.emplace_back(s.substr(0, eq), s.substr(eq + 1));
  }
  o.removals = args.unsets;
  o.seed = args.seed;
  o.threads = args.threads;
  o.include_paths = args.include_paths;
  return o;
}

// Seconds of wall time between progress lines when stderr is not a
// terminal (a batch job's log): CES_PROGRESS_INTERVAL, else 10.
double log_progress_interval() {
  const char* text = std::getenv("CES_PROGRESS_INTERVAL");
  if (text == nullptr) return 10.0;
  char* end = nullptr;
  const double seconds = std::strtod(text, &end);
  if (end == text || *end != '\0' || !(seconds > 0.0) || !std::isfinite(seconds))
    throw UsageError(std::string("CES_PROGRESS_INTERVAL=") + text +
                     ": expected a number of seconds above 0");
  return seconds;
}

// Loads the scene; its warnings go to stderr, one per line.
ces::Simulation load_scene(const Args& args) {
  std::vector<ces::scene::Diagnostic> warnings;
  ces::scene::LoadOptions options = load_options(args);
  options.warnings = &warnings;
  ces::Simulation sim = ces::scene::load(args.scene, options);
  for (const ces::scene::Diagnostic& w : warnings) std::fprintf(stderr, "%s\n", w.str().c_str());
  return sim;
}

ces::RunOptions run_options(const Args& args) {
  ces::RunOptions options;
  options.out_dir = args.out_dir;
  options.quiet = args.quiet;
  options.progress = !args.quiet && ::isatty(::fileno(stderr));
  options.progress_interval = args.quiet ? 0.0 : log_progress_interval();
  return options;
}

// Exit code and message of a run that ended.
int ended(const ces::RunResult& result) {
  if (result.complete) return kSuccess;
  std::fprintf(stderr, "ces-sim: run incomplete: %s\nces-sim: its outputs so far are in %s\n",
               result.reason.c_str(), result.out_dir.c_str());
  if (std::filesystem::exists(std::filesystem::path(result.out_dir) / "checkpoint.bin"))
    std::fprintf(stderr, "ces-sim: to continue it from its last checkpoint: ces-sim resume %s\n",
                 std::filesystem::path(result.out_dir).parent_path().c_str());
  return kRunFailed;
}

// A file where the output folder goes is the user's to move, not a failed
// run: refused as bad input before the run starts.
void check_out_dir(const Args& args, const ces::Simulation& sim) {
  const bool given = !args.out_dir.empty();
  const std::filesystem::path dir = given ? args.out_dir : sim.output.dir;
  if (const auto file = ces::file_in_the_way(dir))
    throw UsageError(std::string(given ? "-o " : "output.dir ") + dir.string() + ": " +
                     file->string() +
                     " is not a folder, expected a folder's path (made if missing)");
}

int run_scene(const Args& args) {
  const ces::Simulation sim = load_scene(args);
  check_out_dir(args, sim);
  return ended(ces::run(sim, run_options(args)));
}

// The run's own scene, rebuilt from the checkpoint; --threads may differ
// (the bits do not depend on it).
int resume(const Args& args) {
  ces::Checkpoint c = ces::find_checkpoint(args.dir_a);
  ces::scene::LoadOptions o;
  o.threads = args.threads;
  const ces::Simulation sim = ces::scene::load_text(c.resolved_yaml, c.scene_path, o);
  return ended(ces::resume(sim, std::move(c), args.dir_a, run_options(args)));
}

int validate(const Args& args) {
  load_scene(args);
  std::printf("OK: %s\n", args.scene.c_str());
  return kSuccess;
}

int compare(const Args& args) {
  const ces::output::CompareResult r =
      ces::output::compare_outputs(args.dir_a, args.dir_b, args.tolerances);
  constexpr std::size_t kShown = 50;
  for (std::size_t i = 0; i < r.differences.size() && i < kShown; ++i)
    std::printf("%s\n", r.differences[i].c_str());
  if (r.differences.size() > kShown)
    std::printf("... and %zu more differences\n", r.differences.size() - kShown);
  // What was compared, and what could not be, either way.
  for (const std::string& note : r.notes) std::printf("%s\n", note.c_str());
  if (!r.agree()) {
    std::printf("DIFFER: %zu differences between %s and %s\n", r.differences.size(),
                args.dir_a.c_str(), args.dir_b.c_str());
    return kMismatch;
  }
  std::printf("AGREE: %s and %s\n", args.dir_a.c_str(), args.dir_b.c_str());
  return kSuccess;
}

struct StudyArgs {
  ces::study::Options options;
  std::string scheduler = "local";
  std::vector<std::string> vary;
  std::optional<std::size_t> only_case;
  bool list = false;
};

constexpr const char* kStudyHelp =
    "Cases run as separate processes, in DIR/case_K. A case already complete is not\n"
    "run again, so the same command without --case or --scheduler only measures.\n"
    "  ces-sim study s.yaml --vary time.step=2ms,1ms -o st --scheduler parallel --jobs 8\n"
    "  ces-sim study s.yaml --vary time.step=2ms,1ms -o st --scheduler slurm\n"
    "    # then: sbatch st/study.sbatch, and when the array is done:\n"
    "  ces-sim study s.yaml --vary time.step=2ms,1ms -o st\n";

CLI::App* add_study_command(CLI::App& app, Args& args, StudyArgs& study) {
  CLI::App* cmd = app.add_subcommand(
      "study", "Error against run time: run a scene over a grid of settings, measure each run "
               "against the finest (study.csv, study.svg, a table)");
  cmd->add_option("scene", args.scene, "Scene file")->required();
  add_scene_options(*cmd, args);
  cmd->add_option("--vary", study.vary,
                  "An axis of the grid: key.path=v1,v2,...; keys joined by ':' vary together "
                  "(contact.model:time.step=dvi:1ms,dem:5us)")
      ->type_name("K=V,...")
      ->allow_extra_args(false)
      ->required();
  cmd->add_option("--reference", study.options.reference,
                  "Output folder to measure against (default: the finest case: DVI before DEM, "
                  "smallest time.step, then smallest solver.tolerance and "
                  "solver.penetration_tolerance, then largest solver.max_iterations)");
  cmd->add_option("-o,--out", study.options.out_dir, "Study folder (default: study)")
      ->check(kFolder);
  cmd->add_option("--jobs", study.options.jobs, "Cases at once (default: the number of cores)")
      ->check(whole_number(1, std::numeric_limits<int>::max()));
  cmd->add_option("--case", study.only_case, "Run only case K (see --list-cases)")
      ->check(whole_number(0));
  cmd->add_option("--scheduler", study.scheduler,
                  "Who runs the cases: local (this process, --jobs at a time), parallel (GNU "
                  "parallel, --jobs at a time, then measured here) or slurm (writes a job-array "
                  "script, DIR/study.sbatch, and prints how to submit it)")
      ->check(CLI::IsMember({"local", "parallel", "slurm"}));
  cmd->add_flag("--list-cases", study.list, "Print one line per case: K and its --set list");
  cmd->footer(kStudyHelp);
  return cmd;
}

int study(const Args& args, StudyArgs& study) {
  try {
    ces::study::Options& o = study.options;
    o.scene = args.scene;
    const ces::scene::LoadOptions scene_options = load_options(args);
    o.base_sets = scene_options.overrides;
    o.base_unsets = scene_options.removals;
    o.include_paths = args.include_paths;
    o.seed = args.seed;
    o.threads = args.threads;
    o.only_case = study.only_case;
    o.scheduler = ces::study::parse_scheduler(study.scheduler);
    o.axes = ces::study::parse_axes(study.vary);
    if (study.list) {
      std::fputs(ces::study::list_cases(o).c_str(), stdout);
      return kSuccess;
    }
    return ces::study::run(o);
  } catch (const ces::scene::SceneError& e) {
    for (const ces::scene::Diagnostic& d : e.diagnostics())
      std::fprintf(stderr, "%s\n", d.str().c_str());
    return kBadInput;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "ces-sim: %s\n", e.what());
    return kBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ces-sim: study: %s\n", e.what());
    return kRunFailed;
  }
}

// ces-sim compare DIR_A DIR_B [--tol-...].
CLI::App* add_compare_command(CLI::App& app, Args& args) {
  CLI::App* cmd = app.add_subcommand("compare", "Do two output folders agree within tolerances?");
  cmd->add_option("dir_a", args.dir_a, "Output folder A")->required();
  cmd->add_option("dir_b", args.dir_b, "Output folder B")->required();
  cmd->add_option("--tol-count", args.tolerances.tol_count,
                  "Particles a bin or product may differ by (default 0)")
      ->check(whole_number(0));
  cmd->add_option("--tol-mass", args.tolerances.tol_mass,
                  "Mass difference per cell as a fraction of that material's total over the "
                  "collector's rows of the file (the larger of the two folders'); "
                  "also the absolute tolerance on grade and recovery (default 0)")
      ->check(number_at_least(0));
  cmd->add_option("--tol-w1", args.tolerances.tol_w1_mm,
                  "Wasserstein-1 distance (mm) between landing distributions (default 0)")
      ->check(number_at_least(0));
  return cmd;
}

// ces-sim resume DIR [--threads N] [-q].
CLI::App* add_resume_command(CLI::App& app, Args& args) {
  CLI::App* cmd = app.add_subcommand(
      "resume", "Continue an unfinished run from its checkpoint (scenes with output.checkpoint)");
  cmd->add_option("dir", args.dir_a, "The run's output folder (it holds partial/)")->required();
  cmd->add_option("--threads", args.threads, "Worker threads")->check(whole_number(1, 1024));
  cmd->add_flag("-q,--quiet", args.quiet, "No progress line and no end-of-run report");
  return cmd;
}

// Runs the chosen command; maps failures to the documented exit codes.
int dispatch(const CLI::App& app, const CLI::App* validate_cmd, const CLI::App* schema_cmd,
             const CLI::App* compare_cmd, const CLI::App* resume_cmd, const Args& args) {
  try {
    if (validate_cmd->parsed()) return validate(args);
    if (resume_cmd->parsed()) return resume(args);
    if (schema_cmd->parsed()) {
      const std::string text =
          args.markdown ? ces::scene::schema_markdown() : ces::scene::schema_text();
      std::fputs(text.c_str(), stdout);
      return kSuccess;
    }
    if (compare_cmd->parsed()) return compare(args);
    if (args.scene.empty()) {
      std::cerr << app.help();
      return kBadInput;
    }
    return run_scene(args);
  } catch (const ces::scene::SceneError& e) {
    for (const ces::scene::Diagnostic& d : e.diagnostics())
      std::fprintf(stderr, "%s\n", d.str().c_str());
    return kBadInput;
  } catch (const UsageError& e) {
    std::fprintf(stderr, "ces-sim: %s\n", e.what());
    return kBadInput;
  } catch (const ces::output::IoError& e) {
    std::fprintf(stderr, "ces-sim: %s\n", e.what());
    return compare_cmd->parsed() || resume_cmd->parsed() ? kBadInput : kRunFailed;
  } catch (const ces::CorruptData& e) {
    std::fprintf(stderr, "ces-sim: cannot resume: %s\n", e.what());
    return kBadInput;
  } catch (const std::bad_alloc&) {
    // Outside the steps (which record it in summary.json): setting up, or
    // writing the outputs of a run that ran out.
    std::fprintf(stderr, "ces-sim: out of memory (the machine's, or a limit on this process)\n");
    return kRunFailed;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ces-sim: internal error: %s\n", e.what());
    return kInternalError;
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  CLI::App app{"ces-sim: granular flow in corona electrostatic separators (DVI multibody)"};
  app.set_version_flag("--version", [] {
    return std::string("ces-sim ") + CES_VERSION + "\nsolver kernel: " + ces::kernel_description();
  });
  app.footer(kExitCodes);
  app.add_option("scene", args.scene, "Scene file (.yaml or .json)");
  app.add_option("-o,--out", args.out_dir, "Output folder (default: the scene's output.dir)")
      ->check(kFolder);
  add_scene_options(app, args);
  app.add_flag("-q,--quiet", args.quiet, "No progress line and no end-of-run report");

  CLI::App* validate_cmd =
      app.add_subcommand("validate", "Check a scene; print OK or every problem");
  validate_cmd->add_option("scene", args.scene, "Scene file")->required();
  add_scene_options(*validate_cmd, args);

  CLI::App* schema_cmd = app.add_subcommand("schema", "Print the scene JSON Schema");
  schema_cmd->add_flag("--markdown", args.markdown,
                       "Print the scene format as a Markdown reference (docs/scene-format.md)");

  CLI::App* compare_cmd = add_compare_command(app, args);
  CLI::App* resume_cmd = add_resume_command(app, args);
  StudyArgs study_args;
  CLI::App* study_cmd = add_study_command(app, args, study_args);
  app.require_subcommand(0, 1);

  if (const auto mistake = unknown_command(app, argc, argv)) {
    std::fprintf(stderr, "ces-sim: %s\n", mistake->c_str());
    return kBadInput;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kSuccess : kBadInput;
  }
  try {
    ces::kernel_isa();  // here, not in the first step: a bad CES_KERNEL is an input error
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "ces-sim: %s\n", e.what());
    return kBadInput;
  }
  if (study_cmd->parsed()) return study(args, study_args);
  return dispatch(app, validate_cmd, schema_cmd, compare_cmd, resume_cmd, args);
}
