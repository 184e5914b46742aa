#include "study/study.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <tuple>

#include "common/path.hpp"
#include "model/model.hpp"
#include "output/compare.hpp"
#include "output/files.hpp"
#include "output/format.hpp"
#include "output/report_page.hpp"
#include "scene/scene.hpp"

namespace ces::study {
namespace fs = std::filesystem;
namespace {

struct Row {
  Case c;
  bool complete = false;
  double wall_s = 0.0;
  std::string method;
  std::string contact_model = "dvi";
  double residual_p95 = 0.0;
  long steps_at_cap = 0;
  double penetration_relative = 0.0;
  Errors errors;
};

// One shell command per case, in case order: this binary's study command
// with --case K (which runs the case and marks it done).
std::string case_commands(const Options& o);
// The Slurm job array that runs case_commands(), one task per case.
std::string slurm_script(const Options& o);

constexpr const char* kCaseStamp = "study_case.txt";  // the command line a case ran with

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out(1);
  for (const char c : s) {
    if (c == sep)
      out.emplace_back();
    else
      out.back().push_back(c);
  }
  return out;
}

// A path as every command of a study names it: the same whatever the
// folder the command runs in.
std::string full_path(const fs::path& p) { return absolute_path(p).string(); }

fs::path case_dir(const Options& o, const Case& c) {
  return o.out_dir / ("case_" + std::to_string(c.index));
}

std::string joined(const std::vector<std::string>& args) {
  std::string s;
  for (const std::string& a : args) s += (s.empty() ? "" : " ") + a;
  return s;
}

std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Whether `dir`'s summary.json says its run completed.
bool completed(const fs::path& dir) {
  std::ifstream in(dir / "summary.json");
  const auto j = nlohmann::json::parse(in, nullptr, false);
  return j.is_object() && j.value("complete", false);
}

// A case's scene as its run loads it: the study's overrides and removals,
// the case's values, the seed and the include folders.
Simulation case_scene(const Options& o, const Case& c) {
  scene::LoadOptions lo;
  lo.overrides = o.base_sets;
  lo.removals = o.base_unsets;
  lo.include_paths = o.include_paths;
  lo.seed = o.seed;
  lo.overrides.insert(lo.overrides.end(), c.sets.begin(), c.sets.end());
  return scene::load(o.scene, lo);
}

// A case is done when its folder holds a complete run of the same command
// on the same scene: an edit of the scene file or of a file it includes
// since makes the case run again.
bool already_done(const Options& o, const Case& c) {
  const fs::path dir = case_dir(o, c);
  if (read_file(dir / kCaseStamp) != joined(case_arguments(o, c)) + "\n") return false;
  if (!completed(dir)) return false;
  std::ifstream in(dir / "summary.json");
  const auto j = nlohmann::json::parse(in, nullptr, false);
  const auto* hash = j.contains("scene") && j["scene"].is_object() && j["scene"].contains("hash")
                         ? &j["scene"]["hash"]
                         : nullptr;
  try {
    return hash && hash->is_string() && *hash == case_scene(o, c).scene_hash;
  } catch (const scene::SceneError&) {
    return false;  // the run says what is wrong with it
  }
}

int cores() { return std::max(1, int(std::thread::hardware_concurrency())); }

// Each case's threads: --threads, else its share of the cores (cases share
// them, --jobs at a time).
int case_threads(const Options& o) {
  const int jobs = o.jobs > 0 ? o.jobs : cores();
  return o.threads.value_or(std::max(1, cores() / jobs));
}

pid_t spawn(const Options& o, const Case& c) {
  const fs::path dir = case_dir(o, c);
  fs::create_directories(dir);
  std::vector<std::string> args = case_arguments(o, c);
  args.insert(args.end(), {"--threads", std::to_string(case_threads(o))});
  const std::string log = (dir / "log.txt").string();
  std::vector<char*> argv{const_cast<char*>(o.binary.c_str())};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("study: fork failed");
  if (pid > 0) return pid;
  // Child: only async-signal-safe calls (no allocation) until exec.
  const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    ::dup2(fd, STDOUT_FILENO);
    ::dup2(fd, STDERR_FILENO);
  }
  ::execv(o.binary.c_str(), argv.data());
  ::_exit(127);
}

// Runs the cases not yet done, at most `jobs` processes at once; returns
// whether all of them exited 0.
bool run_cases(const Options& o, const std::vector<Case>& cases) {
  const int jobs = o.jobs > 0 ? o.jobs : cores();
  std::map<pid_t, const Case*> running;
  bool ok = true;
  auto reap = [&] {
    int status = 0;
    const pid_t pid = ::wait(&status);
    if (pid <= 0) return;
    const Case& c = *running.at(pid);
    running.erase(pid);
    const bool success = WIFEXITED(status) && WEXITSTATUS(status) == 0;
    if (success)
      output::write_file_atomic(case_dir(o, c) / kCaseStamp, joined(case_arguments(o, c)) + "\n");
    else
      std::fprintf(stderr, "study: case %zu failed, see %s\n", c.index,
                   (case_dir(o, c) / "log.txt").c_str());
    ok = ok && success;
  };
  for (const Case& c : cases) {
    if (already_done(o, c)) continue;
    while (int(running.size()) >= jobs) reap();
    running[spawn(o, c)] = &c;
  }
  while (!running.empty()) reap();
  return ok;
}

// Per collector and product: the grade and recovery of its main material,
// the material with the largest mass (the first listed on a tie), as the
// summary and the report give them, with their standard errors (0 in a
// products.csv written before it had them, which has_errors says).
struct MainFigures {
  double grade = 0.0, recovery = 0.0, grade_se = 0.0, recovery_se = 0.0;
};
using ProductKey = std::pair<std::string, std::string>;  // collector, product
struct ProductFigures {
  std::map<ProductKey, MainFigures> main;
  std::map<ProductKey, std::string> main_material;
  // Every material's, for a case measured on the reference's main material.
  std::map<std::pair<ProductKey, std::string>, MainFigures> each;
  bool has_errors = false;
};

ProductFigures main_material_figures(const fs::path& file) {
  const output::Table t = output::read_table(file);
  const std::size_t collector = t.column("collector", file), product = t.column("product", file),
                    mass = t.column("mass_kg", file), grade = t.column("grade", file),
                    recovery = t.column("recovery", file);
  const auto optional = [&](const std::string& name) {
    const auto it = std::find(t.header.begin(), t.header.end(), name);
    return it == t.header.end() ? std::optional<std::size_t>() : std::size_t(it - t.header.begin());
  };
  const std::optional<std::size_t> grade_se = optional("grade_se"),
                                   recovery_se = optional("recovery_se");
  const std::size_t material = t.column("material", file);
  ProductFigures figures;
  figures.has_errors = grade_se && recovery_se;
  std::map<ProductKey, double> largest;
  for (const auto& row : t.rows) {
    const ProductKey key{row[collector], row[product]};
    const MainFigures f{std::stod(row[grade]), std::stod(row[recovery]),
                        grade_se ? std::stod(row[*grade_se]) : 0.0,
                        recovery_se ? std::stod(row[*recovery_se]) : 0.0};
    figures.each[{key, row[material]}] = f;
    const double kg = std::stod(row[mass]);
    const auto it = largest.find(key);
    if (it != largest.end() && kg <= it->second) continue;
    largest[key] = kg;
    figures.main[key] = f;
    figures.main_material[key] = row[material];
  }
  return figures;
}

// A reference run's tables, read once for every case measured against it.
struct Reference {
  output::Landings landings;
  ProductFigures figures;
};

Reference read_reference(const fs::path& dir) {
  return {output::read_landings(dir / "crossings.csv"),
          main_material_figures(dir / "products.csv")};
}

Errors measure_against(const fs::path& run, const Reference& reference) {
  Errors e;
  const output::Landings a = output::read_landings(run / "crossings.csv");
  const output::Landings& b = reference.landings;
  for (const auto* side : {&a, &b})
    for (const auto& [key, samples] : *side) {
      const auto ia = a.find(key), ib = b.find(key);
      e.w1_mm[key] = ia == a.end() || ib == b.end()
                         ? std::numeric_limits<double>::infinity()
                         : 1e3 * output::wasserstein1(ia->second, ib->second);
    }
  for (const auto& [key, w1] : e.w1_mm) e.w1_max_mm = std::max(e.w1_max_mm, w1);
  const ProductFigures fa = main_material_figures(run / "products.csv");
  const ProductFigures& fb = reference.figures;
  // Each product on the reference's main material: the case's own main
  // material may be another (a product that is mostly copper in one run,
  // mostly FR-4 in the other), and a grade of one against the other's is
  // no error of either.
  for (const auto& [product, b] : fb.main) {
    const auto a = fa.each.find({product, fb.main_material.at(product)});
    if (a == fa.each.end()) continue;
    e.grade = std::max(e.grade, std::abs(a->second.grade - b.grade));
    e.recovery = std::max(e.recovery, std::abs(a->second.recovery - b.recovery));
  }
  std::ifstream in(run / "summary.json");
  const auto j = nlohmann::json::parse(in, nullptr, false);
  e.balance_exact = !j.is_discarded() && j["balance"].value("exact", false);
  return e;
}

// The study command's own arguments (after "study"), but for --case,
// --jobs and --scheduler: what every case command and the final measuring
// command share.
std::vector<std::string> study_arguments(const Options& o) {
  std::vector<std::string> args{full_path(o.scene)};
  for (const Axis& a : o.axes) {
    std::string values;
    for (const std::string& v : a.values) values += (values.empty() ? "" : ",") + v;
    args.insert(args.end(), {"--vary", a.key + "=" + values});
  }
  for (const std::string& k : o.base_unsets) args.insert(args.end(), {"--unset", k});
  for (const auto& [k, v] : o.base_sets) args.insert(args.end(), {"--set", k + "=" + v});
  if (o.seed) args.insert(args.end(), {"--seed", std::to_string(*o.seed)});
  if (o.threads) args.insert(args.end(), {"--threads", std::to_string(*o.threads)});
  if (!o.reference.empty()) args.insert(args.end(), {"--reference", full_path(o.reference)});
  for (const std::string& folder : o.include_paths)
    args.insert(args.end(), {"--include-path", full_path(folder)});
  args.insert(args.end(), {"-o", full_path(o.out_dir)});
  return args;
}

// Single quotes, with any single quote in the text closed and escaped.
std::string shell_quoted(const std::string& s) {
  std::string out = "'";
  for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string this_binary(const Options& o) {
  std::error_code error;
  const fs::path real = fs::read_symlink(o.binary, error);
  return error ? o.binary : real.string();
}

// This binary's study command, quoted for a shell, without --case.
std::string study_command(const Options& o) {
  std::string command = shell_quoted(this_binary(o)) + " study";
  for (const std::string& a : study_arguments(o)) command.append(" ").append(shell_quoted(a));
  return command;
}

constexpr const char* kCommands = "cases.sh";  // one command per case (case_commands)

// GNU parallel runs the case commands, `jobs` at a time; false if it is
// missing or a case failed.
bool run_with_parallel(const Options& o) {
  fs::create_directories(o.out_dir);
  // Each --case process runs one case alone: it is told the share of the
  // cores that this study's --jobs leaves it.
  Options each = o;
  each.threads = case_threads(o);
  output::write_file_atomic(o.out_dir / kCommands, case_commands(each));
  const int jobs = o.jobs > 0 ? o.jobs : cores();
  const std::string command = "parallel --will-cite --jobs " + std::to_string(jobs) +
                              " --halt never < " + shell_quoted((o.out_dir / kCommands).string());
  if (std::system("command -v parallel > /dev/null 2>&1") != 0)
    throw std::invalid_argument(
        "--scheduler parallel: GNU parallel is not installed (Debian: apt-get install parallel)");
  const int status = std::system(command.c_str());
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

int write_slurm(const Options& o) {
  fs::create_directories(o.out_dir);
  output::write_file_atomic(o.out_dir / kCommands, case_commands(o));
  const fs::path script = o.out_dir / "study.sbatch";
  output::write_file_atomic(script, slurm_script(o));
  const std::string measure = study_command(o);
  std::printf("wrote %s (%zu array tasks, one per case)\nsubmit, then measure when the array is done:\n"
              "  jid=$(sbatch --parsable %s)\n"
              "  sbatch --dependency=afterok:$jid --wrap \"%s\"\n",
              script.c_str(), make_cases(o.axes).size(), script.c_str(), measure.c_str());
  return 0;
}

Row read_row(const Options& o, const Case& c, const Reference& reference) {
  Row r;
  r.c = c;
  const fs::path dir = case_dir(o, c);
  std::ifstream in(dir / "summary.json");
  const auto j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded()) return r;
  r.complete = j.value("complete", false);
  r.wall_s = j["wall_time_s"].value("total", 0.0);
  const auto& s = j["solver"];
  r.method = s.value("method", std::string());
  r.contact_model = j.contains("contact") ? j["contact"].value("model", "dvi") : "dvi";
  r.residual_p95 = s.value("residual_p95_mps", 0.0);
  r.steps_at_cap = s.value("steps_at_iteration_cap", 0L);
  r.penetration_relative = s.value("max_penetration_relative", 0.0);
  if (r.complete) r.errors = measure_against(dir, reference);
  return r;
}

std::string fmt(double v) { return std::isinf(v) ? "inf" : output::format_number(v); }

// ---------------------------------------------------------------- the plot

// The keys that set how much work a run does for its accuracy: a line of
// the plot moves along them.
bool work_key(const std::string& k) {
  return k == "time.step" || k == "solver.max_iterations" || k == "solver.tolerance" ||
         k == "solver.penetration_tolerance";
}

// A line of the plot: the values of the axes other than the work keys, or
// the run's solver method. DEM runs use no contact solver, so solver
// settings do not split their line.
std::string series(const Row& r) {
  const bool dem = r.contact_model == "dem";
  std::string label;
  for (const auto& [k, v] : r.c.sets) {
    const bool solver_key = k.starts_with("solver.");
    if (work_key(k) || (dem && solver_key)) continue;
    label += (label.empty() ? "" : " ") + v;
  }
  return !label.empty() ? label : dem ? "dem" : r.method;
}

// What varies along a series' line: the case's work keys.
std::string point_label(const Row& r) {
  std::string label;
  for (const auto& [k, v] : r.c.sets)
    if (work_key(k)) label += (label.empty() ? "" : " ") + v;
  return !label.empty() ? label : "case " + std::to_string(r.c.index);
}

struct Frame {  // log10 ranges mapped to the plot area
  double x0, x1, y0, y1;
  static constexpr double left = 80, top = 40, width = 420, height = 320;
  double px(double v) const { return left + (std::log10(v) - x0) / (x1 - x0) * width; }
  double py(double v) const { return top + height - (std::log10(v) - y0) / (y1 - y0) * height; }
};

// Whole decades around [lo, hi], at least one wide.
std::pair<double, double> decades(double lo, double hi) {
  double a = std::floor(std::log10(lo)), b = std::ceil(std::log10(hi));
  if (b <= a) b = a + 1;
  return {a, b};
}

void axes_svg(const Frame& f, std::ostringstream& out) {
  out << "<rect x='" << f.left << "' y='" << f.top << "' width='" << f.width << "' height='"
      << f.height << "' fill='none' stroke='black'/>\n";
  for (double d = f.x0; d <= f.x1; ++d) {
    const double x = f.px(std::pow(10.0, d));
    out << "<line x1='" << x << "' y1='" << f.top + f.height << "' x2='" << x << "' y2='"
        << f.top + f.height + 5 << "' stroke='black'/><text x='" << x << "' y='"
        << f.top + f.height + 20 << "' text-anchor='middle'>1e" << d << "</text>\n";
  }
  for (double d = f.y0; d <= f.y1; ++d) {
    const double y = f.py(std::pow(10.0, d));
    out << "<line x1='" << f.left - 5 << "' y1='" << y << "' x2='" << f.left << "' y2='" << y
        << "' stroke='black'/><text x='" << f.left - 8 << "' y='" << y + 4
        << "' text-anchor='end'>1e" << d << "</text>\n";
  }
  out << "<text x='" << f.left + f.width / 2 << "' y='" << f.top + f.height + 45
      << "' text-anchor='middle'>wall time (s)</text>\n"
      << "<text transform='translate(20," << f.top + f.height / 2
      << ") rotate(-90)' text-anchor='middle'>landing error, max W1 over materials (mm)</text>\n"
      << "<text x='" << f.left << "' y='22'>Work-precision (the reference, error 0, is not "
         "drawn)</text>\n";
}

std::string study_svg(const std::vector<Row>& rows) {
  struct Point {
    double wall, error;
    std::string label;
    bool operator<(const Point& o) const { return wall < o.wall; }
  };
  std::map<std::string, std::vector<Point>> lines;  // by series
  double wmin = 1e300, wmax = 0, emin = 1e300, emax = 0;
  for (const Row& r : rows) {
    const double e = r.errors.w1_max_mm;
    if (!r.complete || r.wall_s <= 0 || !(e > 0) || std::isinf(e)) continue;  // no log of 0
    lines[series(r)].push_back({r.wall_s, e, point_label(r)});
    wmin = std::min(wmin, r.wall_s), wmax = std::max(wmax, r.wall_s);
    emin = std::min(emin, e), emax = std::max(emax, e);
  }
  if (lines.empty()) wmin = emin = 1.0, wmax = emax = 10.0;
  const auto [x0, x1] = decades(wmin, wmax);
  const auto [y0, y1] = decades(emin, emax);
  const Frame f{x0, x1, y0, y1};
  std::ostringstream out;
  out << "<svg xmlns='http://www.w3.org/2000/svg' width='680' height='430' "
         "font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' "
         "fill='white'/>\n";
  axes_svg(f, out);
  static const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
  int n = 0;
  for (auto& [name, points] : lines) {
    std::sort(points.begin(), points.end());
    const char* colour = colours[n % 6];
    out << "<polyline fill='none' stroke='" << colour << "' points='";
    for (const Point& p : points) out << f.px(p.wall) << "," << f.py(p.error) << " ";
    out << "'/>\n";
    for (const Point& p : points)
      out << "<circle cx='" << f.px(p.wall) << "' cy='" << f.py(p.error) << "' r='3' fill='"
          << colour << "'/><text x='" << f.px(p.wall) + 5 << "' y='" << f.py(p.error) - 5
          << "' font-size='10' fill='" << colour << "'>" << output::xml_escape(p.label) << "</text>\n";
    const double ly = f.top + 10 + 18 * n++;
    out << "<line x1='515' y1='" << ly << "' x2='535' y2='" << ly << "' stroke='" << colour
        << "' stroke-width='2'/><text x='540' y='" << ly + 4 << "'>" << output::xml_escape(name) << "</text>\n";
  }
  out << "</svg>\n";
  return out.str();
}

std::vector<std::string> axis_keys(const Axis& a) { return split(a.key, ':'); }

// Index of the finest case, from each case's compiled scene.
std::size_t finest_case(const Options& o, const std::vector<Case>& cases) {
  using Finest = std::tuple<bool, double, double, double, int>;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::size_t best = 0;
  Finest best_key{true, kInf, kInf, kInf, 0};
  for (const Case& c : cases) {
    const Simulation sim = case_scene(o, c);
    // DVI before DEM (the method under study; a DEM run at its tiny step is
    // not the finer solution of the rigid problem), then the smallest step,
    // then the tightest residual and overlap tolerances, then the largest
    // iteration cap.
    const SolverSettings& solver = sim.model->solver;
    const Finest key{sim.model->contact_model == ContactModel::DEM, sim.model->step,
                     solver.tolerance, solver.penetration_tolerance, -solver.max_iterations};
    if (key < best_key) {
      best_key = key;
      best = c.index;
    }
  }
  return best;
}

std::string study_csv(const std::vector<Axis>& axes, const std::vector<Row>& rows) {
  std::vector<std::string> keys;  // every "material at collector" of any row
  for (const Row& r : rows)
    for (const auto& [k, v] : r.errors.w1_mm)
      if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
  std::sort(keys.begin(), keys.end());
  std::string text = "case";
  for (const Axis& a : axes)
    for (const std::string& k : axis_keys(a)) text += "," + k;
  text += ",complete,wall_time_s,w1_max_mm";
  for (const std::string& k : keys) text += ",w1_mm " + k;
  text += ",grade_error,recovery_error,balance_exact,solver_method,residual_p95_mps,"
          "steps_at_iteration_cap,max_penetration_relative,contact_model\n";
  for (const Row& r : rows) {
    std::vector<std::string> f{std::to_string(r.c.index)};
    for (const auto& [k, v] : r.c.sets) f.push_back(v);
    if (r.complete) {
      f.insert(f.end(), {"true", fmt(r.wall_s), fmt(r.errors.w1_max_mm)});
      for (const std::string& k : keys) {
        const auto it = r.errors.w1_mm.find(k);
        f.push_back(it == r.errors.w1_mm.end() ? std::string() : fmt(it->second));
      }
      f.insert(f.end(),
               {fmt(r.errors.grade), fmt(r.errors.recovery),
                r.errors.balance_exact ? "true" : "false", r.method, fmt(r.residual_p95),
                std::to_string(r.steps_at_cap), fmt(r.penetration_relative), r.contact_model});
    } else {
      f.push_back("false");  // nothing measured: empty cells, not figures of 0
      f.resize(f.size() + 2 + keys.size() + 8);
    }
    for (std::size_t i = 0; i < f.size(); ++i) text.append(i ? "," : "").append(f[i]);
    text += '\n';
  }
  return text;
}

// What the feed's sampling gives at the reference: its products' largest
// standard errors. A case's errors below about 1.4 times them (the spread
// of a difference of two independent samples) are what another seed's
// feed would give: not an error of its settings.
std::string sampling_line(const Reference& reference) {
  const ProductFigures& figures = reference.figures;
  if (!figures.has_errors)
    return "the feed's sampling at the reference: not known (its products.csv has no standard "
           "errors)\n";
  double grade = 0.0, recovery = 0.0;
  for (const auto& [product, f] : figures.main) {
    grade = std::max(grade, f.grade_se);
    recovery = std::max(recovery, f.recovery_se);
  }
  return "the feed's sampling at the reference (its products' largest standard errors): grade " +
         fmt(grade) + ", recovery " + fmt(recovery) + "\n";
}

// A reference that collected nothing leaves nothing to measure: its cases'
// errors read 0, which says so rather than that they agree.
std::string nothing_collected(const Reference& reference) {
  if (!reference.landings.empty()) return "";
  return "warning: the reference collected no particle, so every error below is 0 for want of "
         "anything to compare; run the cases until particles reach the collectors (time.end)\n";
}

std::string study_table(const std::vector<Axis>& axes, const std::vector<Row>& rows) {
  std::vector<std::vector<std::string>> cells{{"case"}};
  for (const Axis& a : axes)
    for (const std::string& k : axis_keys(a)) cells[0].push_back(k);
  cells[0].insert(cells[0].end(), {"wall s", "W1 max mm", "grade err", "recovery err", "balance",
                                   "residual p95 m/s"});
  for (const Row& r : rows) {
    std::vector<std::string> line{std::to_string(r.c.index)};
    for (const auto& [k, v] : r.c.sets) line.push_back(v);
    if (r.complete)
      line.insert(line.end(), {fmt(r.wall_s), fmt(r.errors.w1_max_mm), fmt(r.errors.grade),
                               fmt(r.errors.recovery),
                               r.errors.balance_exact ? "exact" : "NOT EXACT", fmt(r.residual_p95)});
    else
      line.push_back("FAILED");
    cells.push_back(std::move(line));
  }
  std::vector<std::size_t> width(cells[0].size(), 0);
  for (const auto& line : cells)
    for (std::size_t i = 0; i < line.size(); ++i) width[i] = std::max(width[i], line[i].size());
  std::string out;
  for (const auto& line : cells) {
    for (std::size_t i = 0; i < line.size(); ++i)
      out += line[i] + std::string(i + 1 < line.size() ? width[i] - line[i].size() + 2 : 0, ' ');
    out += '\n';
  }
  return out;
}

// The body says whether the plot loaded, as a run's report says whether its
// script ran (data-rendered="ok", or data-error): a test opens both in a
// browser.
constexpr const char* kPlotLoads =
    "onload=\"document.body.dataset.rendered = 'ok'\" "
    "onerror=\"document.body.dataset.error = 'the work-precision plot does not load'\"";

// DIR/report.html: the work-precision plot, the table and a link to each
// case's own report.
std::string study_report(const std::vector<Case>& cases, const fs::path& reference,
                         const std::string& table, const std::string& svg) {
  std::string links;
  for (const Case& c : cases) {
    const std::string k = std::to_string(c.index);
    links += "<a href=\"case_" + k + "/report.html\">case " + k + "</a> ";
  }
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
         "<title>ces-sim study</title>\n<style>body { font: 14px Helvetica, Arial, sans-serif; "
         "margin: 24px auto; max-width: 980px; } img { max-width: 100%; }</style>\n</head>\n"
         "<body>\n<h1>Study</h1>\n<p>reference: " +
         output::xml_escape(reference.string()) + "</p>\n<img alt=\"work-precision\" " +
         kPlotLoads + " src=\"data:image/svg+xml;base64," + output::base64(svg) + "\">\n<pre>" +
         output::xml_escape(table) + "</pre>\n<p>each case's report: " + links + "</p>\n</body>\n</html>\n";
}

std::string case_commands(const Options& o) {
  std::string text;
  const std::string command = study_command(o);
  for (const Case& c : make_cases(o.axes))
    text.append(command).append(" --case ").append(std::to_string(c.index)).append("\n");
  return text;
}

std::string slurm_script(const Options& o) {
  const std::size_t n = make_cases(o.axes).size();
  const fs::path commands = fs::absolute(o.out_dir / kCommands);
  return "#!/bin/bash\n"
         "# ces-sim study: one array task per case. Submit with sbatch; when the array\n"
         "# has run, the same study command without --scheduler measures the cases.\n"
         "#SBATCH --job-name=ces-study\n"
         "#SBATCH --array=0-" + std::to_string(n - 1) + "\n"
         "#SBATCH --ntasks=1\n"
         "#SBATCH --output=" + full_path(o.out_dir) + "/slurm-%A_%a.out\n"
         "set -euo pipefail\n"
         "line=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" " + shell_quoted(commands.string()) +
         ")\n"
         "bash -c \"$line\"\n";
}

}  // namespace

Axis parse_axis(const std::string& spec) {
  const auto eq = spec.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size())
    throw std::invalid_argument("--vary " + spec + ": expected key.path=v1,v2,...");
  Axis a{spec.substr(0, eq), split(spec.substr(eq + 1), ',')};
  const std::size_t keys = axis_keys(a).size();
  for (const std::string& v : a.values) {
    const std::vector<std::string> parts = split(v, ':');
    if (std::any_of(parts.begin(), parts.end(), [](const auto& p) { return p.empty(); }))
      throw std::invalid_argument("--vary " + spec + ": empty value");
    if (parts.size() != keys)
      throw std::invalid_argument("--vary " + spec + ": '" + v + "' has " +
                                  std::to_string(parts.size()) + " values for " +
                                  std::to_string(keys) + " keys");
    if (std::count(a.values.begin(), a.values.end(), v) > 1)
      throw std::invalid_argument("--vary " + spec + ": '" + v +
                                  "' twice, expected each value once (two cases would be one)");
  }
  return a;
}

std::vector<Axis> parse_axes(const std::vector<std::string>& specs) {
  std::vector<Axis> axes;
  std::vector<std::string> keys;
  for (const std::string& spec : specs) {
    axes.push_back(parse_axis(spec));
    for (const std::string& k : axis_keys(axes.back())) {
      // The later --set of a key wins: a key on two axes would label
      // cases by values none of them ran with.
      if (std::find(keys.begin(), keys.end(), k) != keys.end())
        throw std::invalid_argument("--vary " + spec + ": '" + k +
                                    "' is varied twice, expected each key on one axis");
      keys.push_back(k);
    }
  }
  return axes;
}

std::vector<Case> make_cases(const std::vector<Axis>& axes) {
  std::vector<Case> cases(1);
  for (const Axis& axis : axes) {
    const std::vector<std::string> keys = axis_keys(axis);
    std::vector<Case> next;
    for (const Case& c : cases)
      for (const std::string& v : axis.values) {
        next.push_back(c);
        const std::vector<std::string> parts = split(v, ':');
        for (std::size_t k = 0; k < keys.size(); ++k)
          next.back().sets.emplace_back(keys[k], parts[k]);
      }
    cases = std::move(next);
  }
  for (std::size_t k = 0; k < cases.size(); ++k) cases[k].index = k;
  return cases;
}

std::vector<std::string> case_arguments(const Options& o, const Case& c) {
  // Absolute paths: the command is the case's stamp (already_done), the
  // same from this study and from a scheduler's --case process, which is
  // given them absolute.
  std::vector<std::string> args{full_path(o.scene), "-o", full_path(case_dir(o, c)), "--quiet"};
  for (const std::string& k : o.base_unsets) args.insert(args.end(), {"--unset", k});
  for (const Sets* sets : {&o.base_sets, &c.sets})
    for (const auto& [k, v] : *sets) {
      args.push_back("--set");
      args.push_back(k + "=" + v);
    }
  if (o.seed) args.insert(args.end(), {"--seed", std::to_string(*o.seed)});
  for (const std::string& folder : o.include_paths)
    args.insert(args.end(), {"--include-path", full_path(folder)});
  return args;
}

Errors measure(const fs::path& run, const fs::path& reference) {
  return measure_against(run, read_reference(reference));
}

Scheduler parse_scheduler(const std::string& name) {
  if (name == "local") return Scheduler::Local;
  if (name == "parallel") return Scheduler::Parallel;
  if (name == "slurm") return Scheduler::Slurm;
  throw std::invalid_argument("--scheduler " + name + ": expected local, parallel or slurm");
}

std::string list_cases(const Options& o) {
  std::string text;
  for (const Case& c : make_cases(o.axes)) {
    text += std::to_string(c.index) + " ";
    for (const auto& [k, v] : c.sets) text += " --set " + k + "=" + v;
    text += "\n";
  }
  return text;
}

// A reference named on the command line is read once every case has run:
// its files are looked for first, so a wrong path costs no runs.
void check_reference(const fs::path& reference) {
  for (const char* file : {"crossings.csv", "products.csv"})
    if (!fs::is_regular_file(reference / file))
      throw std::invalid_argument("--reference " + reference.string() + ": no " + file +
                                  ", expected the output folder of a complete run");
  if (!completed(reference))
    throw std::invalid_argument("--reference " + reference.string() +
                                ": its summary.json does not say the run completed, expected "
                                "the output folder of a complete run");
}

// The reference the study chose among its cases ran and failed: there is
// nothing to measure the cases against.
void check_chosen_reference(const fs::path& reference) {
  if (completed(reference)) return;
  throw std::runtime_error("the reference, the finest case, " + reference.string() +
                           ", did not complete (its partial/summary.json says why): run it "
                           "again, or name another run with --reference");
}

int run(const Options& o) {
  if (const auto file = file_in_the_way(o.out_dir))
    throw std::invalid_argument("-o " + o.out_dir.string() + ": " + file->string() +
                                " is not a folder, expected a folder's path (made if missing)");
  if (!o.reference.empty()) check_reference(o.reference);
  if (o.scheduler == Scheduler::Slurm) return write_slurm(o);
  if (o.scheduler == Scheduler::Parallel && !o.only_case && !run_with_parallel(o)) return 3;
  const std::vector<Case> cases = make_cases(o.axes);
  if (o.only_case) {
    if (*o.only_case >= cases.size())
      throw std::invalid_argument("--case " + std::to_string(*o.only_case) + ": only " +
                                  std::to_string(cases.size()) + " cases");
    return run_cases(o, {cases[*o.only_case]}) ? 0 : 3;
  }
  const bool ok = run_cases(o, cases);
  const fs::path reference =
      o.reference.empty() ? case_dir(o, cases[finest_case(o, cases)]) : o.reference;
  if (o.reference.empty()) check_chosen_reference(reference);
  const Reference tables = read_reference(reference);
  std::vector<Row> rows;
  for (const Case& c : cases) rows.push_back(read_row(o, c, tables));
  output::write_file_atomic(o.out_dir / "study.csv", study_csv(o.axes, rows));
  const std::string warning = nothing_collected(tables);
  if (!warning.empty()) std::fputs(warning.c_str(), stderr);
  const std::string svg = study_svg(rows),
                    table = warning + sampling_line(tables) + study_table(o.axes, rows);
  output::write_file_atomic(o.out_dir / "study.svg", svg);
  output::write_file_atomic(o.out_dir / "report.html", study_report(cases, reference, table, svg));
  std::printf("reference: %s\n%s", reference.c_str(), table.c_str());
  return ok ? 0 : 3;
}

}  // namespace ces::study
