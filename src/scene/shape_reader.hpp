// The particle shapes and size laws of a scene's feeds, compiled on first
// use into the Model's shapes: a shapes entry (listed spheres or a sphere
// file), the built-in sphere, flake and rod, flakes and rods whose
// dimensions are drawn (a ladder of contact shapes by aspect), and the
// size laws (constant, uniform, normal, lognormal, sieve table).
#pragma once
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "feed/feed.hpp"
#include "feed/shapes.hpp"
#include "model/model.hpp"
#include "scene/diagnostics.hpp"
#include "scene/tree.hpp"

namespace ces::scene {

class ShapeReader {
 public:
  // Shapes go to model.shapes and their names to shape_names, in step.
  ShapeReader(const Node& root, std::filesystem::path scene_dir, Diagnostics& diags, Model& model,
              std::vector<std::string>& shape_names);

  // A mix component's shape (Model::shapes index); nullopt: reported.
  std::optional<int> particle_shape(const Node& component);
  // A flake or rod whose dimensions are drawn: its laws and the ladder of
  // contact shapes the drawn aspects reach; nullopt: reported.
  std::optional<DrawnShape> drawn_shape(const Node& c);
  std::optional<feed::SizeDistribution> size_distribution(const Node& size, feed::Basis basis);
  // The size of shape `index` at scale 1 (m), the one size laws draw.
  double size(int index) const { return sizes_[std::size_t(index)]; }

 private:
  // The thinnest contact geometry of a drawn flake (37 spheres) or rod (19
  // spheres), and the ratio of neighbouring aspects on the ladder.
  static constexpr double kFlakeMinAspect = 0.15;
  static constexpr double kRodMinAspect = 0.1;
  static constexpr double kLadderRatio = 1.1;

  std::vector<DrawnShape::Rung> ladder(const std::string& name, double lo, double hi);
  DrawnShape::Rung rung(const std::string& name, double aspect);
  static std::string rung_key(const std::string& name, double aspect);
  static bool is_builtin_shape(const std::string& name);
  void report_unknown_shape(const Node& ref, const Node* shapes);
  std::optional<double> shape_aspect(const Node& component, const std::string& name,
                                     bool scene_entry);
  static feed::SphereList builtin_spheres(const std::string& name, double aspect);
  std::optional<feed::SphereList> cluster_spheres(const Node& entry);
  std::optional<int> add_shape(const ParticleShape& shape, const Node* entry,
                               const std::string& name);
  std::optional<feed::SizeDistribution> sieve(const Node& rows, feed::Basis basis);
  std::nullopt_t sieve_error(const Node& row, const std::string& what);

  const Node& root_;
  std::filesystem::path scene_dir_;
  Diagnostics& diags_;
  Model* model_;
  std::vector<std::string>& shape_names_;
  // "shapes.<entry>" or "<built-in>@<aspect>" -> Model::shapes index; nullopt: reported
  std::map<std::string, std::optional<int>> shape_index_;
  std::vector<double> sizes_;  // per Model::shapes entry
};

}  // namespace ces::scene
