// The compiled scene: everything a run needs, as plain data. Built by the
// scene compiler (scene/), run by sim/run, read by the outputs. The engine's
// Model and each layer's own spec (feeds, fields, collectors) are gathered
// here with the run's settings; nothing here knows YAML or files.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "collect/collector.hpp"
#include "feed/feed.hpp"
#include "fields/drag.hpp"
#include "fields/electrostatics.hpp"
#include "geometry/shapes.hpp"
#include "model/model.hpp"

namespace ces {

struct Trajectories {
  double every = 0.0;              // s; 0 = none
  bool vtk = true;
  bool csv = false;
};

// field.csv and field.svg: the field model sampled on a grid in the drum's
// cross-section (z = 0).
struct FieldPicture {
  double resolution = 0.002;       // grid spacing (m)
  Vec2 min = Vec2::Zero();         // corners of the pictured rectangle (m)
  Vec2 max = Vec2::Zero();
};

struct OutputSettings {
  std::string dir = "out";
  Trajectories trajectories;
  bool steps_csv = true;
  bool distribution_svg = true;
  std::optional<FieldPicture> field;  // needs Simulation::electrostatics
  double checkpoint_every = 0.0;      // s of simulated time; 0 = no checkpoints
};

// An electrode as the scene names it, for pictures and reports (the field
// model keeps its own copy).
struct NamedElectrode {
  std::string name;
  fields::Electrode electrode;
};

struct Simulation {
  std::string name;
  std::string scene_path;
  std::string scene_hash;          // of the resolved scene text
  std::string resolved_yaml;       // written to the output folder
  std::uint64_t seed = 0;
  double end_time = 1.0;
  // time.until: collected: the run ends once every feed has stopped and no
  // particle is left, and end_time is a cap that fails the run.
  bool until_collected = false;
  std::string end_origin;          // "file:line:col: time.end", for the cap's message
  std::shared_ptr<Model> model;
  std::vector<Feed> feeds;
  std::vector<Collector> collectors;
  std::optional<geo::Aabb> domain; // leaving it: lost ("left domain")
  // Separator physics; absent, the run builds no stage for it.
  std::optional<fields::DragSpec> drag;
  std::optional<fields::ElectrostaticsSpec> electrostatics;
  std::vector<NamedElectrode> electrodes;  // empty without electrostatics
  // Per Model::shapes entry, its name in the scene: sphere, flake, rod or a
  // `shapes` entry (a flake of another aspect is another shape, also "flake").
  std::vector<std::string> shape_names;
  OutputSettings output;
  std::vector<std::string> active_components;
};

// The diameter of each Model shape at scale 1 (m): taken from the feeds'
// components (shape_size; a drawn shape's rungs, their width or length),
// else twice the shape's bounding radius.
std::vector<double> shape_sizes(const Simulation& sim);

}  // namespace ces
