// The step loop allocates nothing once its buffers have grown to the run's
// peak: every buffer of the pipeline is kept across steps.
// Counted by replacing the global allocation functions for this binary;
// they count only while a test asks them to.
#include <gtest/gtest.h>
#include <omp.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "sim/world.hpp"

namespace {
std::atomic<bool> counting{false};
std::atomic<long> allocations{0};
}  // namespace

// GCC sees the replaced delete's free() inlined where a pointer came from
// new and warns of a mismatch; here new and delete are malloc and free.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
void* operator new(std::size_t size) {
  if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return ::operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace ces {
namespace {

// A settled box of spheres and two-sphere clusters on a mesh floor inside
// plane walls: broadphase, sphere, cluster and mesh narrowphase, assembly,
// the solver and integration all run every step.
std::unique_ptr<World> settled_box(SolverMethod method) {
  auto m = std::make_shared<Model>();
  m->step = 1e-3;
  m->materials = MaterialTable({{"glass", 2500.0, 0.4, 0.0}}, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  m->shapes.push_back(make_particle_shape({Vec3(-0.6, 0, 0), Vec3(0.6, 0, 0)}, {0.8, 0.8}));
  m->solver.method = method;
  m->solver.max_iterations = 30;
  m->solver.tolerance = 1e-9;
  RigidBody floor;
  floor.name = "floor";
  floor.shape = std::make_shared<const geo::TriMesh>(
      std::vector<Vec3>{Vec3(-0.1, 0, -0.1), Vec3(0.1, 0, -0.1), Vec3(0.1, 0, 0.1), Vec3(-0.1, 0, 0.1)},
      std::vector<std::array<std::uint32_t, 3>>{{0, 2, 1}, {0, 3, 2}});
  m->bodies.push_back(floor);
  for (const Vec3& n : {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)}) {
    RigidBody wall;
    wall.name = "wall";
    wall.shape = geo::Plane{n, -0.02};
    m->bodies.push_back(wall);
  }
  auto w = std::make_unique<World>(m);
  const double r = 0.002;
  for (int layer = 0; layer < 4; ++layer)
    for (int i = 0; i < 8; ++i)
      for (int k = 0; k < 8; ++k)
        w->add_particle((i + k + layer) % 2, r, 0,
                        Vec3(-0.017 + 0.0048 * i, r + 0.0045 * layer, -0.017 + 0.0048 * k));
  for (int s = 0; s < 1000; ++s) w->step();  // the pile collapses by step ~500
  return w;
}

long allocations_in_steps(World& w, int steps) {
  allocations = 0;
  counting = true;
  for (int s = 0; s < steps; ++s) w.step();
  counting = false;
  return allocations.load();
}

// One settled box per solver, stepped on one thread and then on two: a
// change of thread count may grow a buffer once (a thread's own, a chunk
// list), so each count first takes a few steps uncounted.
TEST(Allocation, SettledStepsAllocateNothing) {
  for (SolverMethod method : {SolverMethod::APGD, SolverMethod::SPG, SolverMethod::PGS}) {
    omp_set_num_threads(2);
    auto w = settled_box(method);
    ASSERT_GT(w->contacts().size(), 256u);  // large enough for the parallel paths
    for (int threads : {1, 2}) {
      omp_set_num_threads(threads);
      for (int s = 0; s < 10; ++s) w->step();
      EXPECT_EQ(allocations_in_steps(*w, 50), 0)
          << "threads " << threads << ", method " << int(method);
    }
  }
  omp_set_num_threads(omp_get_num_procs());
}

}  // namespace
}  // namespace ces
