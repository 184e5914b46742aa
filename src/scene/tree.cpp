#include "scene/tree.hpp"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <map>
#include <regex>
#include <stdexcept>

#include "scene/diagnostics.hpp"

namespace ces::scene {
namespace {

// Number from a plain scalar known to match the YAML 1.2 core schema.
nlohmann::json parse_number(const std::string& s, bool integer) {
  const char* first = s.data() + (s[0] == '+' ? 1 : 0);
  const char* last = s.data() + s.size();
  if (integer) {
    std::int64_t i = 0;
    if (std::from_chars(first, last, i).ec == std::errc()) return i;
    std::uint64_t u = 0;
    if (std::from_chars(first, last, u).ec == std::errc()) return u;
  }
  double d = 0.0;
  if (std::from_chars(first, last, d).ec == std::errc()) return d;
  return s;  // out of range: left as text, the schema reports its type
}

// Types of plain (unquoted) scalars by the YAML 1.2 core schema, which is
// also what JSON means: "1 ms" stays a string, "1e-3" is a number, "yes" is
// a string (not a YAML 1.1 boolean).
nlohmann::json resolve_plain(const std::string& s) {
  static const std::regex kInt("[-+]?[0-9]+");
  static const std::regex kFloat(R"([-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?)");
  if (s == "true" || s == "True" || s == "TRUE") return true;
  if (s == "false" || s == "False" || s == "FALSE") return false;
  if (std::regex_match(s, kInt)) return parse_number(s, true);
  if (std::regex_match(s, kFloat)) return parse_number(s, false);
  return s;
}

class Converter {
 public:
  Converter(const std::string& file, Diagnostics& diags) : file_(file), diags_(diags) {}

  Mark mark(const YAML::Mark& m) const { return {file_, m.line + 1, m.column + 1}; }

  // `holder` is where the user sees the value start: the key for values in
  // a mapping (yaml-cpp marks an empty value at the next token). `path`
  // names the value in duplicate-key messages.
  Node convert(const YAML::Node& y, const Mark& holder, const std::string& path = "") {
    Node n;
    n.mark = holder;
    if (y.IsScalar()) {
      n.kind = Node::Kind::Scalar;
      n.mark = mark(y.Mark());
      n.text = y.Scalar();
      const bool quoted = y.Tag() == "!" || y.Tag() == "tag:yaml.org,2002:str";
      n.scalar = quoted ? nlohmann::json(n.text) : resolve_plain(n.text);
    } else if (y.IsSequence()) {
      n.kind = Node::Kind::Sequence;
      for (const YAML::Node& item : y)
        n.items.push_back(
            convert(item, mark(item.Mark()), path + "[" + std::to_string(n.items.size()) + "]"));
    } else if (y.IsMap()) {
      n.kind = Node::Kind::Map;
      convert_map(y, n, path);
    }
    return n;
  }

 private:
  // yaml-cpp keeps every duplicate key; the first one wins, the others are
  // reported (they are almost always a forgotten edit).
  void convert_map(const YAML::Node& y, Node& n, const std::string& path) {
    std::map<std::string, Mark> seen;
    for (auto it = y.begin(); it != y.end(); ++it) {
      const Mark key_mark = mark(it->first.Mark());
      if (!it->first.IsScalar()) {
        diags_.error(key_mark, "", "keys must be plain names, not lists or mappings");
        continue;
      }
      const std::string key = it->first.Scalar();
      const std::string key_path = path.empty() ? key : path + "." + key;
      const auto [first, inserted] = seen.emplace(key, key_mark);
      if (!inserted) {
        diags_.error(key_mark, key_path,
                     "duplicate key '" + key + "', first given at line " +
                         std::to_string(first->second.line));
        continue;
      }
      n.entries.push_back({key, key_mark, convert(it->second, key_mark, key_path)});
    }
  }

  const std::string& file_;
  Diagnostics& diags_;
};

// nlohmann names the place as "at line L, column C: "; keep the rest.
void report_json_error(const nlohmann::json::exception& e, const std::string& file,
                       Diagnostics& diags) {
  static const std::regex kWhere(R"(line (\d+), column (\d+): (.*))");
  std::smatch m;
  const std::string what = e.what();
  if (std::regex_search(what, m, kWhere))
    diags.error({file, std::stoi(m[1]), std::stoi(m[2])}, "", "invalid JSON: " + m[3].str());
  else
    diags.error({file, 0, 0}, "", "invalid JSON: " + what);
}

void emit(YAML::Emitter& out, const Node& n) {
  switch (n.kind) {
    case Node::Kind::Null:
      out << YAML::Null;
      break;
    case Node::Kind::Scalar:
      if (n.scalar.is_string())
        out << YAML::DoubleQuoted << n.string();
      else
        out << n.scalar.dump();
      break;
    case Node::Kind::Sequence: {
      // Vectors and pairs ([x, y, z]) read best on one line.
      bool flat = true;
      for (const Node& item : n.items)
        flat = flat && item.kind != Node::Kind::Map && item.items.empty();
      out << (flat ? YAML::Flow : YAML::Block) << YAML::BeginSeq;
      for (const Node& item : n.items) emit(out, item);
      out << YAML::EndSeq;
      break;
    }
    case Node::Kind::Map:
      out << (n.entries.empty() ? YAML::Flow : YAML::Block) << YAML::BeginMap;
      for (const Entry& e : n.entries) {
        out << YAML::Key << e.key << YAML::Value;
        emit(out, e.value);
      }
      out << YAML::EndMap;
      break;
  }
}

}  // namespace

const Node* Node::find(std::string_view key) const {
  const Entry* e = entry(key);
  return e ? &e->value : nullptr;
}

Node* Node::find(std::string_view key) { return const_cast<Node*>(std::as_const(*this).find(key)); }

const Entry* Node::entry(std::string_view key) const {
  for (const Entry& e : entries)
    if (e.key == key) return &e;
  return nullptr;
}

const Node& Node::at(std::string_view key) const {
  if (const Node* n = find(key)) return *n;
  throw std::logic_error("scene compiler: '" + std::string(key) + "' missing under '" + path +
                         "' after validation");
}

std::optional<Node> parse(const std::string& text, const std::string& file, bool json,
                          Diagnostics& diags) {
  if (json) {
    try {
      [[maybe_unused]] const nlohmann::json strict = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {  // syntax, or a number out of range
      report_json_error(e, file, diags);
      return std::nullopt;
    }
  }
  try {
    const YAML::Node root = YAML::Load(text);
    return Converter(file, diags).convert(root, {file, 1, 1});
  } catch (const YAML::Exception& e) {
    diags.error({file, e.mark.line + 1, e.mark.column + 1}, "", "invalid YAML: " + e.msg);
    return std::nullopt;
  }
}

Node from_json(const nlohmann::ordered_json& value, const Mark& mark) {
  Node n;
  n.mark = mark;
  if (value.is_object()) {
    n.kind = Node::Kind::Map;
    for (const auto& [key, child] : value.items())
      n.entries.push_back({key, mark, from_json(child, mark)});
  } else if (value.is_array()) {
    n.kind = Node::Kind::Sequence;
    for (const auto& child : value) n.items.push_back(from_json(child, mark));
  } else if (!value.is_null()) {
    n.kind = Node::Kind::Scalar;
    n.scalar = value;
    n.text = value.is_string() ? value.get<std::string>() : value.dump();
  }
  return n;
}

nlohmann::json to_json(const Node& node) {
  switch (node.kind) {
    case Node::Kind::Scalar:
      return node.scalar;
    case Node::Kind::Sequence: {
      nlohmann::json a = nlohmann::json::array();
      for (const Node& item : node.items) a.push_back(to_json(item));
      return a;
    }
    case Node::Kind::Map: {
      nlohmann::json o = nlohmann::json::object();
      for (const Entry& e : node.entries) o[e.key] = to_json(e.value);
      return o;
    }
    case Node::Kind::Null:
      break;
  }
  return nullptr;
}

std::string to_yaml(const Node& node) {
  YAML::Emitter out;
  emit(out, node);
  return std::string(out.c_str()) + "\n";
}

void assign_paths(Node& node, const std::string& path) {
  node.path = path;
  for (std::size_t i = 0; i < node.items.size(); ++i)
    assign_paths(node.items[i], path + "[" + std::to_string(i) + "]");
  for (Entry& e : node.entries) assign_paths(e.value, path.empty() ? e.key : path + "." + e.key);
}

std::string describe(const Node& node) {
  switch (node.kind) {
    case Node::Kind::Null:
      return "an empty value";
    case Node::Kind::Map:
      return "a mapping";
    case Node::Kind::Sequence:
      return "a list of " + std::to_string(node.items.size()) +
             (node.items.size() == 1 ? " item" : " items");
    case Node::Kind::Scalar:
      break;
  }
  return node.scalar.is_string() ? "'" + node.text + "'" : node.text;
}

}  // namespace ces::scene
