// Packed beds: simple-cubic lattices of 1 mm spheres on a plane. Every
// interior sphere touches six neighbours, so the contact count is about 3 per
// sphere and reproducible.
#include <algorithm>
#include <cmath>

#include "bench.hpp"

namespace bench {

using namespace ces;

double BedRun::rate_per_core() const {
  return contact_iterations / stages[ces::Stage::Solve] / threads;
}

std::shared_ptr<Model> bed_model(int iterations, int threads) {
  auto m = std::make_shared<Model>();
  m->materials = MaterialTable({{"glass", 2500, 0.4, 0}}, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  RigidBody ground;
  ground.shape = geo::Plane{Vec3::UnitY(), 0.0};
  m->bodies.push_back(ground);
  m->solver.max_iterations = iterations;
  m->solver.tolerance = 0.0;  // run every iteration: throughput, not convergence
  m->threads = threads;
  return m;
}

void fill_bed(World& w, std::size_t n, double r, double pitch) {
  const int side = int(std::ceil(std::cbrt(double(n))));
  const double d = 2 * r * pitch;
  const double y0 = r + (d - 2 * r);  // the bottom layer keeps the same gap to the ground
  std::size_t count = 0;
  for (int y = 0; count < n; ++y)
    for (int x = 0; x < side && count < n; ++x)
      for (int z = 0; z < side && count < n; ++z, ++count)
        w.add_particle(0, r, 0, Vec3(d * x, y0 + d * y, d * z));
}

namespace {

// Means per step from the sums.
void average(BedRun& run) {
  const double k = 1.0 / run.steps;
  run.wall *= k;
  run.solver_iterations *= k;
  run.contact_iterations *= k;
  for (double& x : run.stages.seconds) x *= k;
}

}  // namespace

BedRun measure_bed(std::size_t n, int threads, int iterations, double work) {
  World w(bed_model(iterations, threads));
  fill_bed(w, n, 0.001, 1.0);
  // A simple-cubic stack under gravity is unstable: left alone it topples
  // within tens of steps and the contact count drifts. Putting the bed back
  // after every step makes every step solve the same problem.
  const Particles start = w.particles();
  BedRun run;
  run.particles = n;
  run.threads = threads;
  run.iterations = iterations;
  run.contacts = w.step().contacts;  // warm caches and the warm start
  w.particles() = start;
  const double per_step = double(std::max<std::size_t>(run.contacts, 1)) * iterations;
  run.steps = int(std::clamp(std::ceil(work / per_step), 2.0, 200.0));
  for (int s = 0; s < run.steps; ++s) {
    const auto t0 = Clock::now();
    const StepStats& st = w.step();
    run.wall += since(t0);
    run.stages += st.seconds;
    run.solver_iterations += st.solver.iterations;
    run.contact_iterations += double(st.contacts) * st.solver.iterations;
    run.contacts = st.contacts;
    w.particles() = start;  // copy-assigning into the same sizes: no allocation
  }
  average(run);
  return run;
}

}  // namespace bench
