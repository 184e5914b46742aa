// The scene tree: bodies, joints, motors, electrodes, feeds and collectors
// made from the placed parts, merged with the scene keys of the annotations
// (theirs win; lists join, generated items first). Generated values carry
// the mark of the annotation rule that made them, copied values their own,
// so problems found later point into the annotations.
#pragma once
#include <filesystem>
#include <set>
#include <string>

#include "annotations.hpp"
#include "machine.hpp"
#include "scene/tree.hpp"

namespace ces::exporter {

struct SceneSetup {
  std::string name;                     // default scene name
  std::filesystem::path scene_path;     // where scene.yaml will be
  std::set<std::string> included_keys;  // top-level keys the includes define
};

// Gravity, written along -y of the scene when the annotations give none.
inline constexpr const char* kGravity = "-9.81 m/s^2";

// The domain written when the annotations give none: everything the parts
// span, with a tenth of the machine's size around it.
Bounds default_domain(const Machine& machine);

// Throws InputError when annotations and geometry disagree (a rotation axis
// across the drum, an electrode not parallel to it, ...).
scene::Node build_scene(const Machine& machine, const Annotations& annotations,
                        const SceneSetup& setup, std::vector<std::string>& warnings);

}  // namespace ces::exporter
