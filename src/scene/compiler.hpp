// The scene compiler: reads the resolved, validated tree into a Simulation,
// section by section, with a diagnostic for each problem. Private to the
// scene layer: its definitions are in compile.cpp (settings, materials,
// bodies, joints, motors, domain), compile_feeds.cpp and
// compile_outputs.cpp (collectors, separator physics, outputs).
#pragma once
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "feed/shapes.hpp"
#include "fields/electrostatics.hpp"
#include "scene/compile_support.hpp"
#include "scene/diagnostics.hpp"
#include "scene/electrostatics.hpp"
#include "scene/limits.hpp"
#include "scene/resolve.hpp"
#include "scene/schema.hpp"
#include "scene/shape_reader.hpp"
#include "spec/simulation.hpp"

namespace ces::scene {

class Compiler {
 public:
  Compiler(const Node& root, const std::string& scene_path, Diagnostics& diags)
      : root_(root),
        scene_dir_(std::filesystem::path(scene_path).parent_path()),
        diags_(diags),
        model_(std::make_shared<Model>()),
        shapes_(root, scene_dir_, diags, *model_, sim_.shape_names) {
    sim_.scene_path = scene_path;
  }

  Simulation build() {
    read_settings();
    read_materials();
    read_bodies();
    read_joints();
    read_motors();
    read_domain();
    check_bodies_in_domain();
    read_feeds();
    check_feed_counts();
    check_gravity();
    read_collectors();
    check_bin_tallies();
    read_air();
    read_electrostatics();
    read_output();
    list_components();
    sim_.model = model_;
    return std::move(sim_);
  }

 private:
  // Settings
  void read_settings();
  void read_solver(const Node& s);
  std::optional<Vec3> direction(const Node& n);

  // Materials
  void read_materials();
  ElasticProperties elastic(const Node& m) const;
  std::vector<MaterialPair> read_pairs();
  std::optional<int> dense_material(const Node& ref, const std::string& who);

  // Bodies
  void read_bodies();
  std::optional<geo::Shape> geometry(const Node& g);
  std::optional<geo::Shape> cylinder(const Node& s);
  std::optional<geo::Shape> mesh(const Node& s);
  Pose pose(const Node& p);
  void read_motion(const Node& b, RigidBody& body, bool has_shape);
  void mass_properties(const Node& b, const Node& d, RigidBody& body);

  // Joints
  void read_joints();
  std::optional<int> body_ref(const Node& ref);
  bool is_dynamic(int body) const;
  void check_joint_bodies(const Node& j, int a, int b);

  // Motors
  void read_motors();
  std::optional<Motor> read_motor(const Node& m, bool revolute);
  bool check_kind(const Node& value, const std::string& kind, bool revolute);

  // Domain
  void read_domain();
  std::optional<geo::Aabb> aabb(const Node& box);
  static bool fixed_in_space(const RigidBody& b);
  void check_bodies_in_domain();
  bool inside_domain(const geo::Aabb& b) const;

  // Feeds
  void read_feeds();
  std::optional<geo::Aabb> feed_region(const Node& region);
  std::optional<geo::Aabb> outlet(const Node& o);
  std::vector<double> read_mix(const Node& mix, Feed& feed);
  static double law_end(const feed::SizeDistribution& d, const Node& law, bool upper);
  double end_volume(const Node& c, const FeedComponent& component, bool upper) const;
  void check_masses(const Node& c, const FeedComponent& component, const std::string& feed);
  void check_fit(const Node& region, const geo::Aabb& box, const std::vector<double>& across);
  void check_free(const Node& region, const geo::Aabb& box);
  void check_feed_counts();
  double expected_particles(const Feed& f) const;
  double mean_volume(const FeedComponent& c) const;
  void check_gravity();

  // Collectors
  void read_collectors();
  void check_bin_tallies();
  bool check_bins(const Node& bins, const Collector& c);
  void read_products(const Node* products, Collector& c);
  void check_reachable(const Node& plane, const Node& bins, const Collector& c);
  void check_bins_in_domain(const Node& bins, const Collector& c);

  // Separator physics
  void read_air();
  void read_electrostatics();

  // Output
  void check_frames(const Node& every_node, double every);
  void read_output();
  // More samples than this would make a field.csv of hundreds of MB.
  static constexpr double kMaxFieldSamples = 4e6;
  void read_field_picture(const Node& f);
  void default_extent(FieldPicture& p) const;
  void list_components();

  const Node& root_;
  std::filesystem::path scene_dir_;
  Diagnostics& diags_;
  Simulation sim_;
  std::shared_ptr<Model> model_;
  NameTable materials_{"material"};
  NameTable bodies_{"body"};
  NameTable joints_{"joint"};
  std::vector<bool> has_density_;
  ShapeReader shapes_;
  std::vector<const Node*> feed_rates_;  // per Simulation::feeds entry
  std::vector<geo::SurfaceHit> hits_;

};

}  // namespace ces::scene
