// From files to one tree: includes, --set overrides, relative paths.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "scene/tree.hpp"

namespace ces::scene {

class Diagnostics;

// Reads `path` (or parses `text` as if read from `path`) and merges in the
// fragments its top-level `include:` names, recursively, relative to the
// including file. Precedence, lowest first: earlier includes, later
// includes, the including file. Maps merge key by key, lists concatenate
// (included items first), any other value is replaced. Cycles are errors.
// Every include must resolve, symlinks followed, inside the folder of
// `path` or one of `include_paths`; chains and file counts are bounded
// (limits.hpp).
std::optional<Node> load_tree(const std::string& path,
                              const std::vector<std::string>& include_paths, Budget& budget,
                              Diagnostics& diags);
std::optional<Node> load_tree_text(const std::string& text, const std::string& path,
                                   const std::vector<std::string>& include_paths, Budget& budget,
                                   Diagnostics& diags);

// Applies one "--set key.path=value" (the ordinal-th, 1-based; it names the
// override in diagnostics). The path walks maps by key, creating missing
// ones, and lists by index ("bodies.0" or "bodies[0]") or by an item's name
// ("bodies.drum"). The value is parsed as YAML ("0.5 mm", "[0, 1, 0]",
// "{speed: 60 rpm}").
void apply_override(Node& root, const std::string& key_path, const std::string& value, int ordinal,
                    Budget& budget, Diagnostics& diags);

// Applies one "--unset key.path" (the ordinal-th, 1-based): removes the
// key, or the list item, that the path names (as apply_override walks it),
// so that the schema's default, or nothing, takes its place. A path the
// tree does not hold is an error: a misspelt key would otherwise remove
// nothing in silence.
void apply_removal(Node& root, const std::string& key_path, int ordinal, Diagnostics& diags);

// Applies the tree's top-level `set:` (merged from the scene and its
// includes) and removes it: each key path, as --set takes it, gets its
// value, in the order written. Before the command line's --set, which wins.
void apply_scene_set(Node& root, Diagnostics& diags);

// Rewrites the strings the schema marks as paths ("x-path") from relative
// to the file that wrote them to relative to the scene's folder, so the
// resolved scene stands alone next to the scene file. --set paths are
// relative to the working directory, like any command-line path.
void rebase_paths(Node& root, const std::string& scene_path);

// Why a data file a scene names (mesh, field grid, sphere list) is not
// read: "N bytes, expected at most M" past `max_bytes`, else "".
std::string too_large(const std::filesystem::path& file, std::uintmax_t max_bytes);

}  // namespace ces::scene
