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

Quat add_raft_shape(Model& m, int half, double spacing) {
  std::vector<Vec3> centres;
  for (int i = -half; i <= half; ++i)
    for (int k = -half; k <= half; ++k) centres.emplace_back(spacing * i, 0.0, spacing * k);
  m.shapes.push_back(make_particle_shape(centres, std::vector<double>(centres.size(), 1.0)));
  Eigen::Index normal_axis;
  m.shapes.back().unit_inertia.maxCoeff(&normal_axis);
  return Quat::FromTwoVectors(Vec3::Unit(normal_axis), Vec3::UnitY());
}

}  // namespace ces::test
