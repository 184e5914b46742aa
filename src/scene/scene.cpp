#include "scene/scene.hpp"

#include <cstdio>
#include <filesystem>

#include "common/hash.hpp"
#include "scene/compile.hpp"
#include "scene/diagnostics.hpp"
#include "scene/electrostatics.hpp"
#include "scene/resolve.hpp"
#include "scene/schema.hpp"

namespace ces::scene {
namespace {

std::string fnv1a_hex(const std::string& text) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(fnv1a(text)));
  return hex;
}

void set_key(Node& root, const std::string& key, nlohmann::ordered_json value, const Mark& mark) {
  Node node = from_json(value, mark);
  if (Node* existing = root.find(key))
    *existing = std::move(node);
  else
    root.entries.push_back({key, mark, std::move(node)});
}

// Everything after reading the files: overrides, defaults, the resolved
// text, units, validation, compilation. Throws SceneError.
Simulation finish(std::optional<Node> tree, const std::string& path, const LoadOptions& options,
                  Budget& budget, Diagnostics& diags) {
  if (!tree) diags.raise();
  Node& root = *tree;
  apply_scene_set(root, diags);
  for (std::size_t i = 0; i < options.removals.size(); ++i)
    apply_removal(root, options.removals[i], int(i + 1), diags);
  for (std::size_t i = 0; i < options.overrides.size(); ++i)
    apply_override(root, options.overrides[i].first, options.overrides[i].second, int(i + 1),
                   budget, diags);
  if (options.seed) set_key(root, "seed", *options.seed, {"--seed", 0, 0});
  if (!root.find("name"))
    set_key(root, "name", std::filesystem::path(path).stem().string(), root.mark);
  apply_defaults(root);
  drop_corona_defaults(root);
  rebase_paths(root, path);
  assign_paths(root);
  const std::string resolved = to_yaml(root);  // before units: the user's own words
  convert_units(root, diags);
  validate(root, diags);
  if (!diags.empty()) diags.raise();  // the compiler relies on a valid tree
  Simulation sim = compile(root, path, diags);
  if (!diags.empty()) diags.raise();
  if (options.warnings)
    options.warnings->insert(options.warnings->end(), diags.warnings().begin(),
                             diags.warnings().end());
  sim.resolved_yaml = resolved;
  sim.scene_hash = fnv1a_hex(resolved);
  if (options.threads) sim.model->threads = *options.threads;
  return sim;
}

}  // namespace

Simulation load(const std::string& path, const LoadOptions& options) {
  Diagnostics diags;
  Budget budget;
  return finish(load_tree(path, options.include_paths, budget, diags), path, options, budget,
                diags);
}

Simulation load_text(const std::string& text, const std::string& path, const LoadOptions& options) {
  Diagnostics diags;
  Budget budget;
  return finish(load_tree_text(text, path, options.include_paths, budget, diags), path, options,
                budget, diags);
}

}  // namespace ces::scene
