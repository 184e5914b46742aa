// ces_bench: solver throughput, per-stage step times and broadphase choice.
//
//   ces_bench [--quick] [--out DIR]
//
// Writes DIR/bench.csv (one row per measurement) and prints a short report.
// Packed beds are simple-cubic lattices of touching spheres on a plane, so
// every interior sphere has six contacts and the counts are reproducible.
#include <omp.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "collision/broadphase.hpp"
#include "dynamics/world.hpp"

#ifdef CES_HAVE_BULLET
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/BroadphaseCollision/btOverlappingPairCache.h>
#endif

namespace {

using namespace ces;
using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct Row {
  std::string what;
  std::size_t particles, contacts;
  int threads;
  double value;
  std::string unit;
};

std::shared_ptr<Model> bed_model(int iterations) {
  auto m = std::make_shared<Model>();
  m->materials = MaterialTable({{"glass", 2500, 0.4, 0}}, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  RigidBody ground;
  ground.shape = geo::Plane{Vec3::UnitY(), 0.0};
  m->bodies.push_back(ground);
  m->solver.max_iterations = iterations;
  m->solver.tolerance = 0.0;  // run every iteration: throughput, not convergence
  return m;
}

void fill_bed(World& w, std::size_t n, double r) {
  const int side = int(std::ceil(std::cbrt(double(n))));
  std::size_t count = 0;
  for (int y = 0; count < n; ++y)
    for (int x = 0; x < side && count < n; ++x)
      for (int z = 0; z < side && count < n; ++z, ++count)
        w.add_particle(0, r, 0, Vec3(2 * r * x, r + 2 * r * y, 2 * r * z));
}

// Steps a packed bed and reports contact-iterations per second per core and
// the time per step split by stage.
void bench_solver(std::size_t n, int threads, int iterations, int steps, std::vector<Row>& rows) {
  omp_set_num_threads(threads);
  auto m = bed_model(iterations);
  World w(m);
  fill_bed(w, n, 0.001);
  w.step();  // warm caches and the warm start
  StageTimes total;
  double solve_iterations = 0;
  std::size_t contacts = 0;
  for (int s = 0; s < steps; ++s) {
    const StepStats& st = w.step();
    total += st.seconds;
    solve_iterations += st.solver.iterations;
    contacts = st.contacts;
  }
  // APGD applies N twice per iteration (gradient at y and at the new iterate).
  const double rate = double(contacts) * solve_iterations / total.solve / threads;
  rows.push_back({"solver_contact_iterations_per_s_per_core", n, contacts, threads, rate, "1/s"});
  const std::pair<const char*, double> stages[] = {
      {"stage_broadphase", total.broadphase}, {"stage_narrowphase", total.narrowphase},
      {"stage_assemble", total.assemble},     {"stage_solve", total.solve},
      {"stage_integrate", total.integrate},   {"step_total", total.total()}};
  for (const auto& [name, seconds] : stages)
    rows.push_back({name, n, contacts, threads, seconds / steps, "s/step"});
}

std::vector<Vec3> random_cloud(std::size_t n, double r, std::vector<double>& radii) {
  // A loose random packing (solid fraction ~0.3): what a falling curtain looks like.
  const double side = std::cbrt(double(n) * 4.19 * r * r * r / 0.3);
  std::vector<Vec3> c(n);
  std::uint64_t s = 12345;
  auto uniform = [&] {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(s >> 11) * 0x1.0p-53;
  };
  for (auto& p : c) p = side * Vec3(uniform(), uniform(), uniform());
  radii.assign(n, 1.2 * r);  // radius plus envelope
  return c;
}

void bench_broadphase(std::size_t n, std::vector<Row>& rows) {
  omp_set_num_threads(1);
  std::vector<double> radii;
  const std::vector<Vec3> centres = random_cloud(n, 0.001, radii);
  GridBroadphase grid;
  std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
  grid.find_pairs(centres, radii, pairs);
  const int reps = 5;
  auto t0 = Clock::now();
  for (int k = 0; k < reps; ++k) grid.find_pairs(centres, radii, pairs);
  rows.push_back({"broadphase_grid", n, pairs.size(), 1, since(t0) / reps, "s"});
#ifdef CES_HAVE_BULLET
  // Bullet's dynamic AABB tree, used the way a stepper would: proxies persist,
  // every step moves them (setAabb) and recomputes the overlapping pairs.
  // Bullet fattens every AABB by gDbvtMargin (0.05 units, sized for metre-scale
  // bodies); at mm scale that makes every pair overlap. Use the envelope.
  gDbvtMargin = 0.1 * 0.001;
  btDbvtBroadphase bp;
  btDispatcher* no_dispatcher = nullptr;
  std::vector<btBroadphaseProxy*> proxies(n);
  for (std::size_t i = 0; i < n; ++i) {
    const btVector3 lo(centres[i].x() - radii[i], centres[i].y() - radii[i], centres[i].z() - radii[i]);
    const btVector3 hi(centres[i].x() + radii[i], centres[i].y() + radii[i], centres[i].z() + radii[i]);
    proxies[i] = bp.createProxy(lo, hi, 0, nullptr, 1, 1, no_dispatcher);
  }
  bp.calculateOverlappingPairs(no_dispatcher);
  t0 = Clock::now();
  for (int k = 0; k < reps; ++k) {
    const double shift = 1e-6 * (k + 1);  // every proxy moves, as in a flow
    for (std::size_t i = 0; i < n; ++i) {
      const btVector3 lo(centres[i].x() - radii[i] + shift, centres[i].y() - radii[i], centres[i].z() - radii[i]);
      const btVector3 hi(centres[i].x() + radii[i] + shift, centres[i].y() + radii[i], centres[i].z() + radii[i]);
      bp.setAabb(proxies[i], lo, hi, no_dispatcher);
    }
    bp.calculateOverlappingPairs(no_dispatcher);
  }
  const double bullet = since(t0) / reps;
  rows.push_back({"broadphase_bullet_dbvt", n,
                  std::size_t(bp.getOverlappingPairCache()->getNumOverlappingPairs()), 1, bullet, "s"});
  for (auto* p : proxies) bp.destroyProxy(p, no_dispatcher);
#endif
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string out = "bench/out";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else {
      std::fprintf(stderr, "usage: ces_bench [--quick] [--out DIR]\n");
      return 2;
    }
  }
  std::vector<Row> rows;
  const int procs = omp_get_num_procs();
  for (std::size_t n : {std::size_t(10000), std::size_t(100000)}) {
    if (quick && n > 10000) break;
    bench_solver(n, 1, 100, quick ? 2 : 5, rows);
    if (procs > 1) bench_solver(n, 2, 100, quick ? 2 : 5, rows);
    bench_broadphase(n, rows);
  }
  std::filesystem::create_directories(out);
  std::ofstream csv(out + "/bench.csv");
  csv << "measure,particles,contacts,threads,value,unit\n";
  for (const Row& r : rows) {
    char line[256];
    std::snprintf(line, sizeof line, "%s,%zu,%zu,%d,%.6g,%s\n", r.what.c_str(), r.particles,
                  r.contacts, r.threads, r.value, r.unit.c_str());
    csv << line;
    std::fputs(line, stdout);
  }
  std::printf("wrote %s/bench.csv\n", out.c_str());
  return 0;
}
