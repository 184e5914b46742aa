// The field picture a scene asks for with output.field: the field model
// sampled on a regular grid in the drum's cross-section (z = 0), as a table
// (field.csv) and as a picture (field.svg: |E| in kV/cm with direction
// arrows, the drum and the electrodes, like the seed's Figure 5).
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "spec/simulation.hpp"

namespace ces::output {

struct FieldGrid {
  FieldPicture picture;
  int nx = 0, ny = 0;                            // nodes x_i = min.x + i·resolution, likewise y
  std::vector<Vec2> field;                       // (Ex, Ey) at node i + nx·j, V/m
  std::vector<std::optional<double>> potential;  // V; none for a gridded field
  Vec2 node(int i, int j) const;
};

// Samples sim.electrostatics' field over sim.output.field (both must be set).
FieldGrid sample_field(const Simulation& sim);

// Header x_m,y_m,ex_vpm,ey_vpm,e_vpm,phi_v; rows by y, then x; phi empty
// where the model has no potential.
std::string field_csv(const FieldGrid& grid);

// Hand-written SVG with fixed number formats: the same scene gives the same
// bytes.
std::string field_svg(const Simulation& sim, const FieldGrid& grid);

}  // namespace ces::output
