// Everything the schema decides: structure and ranges (through valijson),
// defaults ("default"), the kind of quantity each key takes ("x-unit") and
// which strings are file paths ("x-path").
#pragma once
#include <cstddef>
#include <functional>
#include <nlohmann/json.hpp>
#include <string_view>

#include "scene/tree.hpp"

namespace ces::scene {

class Diagnostics;

// schema/scene.schema.json, parsed once (in file order, so defaults are
// added in the order the schema lists them).
const nlohmann::ordered_json& schema();

// Calls visit(node, subschema) on every node of the tree, parents before
// children, with nullptr where the schema does not describe the node. A
// visitor may add map entries; the walk then enters them.
void walk_schema(Node& root,
                 const std::function<void(Node&, const nlohmann::ordered_json*)>& visit);

// The value of `name` in a subschema, following $ref and allOf; nullptr if absent.
const nlohmann::ordered_json* keyword(const nlohmann::ordered_json& subschema,
                                      std::string_view name);

// Adds every missing key that has a "default", recursively (a default {}
// section is then filled in turn).
void apply_defaults(Node& root);

// Turns unit strings into SI numbers, checking each against the kind(s) its
// key takes; records the kind in Node::dimension.
void convert_units(Node& root, Diagnostics& diags);

// The largest value (counted in values, itself included) validate() checks
// whole; a larger one is checked a piece at a time, holding memory to what
// one piece's errors take.
inline constexpr std::size_t kPieceValues = 4096;

// Validates against the schema; one diagnostic per problem, at the line of
// the offending key or value, in words (not valijson's). `piece_values` is
// for tests, which check that pieces of any size find the same problems.
void validate(const Node& root, Diagnostics& diags, std::size_t piece_values = kPieceValues);

}  // namespace ces::scene
