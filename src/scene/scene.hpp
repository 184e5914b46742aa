// Scene files in: YAML or JSON -> validated, resolved, compiled Simulation.
//
// Pipeline (every stage adds to one list of diagnostics; SceneError carries
// them all): read the file and its includes -> apply --unset, --set, --seed ->
// fill schema defaults -> resolved text (Simulation::resolved_yaml) ->
// convert units -> validate against schema/scene.schema.json -> compile
// (references, physical sanity, meshes). Compilation runs only on a valid
// tree, so reference and sanity errors appear once the structure is right.
//
// Precedence, lowest first: included fragments in list order, the including
// file (its `set:` last), --unset removals, --set overrides in order,
// --seed. Maps merge key by key, lists concatenate (included items first),
// other values are replaced.
#pragma once
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "spec/simulation.hpp"

namespace ces::scene {

// One problem found in a scene, pointing at where the user must look.
struct Diagnostic {
  std::string file;
  int line = 0;      // 1-based; 0 when unknown
  int column = 0;    // 1-based; 0 when unknown
  std::string path;  // key path, e.g. "materials.copper.density", "bodies[0].name"
  std::string message;
  bool warning = false;  // the scene loads all the same
  // "file:line:col: key.path: message" ("file:line:col: warning: ..."), on
  // one line. --set overrides are reported as file "--set", line = the
  // override's position on the command line.
  std::string str() const;
};

// Thrown with every problem found, not just the first.
class SceneError : public std::runtime_error {
 public:
  explicit SceneError(std::vector<Diagnostic> d);
  const std::vector<Diagnostic>& diagnostics() const { return diagnostics_; }

 private:
  std::vector<Diagnostic> diagnostics_;
};

struct LoadOptions {
  // "--set key.path=value" overrides, applied before validation, in order.
  std::vector<std::pair<std::string, std::string>> overrides;
  // "--unset key.path" removals, applied before the overrides, in order.
  std::vector<std::string> removals;
  std::optional<std::uint64_t> seed;  // --seed, wins over the scene's
  std::optional<int> threads;         // --threads
  // --include-path: folders includes may come from besides the scene's own.
  std::vector<std::string> include_paths;
  // Where warnings go (a scene that loads but likely does not do what was
  // meant, as feeds without gravity); nullptr: they are dropped.
  std::vector<Diagnostic>* warnings = nullptr;
};

// Parses, resolves includes and overrides, validates against the schema and
// the physical-sanity rules, and compiles. Throws SceneError. Files ending
// in .json are JSON (strict), anything else YAML.
Simulation load(const std::string& path, const LoadOptions& options = {});

// The same for a scene held in memory: `path` names it in diagnostics,
// picks YAML or JSON by its extension, and anchors relative paths (include,
// mesh files). Loading sim.resolved_yaml as "<scene folder>/any.yaml"
// rebuilds `sim`.
Simulation load_text(const std::string& text, const std::string& path,
                     const LoadOptions& options = {});

// The JSON Schema every scene is validated against (schema/scene.schema.json).
const std::string& schema_text();

}  // namespace ces::scene
