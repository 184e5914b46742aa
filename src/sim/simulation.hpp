// A compiled scene: the engine's Model plus what surrounds the engine in a
// run (feeds, collectors, the domain, outputs). Built by scene/compile, run by
// sim/run. Plain data; no YAML here.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dynamics/model.hpp"
#include "feed/size_distribution.hpp"
#include "fields/stages.hpp"
#include "geometry/shapes.hpp"

namespace ces {

// One component of a feed's mix.
struct FeedComponent {
  int material = 0;
  double mass_fraction = 1.0;      // fractions of a feed sum to 1
  feed::SizeDistribution size = feed::SizeDistribution::constant(1e-3);
  int shape = 0;                   // Model::shapes index; size = scale * shape_size
  // The shape's characteristic size at scale 1 (m): for spheres, flakes and
  // rods the diameter of the sphere of equal volume, for scene clusters
  // their `size`. Size distributions draw this size.
  double shape_size = 1.0;
};

struct Feed {
  std::string name;
  // Spawn region: a box, or an outlet rectangle (a box of zero thickness).
  geo::Aabb region;
  double start = 0.0;              // s
  double duration = 1e300;         // s
  // Exactly one of these rates is > 0.
  double mass_rate = 0.0;          // kg/s
  double count_rate = 0.0;         // 1/s
  Vec3 velocity = Vec3::Zero();    // mean initial velocity
  double velocity_spread = 0.0;    // m/s, uniform per component in [-s, s]
  bool random_orientation = true;
  int max_attempts = 20;           // spawn retries before a particle is deferred
  std::vector<FeedComponent> mix;
};

// A collector plane: a particle is collected when its centre crosses the
// plane against the normal (from the side the normal points to).
struct Product {
  std::string name;
  double from = 0.0, to = 0.0;     // along the bin axis (m)
};
struct Collector {
  std::string name;
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitY();
  Vec3 axis = Vec3::UnitX();       // bins and products are measured along it
  double from = 0.0, to = 1.0;
  int bins = 10;
  std::vector<Product> products;
};

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
  std::shared_ptr<Model> model;
  std::vector<Feed> feeds;
  std::vector<Collector> collectors;
  std::optional<geo::Aabb> domain; // leaving it: lost ("left domain")
  // Separator physics; absent, the run builds no stage for it (DESIGN.md §1).
  std::optional<fields::DragSpec> drag;
  std::optional<fields::ElectrostaticsSpec> electrostatics;
  std::vector<NamedElectrode> electrodes;  // empty without electrostatics
  OutputSettings output;
  std::vector<std::string> active_components;
};

}  // namespace ces
