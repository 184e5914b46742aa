// The scene's electrostatics section -> the field model, the corona wires'
// bands, charging zones and per-material electrical behaviour
// (fields/electrostatics.hpp), with the checks the schema cannot make: the
// drum and brush exist and the drum sits where the field models put it,
// electrodes clear of the drum and of each other, the model gets the
// electrodes it needs, corona wires thin, above onset and in the
// line-charge field, a grid file that reads, corona sectors in order with
// their current, materials that say how they conduct.
#pragma once
#include <filesystem>
#include <functional>
#include <optional>
#include <vector>

#include "scene/tree.hpp"
#include "spec/simulation.hpp"

namespace ces::scene {

class Diagnostics;

// A wire thicker than this never ionises at separator voltages (Peek's onset
// field grows as the radius shrinks, but the surface field of a thick
// electrode falls faster); the corona laws of docs/physics.md §4 are for
// wires of a few tenths of a millimetre. Metres.
inline constexpr double kMaxCoronaWireRadius = 1e-3;

struct ElectrostaticsInput {
  const Node& section;    // electrostatics
  const Node* materials;  // the materials section, or null
  const Model& model;     // bodies and materials compiled
  std::vector<int> fed;   // materials fed as particles
  std::filesystem::path scene_dir;
  // A body's index by the name `ref` holds; unknown names are reported.
  std::function<std::optional<int>(const Node& ref)> body;
};

// Takes the corona wire's keys (mobility, air_density) off every electrode
// that is not a corona wire where they are the schema's defaults, after the
// defaults are filled: nothing reads them there, and the resolved scene
// that gives them would be refused on loading again (ces-sim resume) as a
// static electrode with a corona's keys.
void drop_corona_defaults(Node& root);

// Sets sim.electrostatics and sim.electrodes, or reports every problem.
void compile_electrostatics(const ElectrostaticsInput& in, Simulation& sim, Diagnostics& diags);

}  // namespace ces::scene
