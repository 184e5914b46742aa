#include "output/summary.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

#include "output/format.hpp"

namespace ces::output {
namespace {

using Json = nlohmann::ordered_json;

// A passive run that gains more than this fraction of its peak kinetic
// energy is worth a warning: the numerics, not the physics, made it.
constexpr double kEnergyGainWarning = 0.01;

Json tally_json(const Tally& t) { return {{"count", t.count}, {"mass_kg", t.kg()}}; }

const char* method_name(SolverMethod m) {
  switch (m) {
    case SolverMethod::APGD:
      return "apgd";
    case SolverMethod::SPG:
      return "spg";
    case SolverMethod::PGS:
      return "pgs";
  }
  return "?";
}

// Per Model material: where its particles went.
struct Fates {
  std::vector<Tally> collected, lost;
};

Fates fates(const RunRecord& r) {
  const std::size_t n = r.fed.size();
  Fates f{std::vector<Tally>(n), std::vector<Tally>(n)};
  for (std::size_t m = 0; m < n; ++m) {
    f.collected[m] = r.collection->collected_total(m);
    f.lost[m] = r.collection->lost_total(m);
  }
  return f;
}

Tally sum(const std::vector<Tally>& v) {
  Tally t;
  for (const Tally& x : v) t += x;
  return t;
}

bool balanced(const RunRecord& r, const Fates& f) {
  for (std::size_t m = 0; m < r.fed.size(); ++m)
    if (!(r.fed[m] == f.collected[m] + f.lost[m] + r.active[m])) return false;
  return true;
}

Json balance_json(const RunRecord& r) {
  const Fates f = fates(r);
  Json j = {{"fed", tally_json(sum(r.fed))},
            {"collected", tally_json(sum(f.collected))},
            {"lost", tally_json(sum(f.lost))},
            {"active", tally_json(sum(r.active))},
            {"exact", balanced(r, f)}};
  Json& materials = j["materials"] = Json::object();
  for (const int m : r.materials) {
    const auto i = std::size_t(m);
    materials[r.sim->model->materials.materials()[i].name] = {
        {"fed", tally_json(r.fed[i])},
        {"collected", tally_json(f.collected[i])},
        {"lost", tally_json(f.lost[i])},
        {"active", tally_json(r.active[i])}};
  }
  Json& reasons = j["lost_by_reason"] = Json::object();
  for (const LossReason reason : kLossReasons)
    reasons[std::string(to_string(reason))] = tally_json(sum(r.collection->lost(reason)));
  return j;
}

Json wall_json(const RunRecord& r) {
  Json stages = Json::object();
  for (std::size_t i = 0; i < kStageCount; ++i)
    stages[std::string(kStageNames[i])] = r.solver.seconds.seconds[i];
  return {{"total", r.wall}, {"stages", stages}};
}

Json solver_json(const RunRecord& r) {
  const SolverSettings& settings = r.sim->model->solver;
  const SolverSummary& s = r.solver;
  return {{"method", method_name(settings.method)},
          {"max_iterations", settings.max_iterations},
          {"tolerance_mps", settings.tolerance},
          {"penetration_tolerance", settings.penetration_tolerance},
          {"penetration_met", s.max_penetration_relative <= settings.penetration_tolerance},
          {"steps_solved", s.solved_steps},
          {"iterations_mean", s.iterations_mean},
          {"iterations_max", s.iterations_max},
          {"steps_at_iteration_cap", s.steps_at_cap},
          {"steps_non_finite_residual", s.steps_non_finite},
          {"residual_median_mps", s.residual_median},
          {"residual_p95_mps", s.residual_p95},
          {"residual_max_mps", s.residual_max},
          {"max_penetration_m", s.max_penetration},
          {"max_penetration_relative", s.max_penetration_relative},
          {"max_wall_penetration_relative", s.max_wall_penetration_relative},
          {"max_surface_yield_m", s.max_yield},
          {"steps_impulses_scaled", s.steps_impulses_scaled},
          {"wall_guard_corrections", s.wall_corrections},
          {"wall_guard_bodies_finished", s.walls_finished},
          {"wall_guard_bodies_unfinished", s.walls_unfinished},
          {"sliding_releases", s.sliding_releases},
          {"spin_limited", s.spin_limited},
          {"unlisted_wall_stops", s.unlisted_wall_stops},
          {"drag_held", s.drag_held},
          {"joint_drift_max_m", s.max_joint_drift},
          {"particles_max", s.max_particles},
          {"contacts_max", s.max_contacts},
          {"asleep_max", s.max_asleep}};
}

// A value that only some runs have: "n/a" for the others.
Json value_or_na(bool applies, double value) { return applies ? Json(value) : Json("n/a"); }

Json contact_json(const RunRecord& r) {
  const bool dem = r.sim->model->contact_model == ContactModel::DEM;
  const double rayleigh = r.solver.rayleigh_time_min;
  const bool four = r.sim->model->contact.manifold == Manifold::Four;
  const SleepSettings& sleep = r.sim->model->sleep;
  const Json sleep_json = sleep.enabled ? Json{{"speed_mps", sleep.speed}, {"time_s", sleep.time}}
                                        : Json("off");
  return {{"model", dem ? "dem" : "dvi"},
          {"manifold", four ? "four" : "hold"},
          {"flake_faces", r.sim->model->contact.flat_faces ? "flat" : "spheres"},
          {"sleep", sleep_json},
          {"rayleigh_time_min_s", value_or_na(dem && std::isfinite(rayleigh), rayleigh)},
          {"steps_above_rayleigh_limit", r.solver.steps_above_rayleigh_limit}};
}

Json energy_json(const RunRecord& r) {
  const EnergyBalance& e = r.energy;
  const bool passive = e.not_passive.empty();
  return {{"balance", passive ? "passive" : "n/a"},
          {"reason", e.not_passive},
          {"initial_J", e.initial},
          {"fed_J", e.fed},
          {"removed_J", e.removed},
          {"final_J", e.final},
          {"dissipated_J", value_or_na(passive, e.dissipated)},
          {"max_gain_J", value_or_na(passive, e.max_gain)},
          {"peak_kinetic_J", e.peak_kinetic},
          {"max_gain_relative", value_or_na(passive, e.max_gain_relative())}};
}

Json feeds_json(const RunRecord& r) {
  Json feeds = Json::array();
  for (const FeedRecord& f : r.feeds)
    feeds.push_back({{"name", f.name},
                     {"rate_basis", f.by_mass ? "mass" : "count"},
                     {"target", f.target},
                     {"fed", tally_json(f.fed)},
                     {"spawn_retries", f.retries},
                     {"deferrals", f.deferrals}});
  return feeds;
}

Json spawn_json(const RunRecord& r) {
  std::uint64_t retries = 0, deferrals = 0;
  for (const FeedRecord& f : r.feeds) {
    retries += f.retries;
    deferrals += f.deferrals;
  }
  return {{"retries", retries}, {"deferrals", deferrals}};
}

Json collectors_json(const RunRecord& r) {
  Json out = Json::array();
  for (std::size_t k = 0; k < r.sim->collectors.size(); ++k) {
    const CollectorTallies& t = r.collection->collectors()[k];
    Json products = Json::array();
    for (const ProductResult& p : r.products) {
      if (p.collector != int(k)) continue;
      const auto& materials = r.sim->model->materials.materials();
      const ProductShare main = p.main();
      products.push_back(
          {{"name", r.sim->collectors[k].products[std::size_t(p.product)].name},
           {"mass_kg", p.total_kg},
           {"main_material", main.material < 0 ? "" : materials[std::size_t(main.material)].name},
           {"grade", main.grade},
           {"recovery", main.recovery},
           {"grade_se", main.grade_se},
           {"recovery_se", main.recovery_se}});
    }
    out.push_back({{"name", r.sim->collectors[k].name},
                   {"collected", tally_json(sum(t.total))},
                   {"outside_bins", tally_json(sum(t.outside))},
                   {"products", products}});
  }
  return out;
}

std::string grams(double kg) {
  char s[32];
  std::snprintf(s, sizeof s, "%.4g g", kg * 1e3);
  return s;
}

std::string count_and_mass(const Tally& t) {
  return std::to_string(t.count) + " (" + grams(t.kg()) + ")";
}

void print_products(const RunRecord& r, std::FILE* out) {
  if (r.products.empty()) return;
  std::fprintf(out, "products:\n");
  const auto& materials = r.sim->model->materials.materials();
  for (const ProductResult& p : r.products) {
    const Collector& c = r.sim->collectors[std::size_t(p.collector)];
    const std::string name = c.name + "/" + c.products[std::size_t(p.product)].name;
    const ProductShare main = p.main();
    if (main.material < 0) {
      std::fprintf(out, "  %-24s empty\n", name.c_str());
      continue;
    }
    std::fprintf(out, "  %-24s %-12s grade %.3f +- %.3f  recovery %.3f +- %.3f  %s\n", name.c_str(),
                 materials[std::size_t(main.material)].name.c_str(), main.grade, main.grade_se,
                 main.recovery, main.recovery_se, grams(p.total_kg).c_str());
  }
}

void print_indicators(const RunRecord& r, std::FILE* out) {
  const SolverSummary& s = r.solver;
  std::fprintf(out,
               "solver: iterations mean %.1f, max %d (%llu steps at the cap); residual "
               "median %.2g, p95 %.2g m/s; max penetration %.3g mm (%.3g of the radius)\n",
               s.iterations_mean, s.iterations_max, (unsigned long long)s.steps_at_cap,
               s.residual_median, s.residual_p95, s.max_penetration * 1e3,
               s.max_penetration_relative);
  const EnergyBalance& e = r.energy;
  if (e.not_passive.empty())
    std::fprintf(out, "energy: dissipated %.3g J, largest gain without a source %.3g J (%.2g of "
                      "the peak kinetic energy)\n",
                 e.dissipated, e.max_gain, e.max_gain_relative());
}

// Three significant digits: enough for a warning.
std::string g3(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%.3g", v);
  return s;
}

// How the steps' thread counts were chosen and how many steps ran at each.
Json threads_json(const RunRecord& r) {
  Json steps = Json::object();
  for (std::size_t n = 1; n < r.steps_at_threads.size(); ++n)
    if (r.steps_at_threads[n] > 0) steps[std::to_string(n)] = r.steps_at_threads[n];
  return {{"by", r.threads_adaptive ? "timing (adaptive)" : "fixed"}, {"steps_at", steps}};
}

}  // namespace

std::string rayleigh_warning(double step, double rayleigh_time, std::uint64_t steps) {
  return "DEM: the step (" + g3(step) + " s) is above a fifth of the Rayleigh time (" +
         g3(rayleigh_time) + " s) of the smallest particle" +
         (steps > 0 ? " in " + std::to_string(steps) + " steps" : std::string()) +
         ": explicit contact forces are unreliable (overlaps, energy gain, blow-up); take a "
         "step below " +
         g3(0.2 * rayleigh_time) + " s or a softer youngs_modulus";
}

void add_warnings(RunRecord& r) {
  auto warn = [&](std::string w) { r.warnings.push_back(std::move(w)); };
  const SolverSummary& s = r.solver;
  if (s.steps_at_cap > 0)
    warn(std::to_string(s.steps_at_cap) + " of " + std::to_string(s.solved_steps) +
         " solved steps stopped at the iteration cap before meeting the solver's tolerances");
  if (s.steps_non_finite > 0)
    warn(std::to_string(s.steps_non_finite) + " of " + std::to_string(s.solved_steps) +
         " solved steps met no finite solver residual (NaN or inf in the contact problem): "
         "those steps kept their warm start, apart from the safeguards on finite rows");
  const double allowed = r.sim->model->solver.penetration_tolerance;
  if (s.max_penetration_relative > allowed)
    warn("particles overlapped by up to " + g3(s.max_penetration_relative) +
         " of their radius, past solver.penetration_tolerance (" + g3(allowed) +
         "): consider a smaller time step or a higher max_iterations");
  if (s.steps_above_rayleigh_limit > 0)
    warn(rayleigh_warning(r.sim->model->step, s.rayleigh_time_min, s.steps_above_rayleigh_limit));
  if (s.drag_held > 0)
    warn("drag: the step (" + g3(r.sim->model->step) +
         " s) is above the drag relaxation time of some particles (" + std::to_string(s.drag_held) +
         " particle-steps): their drag was held to stopping them against the air in a step, "
         "so they settle at g times the step instead of their terminal speed; take a smaller "
         "time step");
  const EnergyBalance& e = r.energy;
  if (e.not_passive.empty() && e.max_gain_relative() > kEnergyGainWarning)
    warn("energy grew without a source by up to " + g3(e.max_gain) + " J (" +
         g3(e.max_gain_relative()) +
         " of the peak kinetic energy): consider a smaller time step or more iterations");
  for (const FeedRecord& f : r.feeds) {
    if (f.deferrals > 0)
      warn("feed '" + f.name + "': " + std::to_string(f.deferrals) +
           " particles deferred to a later step because its region was full");
    const double fed = f.by_mass ? f.fed.kg() : double(f.fed.count);
    const double one = f.by_mass && f.fed.count > 0 ? fed / double(f.fed.count) : 1.0;
    if (f.target - fed > 1.5 * one)
      warn("feed '" + f.name + "' fed " + format_number(fed) + " of the " +
           format_number(f.target) + (f.by_mass ? " kg" : " particles") + " its rate asked for");
  }
  for (const LossReason reason : kLossReasons)
    if (const Tally t = sum(r.collection->lost(reason)); t.count > 0)
      warn(std::to_string(t.count) + " particles lost: " + std::string(to_string(reason)));
  if (!balanced(r, fates(r))) warn("internal: particle balance does not close");
}

std::string summary_json(const RunRecord& r) {
  const Simulation& sim = *r.sim;
  Json j = {{"tool", "ces-sim"},
            {"version", CES_VERSION},
            {"complete", r.complete},
            {"reason", r.reason},
            {"scene", {{"name", sim.name}, {"path", sim.scene_path}, {"hash", sim.scene_hash}}},
            {"seed", sim.seed},
            {"threads", r.threads},
            {"threads_chosen", threads_json(r)},
            {"step_s", sim.model->step},
            {"end_time_s", sim.end_time},
            {"steps", r.steps},
            {"simulated_time_s", r.time},
            {"wall_time_s", wall_json(r)},
            {"peak_memory_mib", r.peak_memory / double(1 << 20)},
            {"balance", balance_json(r)},
            {"collectors", collectors_json(r)},
            {"solver", solver_json(r)},
            {"contact", contact_json(r)},
            {"energy", energy_json(r)},
            {"feeds", feeds_json(r)},
            {"spawn", spawn_json(r)},
            {"trajectory_frames", r.frames},
            {"active_components", sim.active_components},
            {"warnings", r.warnings},
            {"files", r.files}};
  return j.dump(2) + "\n";
}

void print_report(const RunRecord& r, std::FILE* out) {
  const Fates f = fates(r);
  std::fprintf(out, "ces-sim %s: %s, seed %llu, %d thread%s\n", CES_VERSION, r.sim->name.c_str(),
               (unsigned long long)r.sim->seed, r.threads, r.threads == 1 ? "" : "s");
  const std::string status = r.complete ? "complete" : "INCOMPLETE (" + r.reason + ")";
  std::fprintf(out, "%s: %llu steps, %.4g s simulated in %.3g s wall, peak memory %.0f MiB\n",
               status.c_str(), (unsigned long long)r.steps, r.time, r.wall,
               r.peak_memory / double(1 << 20));
  std::fprintf(out, "particles: fed %s, collected %s, lost %s, in flight %s\n",
               count_and_mass(sum(r.fed)).c_str(), count_and_mass(sum(f.collected)).c_str(),
               count_and_mass(sum(f.lost)).c_str(), count_and_mass(sum(r.active)).c_str());
  print_products(r, out);
  print_indicators(r, out);
  for (const std::string& w : r.warnings) std::fprintf(out, "warning: %s\n", w.c_str());
  std::fprintf(out, "output: %s\n", r.out_dir.c_str());
}

}  // namespace ces::output
