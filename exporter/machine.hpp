// Parts given roles: each matched to its annotation rule, its mesh cleaned,
// and the primitive it stands for recovered (an exact or fitted cylinder, a
// box) where the role wants one.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "annotations.hpp"
#include "fit.hpp"
#include "mesh.hpp"
#include "parts.hpp"

namespace ces::exporter {

// What one part becomes in the scene.
enum class Output { Cylinder, Box, Mesh, Electrode, Feed, Collector };

struct Placed {
  const Part* part = nullptr;
  const Rule* rule = nullptr;
  std::string name;  // unique among the scene's bodies, feeds or collectors
  Output output = Output::Mesh;
  Mesh mesh;  // cleaned, metres
  MeshQuality quality;
  std::optional<Cylinder> cylinder;  // Output::Cylinder and Electrode
  std::string cylinder_source;       // "step" (exact faces) or "fit"
  std::optional<CylinderFit> fit;    // tried on meshes, reported even when not used
  std::optional<BoxFit> box_fit;     // tried on splitters, reported even when not used
  std::optional<Box> box;            // Output::Box
  std::string mesh_file;             // Output::Mesh: "meshes/<name>.stl"
};

// "drum 'drum_1'": the role and the CAD name, for messages.
std::string label(const Placed& p);

struct Machine {
  std::vector<Part> cad;  // the CAD parts moved into the scene frame; Placed::part points here
  Mat3 rotation = Mat3::Identity();  // CAD directions to scene directions (frame:)
  std::vector<Placed> parts;
  std::vector<std::string> unassigned;  // no rule matched: ignored, with a warning
  std::vector<std::string> ignored;     // role: ignore
};

// How the CAD's length unit was chosen, for messages about sizes.
struct UnitChoice {
  double scale = 1.0;  // metres per CAD unit
  std::string how;     // "mm (the default for STL/OBJ)"
};

// Throws scene::SceneError when a rule matches no part or misuses `name`,
// InputError when a part cannot be what its role needs, the units look
// wrong or the frame cannot be built. Adds what it notices to `warnings`,
// also when it throws.
Machine assemble(std::vector<Part> parts, const Annotations& annotations, const UnitChoice& units,
                 std::vector<std::string>& warnings);

}  // namespace ces::exporter
