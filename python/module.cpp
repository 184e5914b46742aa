// ces_sim: ces-sim from Python (docs/python.md). Loads a scene as the
// command line does (overrides, seed), runs it into an output folder as
// `ces-sim SCENE -o DIR` does, with a progress callback, and hands back what
// the run wrote as Python objects.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "columns.hpp"
#include "scene/scene.hpp"
#include "sim/run.hpp"

namespace ces::python {
namespace {

namespace fs = std::filesystem;
namespace py = pybind11;
using namespace pybind11::literals;
using Overrides = std::vector<std::pair<std::string, std::string>>;

// ces_sim.SceneError (a ValueError) and ces_sim.RunError (a RuntimeError);
// alive as long as the process.
PyObject* g_scene_error = nullptr;
PyObject* g_run_error = nullptr;

// The exception's text is every diagnostic, one a line, as ces-sim prints
// them; its `diagnostics` attribute lists them.
void raise_scene_error(const scene::SceneError& e) {
  std::string text;
  for (const scene::Diagnostic& d : e.diagnostics()) text += (text.empty() ? "" : "\n") + d.str();
  py::object error = py::handle(g_scene_error)(text);
  error.attr("diagnostics") = py::cast(e.diagnostics());
  PyErr_SetObject(g_scene_error, error.ptr());
}

// A value as the YAML text of --set: text as it is ("70 rpm"), True and
// False as true and false, numbers as Python writes them, anything else
// (lists, dicts) as JSON, which YAML reads.
std::string yaml_value(py::handle value) {
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::int_>(value) || py::isinstance<py::float_>(value))
    return py::str(value).cast<std::string>();
  return py::module_::import("json").attr("dumps")(value).cast<std::string>();
}

std::pair<std::string, std::string> key_value(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw py::value_error("set: " + text + ": expected key.path=value");
  return {text.substr(0, eq), text.substr(eq + 1)};
}

// set=: {key: value}, or a list of "key=value" strings, applied in order,
// as --set.
Overrides overrides(py::handle set) {
  Overrides out;
  if (set.is_none()) return out;
  if (py::isinstance<py::dict>(set)) {
    for (const auto [key, value] : set.cast<py::dict>())
      out.emplace_back(py::str(key).cast<std::string>(), yaml_value(value));
    return out;
  }
  if (py::isinstance<py::str>(set) || !py::isinstance<py::iterable>(set))
    throw py::type_error("set: expected {key: value} or a list of \"key=value\"");
  for (py::handle item : set) {
    if (!py::isinstance<py::str>(item))
      throw py::type_error("set: expected {key: value} or a list of \"key=value\"");
    out.push_back(key_value(item.cast<std::string>()));
  }
  return out;
}

std::optional<std::uint64_t> seed_of(py::handle seed) {
  if (seed.is_none()) return std::nullopt;
  if (py::isinstance<py::int_>(seed) && !py::isinstance<py::bool_>(seed)) {
    try {
      return seed.cast<std::uint64_t>();
    } catch (const py::cast_error&) {  // negative, or beyond 64 bits
    }
  }
  throw py::value_error("seed: expected a whole number >= 0");
}

// The compiled scene, shared by every run made from it.
struct Scene {
  std::shared_ptr<const Simulation> sim;
};

Scene load(const fs::path& path, py::handle set, py::handle seed,
           const std::vector<fs::path>& include_paths) {
  scene::LoadOptions options;
  options.overrides = overrides(set);
  options.seed = seed_of(seed);
  for (const fs::path& p : include_paths) options.include_paths.push_back(p.string());
  const py::gil_scoped_release release;
  return {std::make_shared<const Simulation>(scene::load(path.string(), options))};
}

// The progress callback, progress(time, particles, fraction), called with
// the GIL held. A result of False (not None) stops the run; so does an
// exception, raised again once the run has ended.
class Watch {
 public:
  explicit Watch(py::object callback) : callback_(std::move(callback)) {}

  bool operator()(const RunProgress& p) {
    const py::gil_scoped_acquire gil;
    try {
      const double fraction = p.end_time > 0.0 ? std::min(1.0, p.time / p.end_time) : 1.0;
      const py::object go_on = callback_(p.time, p.particles, fraction);
      stopped_ = !go_on.is_none() && !static_cast<bool>(py::bool_(go_on));
    } catch (py::error_already_set& e) {
      error_.emplace(std::move(e));
      stopped_ = true;
    }
    return stopped_;
  }
  bool stopped() const { return stopped_; }
  void raise_if_failed() const {
    if (error_) throw *error_;
  }

 private:
  py::object callback_;
  bool stopped_ = false;
  std::optional<py::error_already_set> error_;
};

// With the GIL released, one run at a time: a run holds the process's
// SIGINT and SIGTERM handlers and OpenMP's thread count while it goes. A
// run started from a running one's progress callback (its own thread)
// would wait for itself for ever: it is an error.
RunResult run_released(const Simulation& sim, const RunOptions& options) {
  static std::mutex one_at_a_time;
  thread_local bool running = false;
  if (running)
    throw std::runtime_error(
        "a run is going in this thread: Scene.run cannot be called from a progress callback");
  running = true;
  const struct Done {
    ~Done() { running = false; }
  } done;
  const py::gil_scoped_release release;
  const std::lock_guard lock(one_at_a_time);
  return ces::run(sim, options);
}

// A signal that stopped the run does what it does in Python: SIGINT raises
// KeyboardInterrupt; SIGTERM is raised again for the process's own handler.
void pass_on(int signal) {
  if (signal == SIGINT) {
    PyErr_SetNone(PyExc_KeyboardInterrupt);
    throw py::error_already_set();
  }
  if (signal == SIGTERM) std::raise(SIGTERM);
}

// A table the run wrote, or None when it wrote none.
py::object table_or_none(const fs::path& file) {
  if (!fs::exists(file)) return py::none();
  return to_python(read_csv(file));
}

// A run that ended, and what it wrote, read from its folder as soon as it
// ended: a later run into the same folder changes none of it.
class Result {
 public:
  explicit Result(RunResult result)
      : result_(std::move(result)),
        summary_(py::module_::import("json").attr("loads")(read_text(dir() / "summary.json"))),
        products_(to_python(read_csv(dir() / "products.csv"))),
        bins_(to_python(read_csv(dir() / "bins.csv"))),
        crossings_(table_or_none(dir() / "crossings.csv")),
        trajectories_(table_or_none(dir() / "trajectories.csv")) {}

  fs::path dir() const { return result_.out_dir; }
  bool complete() const { return result_.complete; }
  const std::string& reason() const { return result_.reason; }
  const py::object& summary() const { return summary_; }
  const py::dict& products() const { return products_; }
  const py::dict& bins() const { return bins_; }
  const py::object& crossings() const { return crossings_; }
  const py::object& trajectories() const { return trajectories_; }

  std::string repr() const {
    return "<ces_sim.Result " +
           (complete() ? std::string("complete") : "incomplete (" + reason() + ")") + " in " +
           result_.out_dir + ">";
  }

 private:
  RunResult result_;
  py::object summary_;
  py::dict products_, bins_;
  py::object crossings_, trajectories_;
};

Result run_scene(const Scene& scene, const std::optional<fs::path>& out_dir,
                 std::optional<int> threads, const py::object& progress, double progress_every) {
  if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
    throw py::type_error("progress: expected a function of (time, particles, fraction)");
  if (!(progress_every >= 0.0)) throw py::value_error("progress_every: expected seconds >= 0");
  if (threads && *threads < 1) throw py::value_error("threads: expected a whole number >= 1");
  RunOptions options;
  options.out_dir = out_dir ? out_dir->string() : std::string();
  options.quiet = true;
  options.threads = threads.value_or(0);
  Watch watch(progress);
  if (!progress.is_none()) {
    options.on_progress = [&watch](const RunProgress& p) { return watch(p); };
    options.on_progress_every = progress_every;
  }
  const RunResult result = run_released(*scene.sim, options);
  watch.raise_if_failed();
  pass_on(result.signal);
  if (!result.complete && !watch.stopped()) {
    PyErr_SetString(g_run_error, (result.reason + " (outputs in " + result.out_dir + ")").c_str());
    throw py::error_already_set();
  }
  return Result(result);
}

void define_errors(py::module_& m) {
  g_scene_error = PyErr_NewExceptionWithDoc(
      "ces_sim.SceneError",
      "A scene that cannot run: every problem found, one a line, as file:line:col: key: "
      "message, as ces-sim prints them; the list in .diagnostics.",
      PyExc_ValueError, nullptr);
  g_run_error = PyErr_NewExceptionWithDoc(
      "ces_sim.RunError",
      "A run that failed (an error in a step, outputs that cannot be written): the reason "
      "summary.json gives, and where the outputs are.",
      PyExc_RuntimeError, nullptr);
  m.add_object("SceneError", py::handle(g_scene_error));
  m.add_object("RunError", py::handle(g_run_error));
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const scene::SceneError& e) {
      raise_scene_error(e);
    }
  });
  py::class_<scene::Diagnostic>(m, "Diagnostic", "One problem of a scene, where it is.")
      .def_readonly("file", &scene::Diagnostic::file, "the file, or --set for an override")
      .def_readonly("line", &scene::Diagnostic::line, "from 1; 0 when unknown")
      .def_readonly("column", &scene::Diagnostic::column, "from 1; 0 when unknown")
      .def_readonly("key", &scene::Diagnostic::path, "the key path, e.g. materials.copper.density")
      .def_readonly("message", &scene::Diagnostic::message)
      .def("__str__", &scene::Diagnostic::str)
      .def("__repr__",
           [](const scene::Diagnostic& d) { return "<ces_sim.Diagnostic " + d.str() + ">"; });
}

void define_scene(py::module_& m) {
  py::class_<Scene>(m, "Scene", "A scene loaded, validated and compiled; run it with run().")
      .def_property_readonly("name", [](const Scene& s) { return s.sim->name; })
      .def_property_readonly("path", [](const Scene& s) { return s.sim->scene_path; })
      .def_property_readonly("seed", [](const Scene& s) { return s.sim->seed; })
      .def_property_readonly("end_time", [](const Scene& s) { return s.sim->end_time; },
                             "end time (s)")
      .def_property_readonly("hash", [](const Scene& s) { return s.sim->scene_hash; },
                             "summary.json's scene.hash")
      .def("run", &run_scene, "out_dir"_a = py::none(), py::kw_only(), "threads"_a = py::none(),
           "progress"_a = py::none(), "progress_every"_a = 1.0,
           "Runs the scene into out_dir (default: its output.dir) as ces-sim does, with "
           "threads worker threads (default: chosen as the run goes). "
           "progress(time, particles, fraction) is called every progress_every s of wall "
           "time and after the last step; returning False stops the run. Returns a Result; "
           "raises RunError when the run fails, KeyboardInterrupt on Ctrl-C.")
      .def("__repr__", [](const Scene& s) { return "<ces_sim.Scene " + s.sim->name + ">"; });
}

void define_result(py::module_& m) {
  py::class_<Result>(m, "Result", "A run that ended, and what it wrote.")
      .def_property_readonly("complete", &Result::complete, "True when it reached its end time")
      .def_property_readonly("reason", &Result::reason, "why it is not complete; empty when it is")
      .def_property_readonly(
          "out_dir", [](const Result& r) { return r.dir(); },
          "its outputs: DIR, or DIR/partial for a run not complete")
      .def_property_readonly("summary", &Result::summary, "summary.json as a dict")
      .def_property_readonly("products", &Result::products, "products.csv: {column: values}")
      .def_property_readonly("bins", &Result::bins, "bins.csv: {column: values}")
      .def_property_readonly("crossings", &Result::crossings, "crossings.csv: {column: values}")
      .def_property_readonly("trajectories", &Result::trajectories,
                             "trajectories.csv: {column: values}; None when not written")
      .def("__repr__", &Result::repr);
}

}  // namespace
}  // namespace ces::python

PYBIND11_MODULE(ces_sim, m) {
  using namespace ces::python;
  m.doc() = "ces-sim from Python: load a scene, run it, read what it wrote (docs/python.md).";
  m.attr("__version__") = CES_VERSION;
  define_errors(m);
  define_scene(m);
  define_result(m);
  m.def("load", &load, "path"_a, py::kw_only(), "set"_a = py::none(), "seed"_a = py::none(),
        "include_paths"_a = std::vector<fs::path>{},
        "Loads a scene as ces-sim does: set={key.path: value} as --set (a str value is YAML, "
        "e.g. '70 rpm'), seed as --seed, include_paths as --include-path. Raises SceneError.");
  m.def(
      "read_csv", [](const std::filesystem::path& path) { return to_python(read_csv(path)); },
      "path"_a, "A CSV file of a run or a study as {column: values}.");
}
