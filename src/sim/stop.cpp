#include "sim/stop.hpp"

#include <algorithm>
#include <map>
#include <sstream>
#include <vector>

#include "geometry/shapes.hpp"

namespace ces {
namespace {

// A particle rests on a body when the body's surface is within this many
// bounding radii of its centre.
constexpr double kOnBodyReach = 1.25;

// The first body (in the scene's order) a particle rests on, or -1.
int body_under(const World& world, std::size_t i, std::vector<geo::SurfaceHit>& hits) {
  const Particles& p = world.particles();
  const Model& m = world.model();
  const double reach =
      kOnBodyReach * p.scale[i] * m.shapes[std::size_t(p.shape[i])].bounding_radius;
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    hits.clear();
    geo::query(m.bodies[b].shape, world.bodies().pose[b].inverse_apply(p.position[i]), reach, hits);
    for (const geo::SurfaceHit& h : hits)
      if (h.distance < reach) return int(b);
  }
  return -1;
}

}  // namespace

bool feed_accounted_for(const World& world) {
  if (!world.particles().id.empty()) return false;
  return std::all_of(world.feeders().begin(), world.feeders().end(),
                     [&](const feed::Feeder& f) { return f.finished(world.time()); });
}

std::string cap_message(const Simulation& sim, const World& world) {
  const Particles& p = world.particles();
  std::vector<geo::SurfaceHit> hits;
  std::map<int, std::size_t> where;  // body (-1: none) -> particles
  double mass = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    ++where[body_under(world, i, hits)];
    mass += p.mass[i];
  }
  std::ostringstream out;
  out << sim.end_origin << ": the run reached its end of " << sim.end_time << " s with ";
  if (p.size() == 0) {
    out << "a feed still owing particles it could not place";
  } else {
    out << p.size() << " particles (" << mass * 1e3 << " g) still active:";
    const char* sep = " ";
    for (const auto& [body, count] : where) {
      if (body < 0) continue;
      out << sep << count << " on " << world.model().bodies[std::size_t(body)].name;
      sep = ", ";
    }
    if (where.count(-1)) out << sep << where.at(-1) << " in flight or on other particles";
  }
  out << "; expected every particle collected or lost (a later time.end, or collectors and a "
         "domain that catch them)";
  return out.str();
}

}  // namespace ces
