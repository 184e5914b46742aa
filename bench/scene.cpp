// A scene end to end: ces-sim as a child process, then its summary.json
// (src/output/summary.cpp: wall_time_s.total and .stages, solver, steps).
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "bench.hpp"

namespace bench {

double SceneRun::stage(const std::string& name) const {
  for (const auto& [n, s] : stages)
    if (n == name) return s;
  return 0;
}

double SceneRun::step_seconds() const {
  double t = 0;
  for (const auto& [n, s] : stages)
    if (n != "output") t += s;
  return t;
}

namespace {

using Json = nlohmann::ordered_json;  // the stages keep summary.json's order

void read_summary(const std::string& path, SceneRun& run) {
  std::ifstream in(path);
  if (!in) {
    run.error = "no " + path;
    return;
  }
  const Json j = Json::parse(in, nullptr, false);
  if (j.is_discarded() || !j.contains("wall_time_s")) {
    run.error = "unreadable " + path;
    return;
  }
  run.name = j.value("scene", Json::object()).value("name", "");
  run.complete = j.value("complete", false);
  run.threads = j.value("threads", run.threads);
  run.simulated = j.value("simulated_time_s", 0.0);
  run.steps = j.value("steps", std::size_t(0));
  run.peak_rss = j.value("peak_memory_mib", 0.0) * double(1 << 20);
  const Json& wall = j.at("wall_time_s");
  run.wall_total = wall.value("total", 0.0);
  const Json stages = wall.value("stages", Json::object());
  for (const auto& [name, seconds] : stages.items())
    run.stages.emplace_back(name, seconds.get<double>());
  const Json s = j.value("solver", Json::object());
  run.iterations_mean = s.value("iterations_mean", 0.0);
  run.particles_max = s.value("particles_max", std::size_t(0));
  run.contacts_max = s.value("contacts_max", std::size_t(0));
}

}  // namespace

SceneRun run_scene(const std::string& ces_sim, const std::string& scene,
                   const std::vector<std::string>& sets, const std::string& out_dir, int threads) {
  SceneRun run;
  run.path = scene;
  run.sets = sets;
  run.out_dir = out_dir;
  // Where a complete run leaves its summary, then where an interrupted or
  // failed one (exit code 3) does. Neither of an earlier run is read as
  // this one's.
  const std::string summaries[] = {out_dir + "/summary.json", out_dir + "/partial/summary.json"};
  for (const std::string& summary : summaries) std::filesystem::remove(summary);
  std::vector<std::string> argv = {ces_sim, scene,         "-o", out_dir, "--quiet",
                                   "--threads", std::to_string(threads)};
  for (const std::string& s : sets) argv.insert(argv.end(), {"--set", s});
  const ProcessResult p = run_process(argv, false);
  run.exit_code = p.exit_code;
  run.process_wall = p.wall;
  run.threads = threads;
  if (p.exit_code != 0) run.error = ces_sim + " exited with code " + std::to_string(p.exit_code);
  for (const std::string& summary : summaries)
    if (std::filesystem::exists(summary)) {
      read_summary(summary, run);
      return run;
    }
  if (run.error.empty()) run.error = "no " + summaries[0];
  return run;
}

}  // namespace bench
