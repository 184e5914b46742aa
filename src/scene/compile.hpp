// Validated tree -> Simulation: resolves names, loads meshes, builds particle
// templates and size laws, checks what the schema cannot (references,
// ordering, fit), and builds only what the scene uses.
#pragma once
#include <optional>
#include <string>

#include "scene/tree.hpp"
#include "spec/simulation.hpp"

namespace ces::scene {

class Diagnostics;

// `root` has passed validation with units converted to SI; mesh paths are
// relative to the folder of `scene_path`.
Simulation compile(const Node& root, const std::string& scene_path, Diagnostics& diags);

}  // namespace ces::scene
