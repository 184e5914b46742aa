#pragma once
// The reference machine's nip, for the tests of grains pinched in it: the
// drum (r 0.16 m) and the brush (r 0.053 m) touching it at 9 o'clock,
// both kinematic and turning the same way at omega, so that at the nip
// their surfaces move opposite.
#include "model/model.hpp"
#include "sim/world.hpp"

namespace ces::test {

// Adds the drum and the brush to m's bodies, of the given materials.
void add_drum_and_brush(Model& m, double omega, int drum_material, int brush_material);

// Six flakes of shape `flake_shape` (1.2 mm wide) falling on edge at 1 m/s
// into the wedge above the nip, where it is 0.5 to 1.5 mm wide, and six
// spheres of shape 0 (r 0.5 mm) riding the drum up into the wedge below it
// at its surface speed; all of material 0.
void add_nip_grains(World& w, int flake_shape, double omega);

}  // namespace ces::test
