// A feed as a scene states it: where particles enter, at what rate, and the
// mix of materials, shapes and sizes they are drawn from.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "common/math.hpp"
#include "feed/size_distribution.hpp"
#include "geometry/shapes.hpp"
#include "model/model.hpp"

namespace ces {

// A flake or rod whose thickness and width (flake) or length (rod) each
// particle draws. Its mass, inertia and volume are those of the drawn
// solid: a disc of diameter `width` (its face's area-equivalent diameter)
// and thickness t; a cylinder of diameter t with hemispherical ends, `length`
// long in all. It touches as the built-in shape of the nearest aspect on a
// ladder (Rung), scaled to the drawn width or length, so the contact
// geometry of a flake thinner than the thinnest rung is that rung's,
// thicker than the flake: very thin flakes would need hundreds of spheres.
struct DrawnShape {
  enum class Kind { Flake, Rod };
  struct Rung {
    int shape = 0;        // Model::shapes index
    double aspect = 0.0;  // its thickness / width (flake) or / length (rod)
    double extent = 1.0;  // its width (face's area-equivalent diameter) or length at scale 1, m
  };
  Kind kind = Kind::Flake;
  feed::SizeDistribution thickness = feed::SizeDistribution::constant(1e-3);
  feed::SizeDistribution extent = feed::SizeDistribution::constant(1e-3);  // width or length
  std::vector<Rung> ladder;  // aspects rising by a constant ratio

  // The rung whose aspect is nearest t/extent (in ratio), clamped to the ladder.
  const Rung& rung(double thickness, double extent) const;
  double volume(double thickness, double extent) const;
  // Principal inertia per unit mass of the drawn solid in the rung shape's
  // principal frame (its axes ordered as the shape's).
  Vec3 unit_inertia(double thickness, double extent, const Vec3& shape_unit_inertia) const;
  // The bounding radius of the largest particle it can make, over the rungs
  // (`shapes`: Model::shapes).
  double largest_bounding_radius(const std::vector<ParticleShape>& shapes) const;
};

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
  // Set: each particle draws its dimensions instead (size, shape and
  // shape_size unused).
  std::optional<DrawnShape> drawn;
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
  // Set: particles start lying flat, their principal axis of largest
  // inertia (a flake's face normal) along this unit vector (up, against
  // gravity), turned at random about it (random_orientation) or not.
  std::optional<Vec3> lie_flat;
  int max_attempts = defaults::kFeedMaxAttempts;  // spawn retries before a particle is deferred
  std::vector<FeedComponent> mix;
};

}  // namespace ces
