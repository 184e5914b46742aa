#include "spec/simulation.hpp"

namespace ces {

std::vector<double> shape_sizes(const Simulation& sim) {
  const std::vector<ParticleShape>& shapes = sim.model->shapes;
  std::vector<double> size(shapes.size(), 0.0);
  for (const Feed& f : sim.feeds)
    for (const FeedComponent& c : f.mix)
      if (size.at(std::size_t(c.shape)) == 0.0) size[std::size_t(c.shape)] = c.shape_size;
  for (std::size_t s = 0; s < shapes.size(); ++s)
    if (size[s] == 0.0) size[s] = 2.0 * shapes[s].bounding_radius;
  return size;
}

}  // namespace ces
