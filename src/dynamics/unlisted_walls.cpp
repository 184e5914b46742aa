#include "dynamics/unlisted_walls.hpp"

#include <vector>

#include "common/parallel.hpp"

namespace ces {
namespace {

// Each pass stops the particle at the wall it would cross deepest; a
// second wall (a corner) takes another.
constexpr int kPasses = 4;

// Whether body k is a wall for particle i all step long: its surface where
// its pose puts it, and not yielding to the particle.
bool is_wall(const Model& m, const Bodies& bodies, std::size_t k, const Particles& p,
             std::size_t i) {
  return turns_in_place(m, bodies, k) &&
         m.materials.pair(m.bodies[k].material, p.material[i]).compliance == 0.0;
}

// The deepest one of particle i's spheres ends past a wall's surface, beyond
// the overlap aim, moving at (v, w) for the step; and the wall's normal.
struct Crossing {
  double depth = 0.0;
  Vec3 normal = Vec3::Zero();
};

Crossing deepest_crossing(const Model& m, const Particles& p, const Bodies& bodies, std::size_t i,
                          const Vec3& v, const Vec3& w) {
  static thread_local std::vector<geo::SurfaceHit> hits;
  const ParticleShape& shape = m.shapes[std::size_t(p.shape[i])];
  const Mat3 R = p.orientation[i].toRotationMatrix() * p.scale[i];
  const double h = m.step, aim = m.solver.overlap_aim();
  const Vec3 centre_end = p.position[i] + h * v;
  const double reach = bounding_radius(m, p, i) * (1.0 + h * w.norm());
  Crossing worst;
  for (std::size_t k = 0; k < m.bodies.size(); ++k) {
    if (!is_wall(m, bodies, k, p, i)) continue;
    const geo::Shape& surface = m.bodies[k].shape;
    const Pose& pose = bodies.pose[k];
    // One query of the centre passes over a wall that no sphere reaches:
    // turning by h |w| moves a sphere's centre off the centre's by at most
    // that times its arm.
    hits.clear();
    geo::query(surface, pose.inverse_apply(centre_end), reach, hits);
    if (hits.empty()) continue;
    for (std::size_t s = 0; s < shape.centers.size(); ++s) {
      const Vec3 arm = R * shape.centers[s];
      const Vec3 end = p.position[i] + arm + h * (v + w.cross(arm));
      const double r = shape.radii[s] * p.scale[i];
      hits.clear();
      geo::query(surface, pose.inverse_apply(end), r, hits);
      for (const geo::SurfaceHit& hit : hits) {
        const double depth = r - hit.distance - aim * r;
        if (depth > worst.depth) worst = {depth, pose.orientation * hit.normal};
      }
    }
  }
  return worst;
}

}  // namespace

std::size_t stop_at_unlisted_walls(const Model& model, const Particles& p, const Bodies& bodies,
                                   std::span<const double> envelope, SolverBodies& B) {
  const double h = model.step;
  // Particle i's stops; whether it was stopped.
  auto stop = [&](std::size_t i) {
    if (p.asleep(i)) return false;
    Vec3& v = B.v[i];
    const Vec3& w = B.w[i];
    // Within its envelope every surface it can reach was listed.
    if ((v.norm() + w.norm() * bounding_radius(model, p, i)) * h <= envelope[i]) return false;
    bool stopped = false;
    for (int pass = 0; pass < kPasses; ++pass) {
      const Crossing c = deepest_crossing(model, p, bodies, i, v, w);
      if (!(c.depth > 0.0)) break;
      v += c.normal * (c.depth / h);
      stopped = true;
    }
    return stopped;
  };
  // In fixed chunks, balanced between the threads: the fast particles,
  // the only ones looked at, come in runs.
  return reduce_chunks<std::size_t>(p.size(),
                                    [&](std::size_t begin, std::size_t end, std::size_t& stopped) {
                                      for (std::size_t i = begin; i < end; ++i)
                                        stopped += stop(i) ? 1 : 0;
                                    });
}

}  // namespace ces
