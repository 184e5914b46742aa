// A collector as a scene states it: a plane that takes the particles
// crossing it, with bins and products along an axis.
#pragma once
#include <string>
#include <vector>

#include "common/math.hpp"

namespace ces {

// A named range of a collector's bin axis.
struct Product {
  std::string name;
  double from = 0.0, to = 0.0;     // along the bin axis (m)
};
// A collector plane: a particle is collected when its centre crosses the
// plane against the normal (from the side the normal points to).
struct Collector {
  std::string name;
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitY();
  Vec3 axis = Vec3::UnitX();       // bins and products are measured along it
  double from = 0.0, to = 1.0;
  int bins = 10;
  std::vector<Product> products;
};

}  // namespace ces
