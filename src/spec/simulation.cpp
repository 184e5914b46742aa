#include "spec/simulation.hpp"

namespace ces {

std::vector<double> shape_sizes(const Simulation& sim) {
  const std::vector<ParticleShape>& shapes = sim.model->shapes;
  std::vector<double> size(shapes.size(), 0.0);
  const auto set = [&](int shape, double value) {
    if (size.at(std::size_t(shape)) == 0.0) size[std::size_t(shape)] = value;
  };
  for (const Feed& f : sim.feeds)
    for (const FeedComponent& c : f.mix) {
      if (!c.drawn) set(c.shape, c.shape_size);
      else
        for (const DrawnShape::Rung& r : c.drawn->ladder) set(r.shape, r.extent);
    }
  for (std::size_t s = 0; s < shapes.size(); ++s)
    if (size[s] == 0.0) size[s] = 2.0 * shapes[s].bounding_radius;
  return size;
}

}  // namespace ces
