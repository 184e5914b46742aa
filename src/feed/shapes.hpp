// Particle templates a feed can name besides the scene's own clusters: the
// built-in flake and rod, and sphere clusters read from a CSV file. Spheres
// come in any frame; make_particle_shape (model/model.hpp) moves them to
// the principal frame.
#pragma once
#include <filesystem>
#include <vector>

#include "common/math.hpp"

namespace ces::feed {

struct SphereList {
  std::vector<Vec3> centers;
  std::vector<double> radii;
};

// A flake of width 1 and thickness `aspect` (0 < aspect <= 1), flat in the
// x–y plane: one layer of spheres of diameter `aspect` on a hexagonal
// lattice, in as many rings as it takes for neighbours to touch or overlap
// (a contiguous plate, no gaps a small grain could lodge in): 19 spheres at
// aspect 0.2. A flat layer is what lets a flake lie on the drum on many
// spheres at once, as crushed PCB flakes do.
SphereList flake_spheres(double aspect);

// A rod of length 1 and thickness `aspect` (0 < aspect <= 1) along x:
// spheres overlapping by at least half a radius, so it rolls nearly as
// smoothly as a cylinder.
SphereList rod_spheres(double aspect);

// One sphere per row "x,y,z,r" (r > 0); blank lines and lines starting with
// '#' are skipped, and a first row "x,y,z,r" is taken as a header. Throws
// std::runtime_error "<file>:<line>: <reason>", or "<file>: <reason>".
SphereList read_sphere_csv(const std::filesystem::path& path);

}  // namespace ces::feed
