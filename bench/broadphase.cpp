// Our grid broadphase rebuilt from scratch against Bullet's dynamic AABB tree
// updated incrementally, on a loose random cloud (solid fraction ~0.3: what a
// falling curtain looks like).
#include <omp.h>

#include <cstdint>

#include "bench.hpp"
#include "collision/broadphase.hpp"

#ifdef CES_HAVE_BULLET
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/BroadphaseCollision/btOverlappingPairCache.h>
#endif

namespace bench {

using ces::Vec3;

namespace {

constexpr int kReps = 5;

std::vector<Vec3> random_cloud(std::size_t n, double r, std::vector<double>& radii) {
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

void time_grid(const std::vector<Vec3>& centres, const std::vector<double>& radii,
               BroadphaseRun& run) {
  ces::GridBroadphase grid;
  std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
  grid.find_pairs(centres, radii, pairs);
  const auto t0 = Clock::now();
  for (int k = 0; k < kReps; ++k) grid.find_pairs(centres, radii, pairs);
  run.grid = since(t0) / kReps;
  run.grid_pairs = pairs.size();
}

#ifdef CES_HAVE_BULLET
void set_box(btDbvtBroadphase& bp, btBroadphaseProxy* proxy, const Vec3& c, double r,
             double shift) {
  const btVector3 lo(c.x() - r + shift, c.y() - r, c.z() - r);
  const btVector3 hi(c.x() + r + shift, c.y() + r, c.z() + r);
  bp.setAabb(proxy, lo, hi, nullptr);
}

// Used the way a stepper would: proxies persist, every step moves them
// (setAabb) and recomputes the overlapping pairs. Bullet fattens every AABB by
// gDbvtMargin (0.05 units, sized for metre-scale bodies); at mm scale that
// makes every pair overlap, so it is set to the envelope.
void time_bullet(const std::vector<Vec3>& centres, const std::vector<double>& radii,
                 BroadphaseRun& run) {
  gDbvtMargin = 0.1 * 0.001;
  btDbvtBroadphase bp;
  std::vector<btBroadphaseProxy*> proxies(centres.size());
  for (std::size_t i = 0; i < centres.size(); ++i) {
    const Vec3& c = centres[i];
    const double r = radii[i];
    proxies[i] = bp.createProxy(btVector3(c.x() - r, c.y() - r, c.z() - r),
                                btVector3(c.x() + r, c.y() + r, c.z() + r), 0, nullptr, 1, 1,
                                nullptr);
  }
  bp.calculateOverlappingPairs(nullptr);
  const auto t0 = Clock::now();
  for (int k = 0; k < kReps; ++k) {
    const double shift = 1e-6 * (k + 1);  // every proxy moves, as in a flow
    for (std::size_t i = 0; i < centres.size(); ++i)
      set_box(bp, proxies[i], centres[i], radii[i], shift);
    bp.calculateOverlappingPairs(nullptr);
  }
  run.bullet = since(t0) / kReps;
  run.bullet_pairs = std::size_t(bp.getOverlappingPairCache()->getNumOverlappingPairs());
  run.have_bullet = true;
  for (auto* p : proxies) bp.destroyProxy(p, nullptr);
}
#endif

}  // namespace

BroadphaseRun measure_broadphase(std::size_t n) {
  omp_set_num_threads(1);
  std::vector<double> radii;
  const std::vector<Vec3> centres = random_cloud(n, 0.001, radii);
  BroadphaseRun run;
  run.particles = n;
  time_grid(centres, radii, run);
#ifdef CES_HAVE_BULLET
  time_bullet(centres, radii, run);
#endif
  return run;
}

}  // namespace bench
