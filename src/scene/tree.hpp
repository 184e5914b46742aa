// The scene document as a tree that remembers where every value was written.
// YAML and JSON files both parse to it (JSON through the same YAML parser,
// after a strict JSON syntax check), includes and --set edit it, the schema
// pass fills defaults and converts units in it, and the compiler reads it.
#pragma once
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scene/limits.hpp"

namespace ces::scene {

class Diagnostics;

struct Mark {
  std::string file;
  int line = 0;    // 1-based; 0 when unknown
  int column = 0;  // 1-based; 0 when unknown
};

struct Entry;

struct Node {
  enum class Kind { Null, Scalar, Sequence, Map };

  Kind kind = Kind::Null;
  nlohmann::json scalar;       // Scalar: string, integer, float or boolean
  std::string text;            // Scalar: as written, for messages
  std::vector<Node> items;     // Sequence
  std::vector<Entry> entries;  // Map, in document order, keys unique
  Mark mark;                   // collections: the mark of the key that holds them
  std::string path;            // "bodies[0].geometry", see assign_paths
  std::string dimension;       // a unit string's kind after conversion ("speed")
  bool reported = false;       // a diagnostic names this node already
  bool defaulted = false;      // filled in from the schema's default, not written

  bool is_map() const { return kind == Kind::Map; }
  bool is_sequence() const { return kind == Kind::Sequence; }
  bool is_string() const { return kind == Kind::Scalar && scalar.is_string(); }
  bool is_number() const { return kind == Kind::Scalar && scalar.is_number(); }

  const Node* find(std::string_view key) const;
  Node* find(std::string_view key);
  const Entry* entry(std::string_view key) const;
  // The child at `key`, which validation guarantees; throws std::logic_error
  // if it is missing (a schema/compiler mismatch, not a user error).
  const Node& at(std::string_view key) const;

  double number() const { return scalar.get<double>(); }
  const std::string& string() const { return scalar.get_ref<const std::string&>(); }
  bool boolean() const { return scalar.get<bool>(); }
};

struct Entry {
  std::string key;
  Mark key_mark;
  Node value;
};

// What one load may still build, shared by its files and --set values
// (limits.hpp): alias expansion and includes cannot make it unbounded.
struct Budget {
  std::size_t values = limits::kValues;
  std::size_t text_bytes = limits::kTextBytes;
  int files = limits::kIncludeFiles;
};

// Parses a YAML or (json = true) JSON document. Syntax errors, invalid
// UTF-8, numbers out of range, duplicate keys and broken bounds go to
// `diags`; returns nullopt when nothing usable was read.
std::optional<Node> parse(const std::string& text, const std::string& file, bool json,
                          Budget& budget, Diagnostics& diags);

// A tree from a JSON value (schema defaults); every node gets `mark`.
Node from_json(const nlohmann::ordered_json& value, const Mark& mark);
nlohmann::json to_json(const Node& node);

// Block YAML, keys in document order, strings double-quoted, numbers in
// shortest round-trip form: reading it back gives the same tree.
std::string to_yaml(const Node& node);

// Sets Node::path on every node below `root` ("" for the root itself).
void assign_paths(Node& node, const std::string& path = "");

// "'20 g/s'", "a mapping", "a list of 2 items": what a value is, for messages.
std::string describe(const Node& node);

}  // namespace ces::scene
