#include "scene/schema_doc.hpp"

#include <sstream>
#include <string_view>
#include <vector>

#include "scene/schema.hpp"
#include "scene/units.hpp"

namespace ces::scene {
namespace {

using ojson = nlohmann::ordered_json;

// "#/definitions/length" -> "length".
std::string ref_name(const ojson& s) {
  const std::string ref = s.value("$ref", "");
  return ref.substr(ref.rfind('/') + 1);
}

const ojson& definition(const std::string& name) { return schema()["definitions"][name]; }

// The $ref of a subschema, directly or as the first entry of its allOf.
std::string referenced(const ojson& s) {
  if (s.contains("$ref")) return ref_name(s);
  if (s.contains("allOf") && s["allOf"].is_array() && !s["allOf"].empty())
    return ref_name(s["allOf"][0]);
  return "";
}

// "type": "object" (a type can also be a list of types).
bool has_type(const ojson& s, const char* type) {
  return s.contains("type") && s["type"].is_string() && s["type"] == type;
}

// "1000 m", or "100000 rad/s; 1000 m/s" for a key of two kinds.
std::string largest(const ojson& s) {
  const ojson& unit = s["x-unit"];
  std::string text;
  for (const ojson& name : unit.is_array() ? unit : ojson::array({unit})) {
    const units::Kind* k = units::find_kind(name.get<std::string>());
    std::ostringstream bound;
    bound << k->largest;
    text += (text.empty() ? "" : "; ") + bound.str() + " " + std::string(k->si);
  }
  return text;
}

bool is_quantity(const std::string& name) {
  return !name.empty() && definition(name).contains("x-unit");
}

std::string code(const std::string& text) { return "`" + text + "`"; }

// [text](#anchor), appended piece by piece: GCC 12 warns falsely (-Wrestrict)
// on a literal + string + literal chain.
std::string link(const std::string& text, const std::string& anchor) {
  std::string out = "[";
  out += text;
  out += "](#";
  out += anchor;
  out += ")";
  return out;
}

std::string type_of(const ojson& s);

std::string type_of_items(const ojson& s) {
  if (!s.contains("items")) return "list";
  const ojson& items = s["items"];
  if (items.is_array()) return "list of " + std::to_string(items.size()) + " numbers";
  std::string count;
  if (s.contains("minItems") && s.value("minItems", 0) == s.value("maxItems", -1))
    count = std::to_string(s["minItems"].get<int>()) + " ";
  return "list of " + count + type_of(items);
}

std::string type_of(const ojson& s) {
  if (s.contains("enum")) {
    std::string out = "one of";
    for (const ojson& v : s["enum"]) {
      out += " ";
      out += code(v.get<std::string>());
    }
    return out;
  }
  const std::string ref = referenced(s);
  if (is_quantity(ref)) return link(ref, "quantities");
  if (!ref.empty()) {
    const ojson& d = definition(ref);
    if (has_type(d, "object")) return link(ref, ref);
    return type_of(d);
  }
  if (s.contains("const")) return code(s["const"].dump());
  if (!s.contains("type")) return "";
  if (s["type"].is_string())
    return has_type(s, "array") ? type_of_items(s) : s["type"].get<std::string>();
  std::string out;  // a list of types: "string or list of string"
  for (const ojson& t : s["type"]) {
    if (!out.empty()) out += " or ";
    out += t == "array" ? type_of_items(s) : t.get<std::string>();
  }
  return out;
}

std::string range_of(const ojson& s) {
  std::string out;
  auto bound = [&](const char* key, const char* sign) {
    if (!s.contains(key)) return;
    if (!out.empty()) out += ", ";
    out += std::string(sign) + " " + s[key].dump();
  };
  bound("minimum", "≥");
  bound("exclusiveMinimum", ">");
  bound("maximum", "≤");
  bound("exclusiveMaximum", "<");
  return out;
}

// Markdown table cells cannot hold a bar or a line break.
std::string cell(std::string text) {
  for (char& c : text)
    if (c == '\n') c = ' ';
  std::string out;
  for (const char c : text) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}

struct Row {
  std::string key, type, required, fallback, range, description;
};

// The rows of an object's properties, nested objects flattened to dotted
// keys (a property that is itself a documented definition links to it).
void rows_of(const ojson& object, const std::string& prefix, std::vector<Row>& rows) {
  if (!object.contains("properties")) return;
  const ojson required = object.value("required", ojson::array());
  for (const auto& [name, s] : object["properties"].items()) {
    const std::string key = prefix + name;
    bool needed = false;
    for (const ojson& r : required) needed = needed || r == name;
    const bool inline_object = has_type(s, "object") && s.contains("properties");
    rows.push_back({code(key), inline_object ? "section" : type_of(s), needed ? "yes" : "",
                    s.contains("default") ? code(s["default"].dump()) : "", range_of(s),
                    s.value("description", "")});
    if (inline_object) rows_of(s, key + ".", rows);
  }
}

void table(std::string& out, const ojson& object) {
  std::vector<Row> rows;
  rows_of(object, "", rows);
  out += "| key | type | required | default | range | description |\n";
  out += "|---|---|---|---|---|---|\n";
  for (const Row& r : rows)
    out += "| " + r.key + " | " + cell(r.type) + " | " + r.required + " | " + cell(r.fallback) +
           " | " + cell(r.range) + " | " + cell(r.description) + " |\n";
}

void section(std::string& out, const std::string& title, const ojson& s) {
  out += "\n### " + title + "\n\n";
  if (s.contains("description")) out += cell(s["description"].get<std::string>()) + "\n\n";
  table(out, s);
}

}  // namespace

std::string schema_markdown() {
  const ojson& root = schema();
  std::string out =
      "# Scene format\n\n"
      "Generated from `schema/scene.schema.json` by `ces-sim schema --markdown`; do not edit.\n\n" +
      root.value("description", "") +
      "\n\nA quantity is an SI number or a number with a unit (`0.8 mm`, `35 kV`); "
      "a key left out takes its default.\n\n## Top-level keys\n\n";
  table(out, root);
  out += "\n## Definitions\n";
  for (const auto& [name, s] : root["definitions"].items())
    if (has_type(s, "object") && s.contains("properties")) section(out, name, s);
  out +=
      "\n## Quantities\n\nA value past its kind's largest magnitude is refused: no separator "
      "has it, and no step resolves it.\n\n| quantity | meaning | largest magnitude |\n"
      "|---|---|---|\n";
  for (const auto& [name, s] : root["definitions"].items())
    if (s.contains("x-unit"))
      out += "| " + name + " | " + cell(s.value("description", "")) + " | " + largest(s) + " |\n";
  return out;
}

}  // namespace ces::scene
