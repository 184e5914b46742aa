// A feed as a scene states it: where particles enter, at what rate, and the
// mix of materials, shapes and sizes they are drawn from.
#pragma once
#include <string>
#include <vector>

#include "common/math.hpp"
#include "feed/size_distribution.hpp"
#include "geometry/shapes.hpp"
#include "model/defaults.hpp"

namespace ces {

// One component of a feed's mix.
struct FeedComponent {
  int material = 0;
  double mass_fraction = 1.0;      // fractions of a feed sum to 1
  feed::SizeDistribution size = feed::SizeDistribution::constant(1e-3);
  int shape = 0;                   // Model::shapes index; size = scale * shape_size
  // The shape's characteristic size at scale 1 (m): for spheres, flakes and
  // rods the diameter of the sphere of equal volume, for scene clusters
  // their `size`. Size distributions draw this size.
  double shape_size = 1.0;
};

struct Feed {
  std::string name;
  // Spawn region: a box, or an outlet rectangle (a box of zero thickness).
  geo::Aabb region;
  double start = 0.0;              // s
  double duration = 1e300;         // s
  // Exactly one of these rates is > 0.
  double mass_rate = 0.0;          // kg/s
  double count_rate = 0.0;         // 1/s
  Vec3 velocity = Vec3::Zero();    // mean initial velocity
  double velocity_spread = 0.0;    // m/s, uniform per component in [-s, s]
  bool random_orientation = true;
  int max_attempts = defaults::kFeedMaxAttempts;  // spawn retries before a particle is deferred
  std::vector<FeedComponent> mix;
};

}  // namespace ces
