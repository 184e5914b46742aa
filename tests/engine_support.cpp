#include "engine_support.hpp"

namespace ces::test {

std::string material_name(std::size_t i) {
  std::string name = "m";
  name += std::to_string(i);
  return name;
}

std::shared_ptr<Model> base_model(std::vector<double> frictions, double step) {
  auto m = std::make_shared<Model>();
  m->step = step;
  std::vector<Material> mats;
  for (std::size_t i = 0; i < frictions.size(); ++i)
    mats.push_back({material_name(i), 2500.0, frictions[i], 0.0});
  m->materials = MaterialTable(mats, {});
  m->shapes.push_back(make_particle_shape({Vec3::Zero()}, {1.0}));
  m->solver.max_iterations = 500;
  m->solver.tolerance = 1e-10;
  return m;
}

}  // namespace ces::test
