#include "scene/schema.hpp"

#include <cmath>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <valijson/adapters/nlohmann_json_adapter.hpp>
#include <valijson/schema.hpp>
#include <valijson/schema_parser.hpp>
#include <valijson/validator.hpp>
#include <variant>

#include "scene/diagnostics.hpp"
#include "scene/schema_text.hpp"  // generated from schema/scene.schema.json
#include "scene/text.hpp"
#include "scene/units.hpp"

namespace ces::scene {

using ojson = nlohmann::ordered_json;

const std::string& schema_text() {
  static const std::string text(kSceneSchemaText);
  return text;
}

const ojson& schema() {
  static const ojson parsed = ojson::parse(schema_text());
  return parsed;
}

namespace {

const ojson& dereference(const ojson& ref) {
  // Local references only: "#/definitions/length".
  return schema().at(ojson::json_pointer(ref.get<std::string>().substr(1)));
}

const ojson* property_schema(const ojson& s, const std::string& key) {
  if (const ojson* props = keyword(s, "properties"); props && props->contains(key))
    return &props->at(key);
  const ojson* extra = keyword(s, "additionalProperties");
  return extra && extra->is_object() ? extra : nullptr;
}

const ojson* item_schema(const ojson& s, std::size_t index) {
  const ojson* items = keyword(s, "items");
  if (!items || !items->is_array()) return items;
  return index < items->size() ? &(*items)[index] : nullptr;
}

std::vector<std::string> property_names(const ojson& s) {
  std::vector<std::string> names;
  if (const ojson* props = keyword(s, "properties"))
    for (const auto& [name, sub] : props->items()) names.push_back(name);
  return names;
}

void walk(Node& n, const ojson* s, const std::function<void(Node&, const ojson*)>& visit) {
  visit(n, s);
  for (std::size_t i = 0; i < n.items.size(); ++i)
    walk(n.items[i], s ? item_schema(*s, i) : nullptr, visit);
  for (std::size_t i = 0; i < n.entries.size(); ++i)
    walk(n.entries[i].value, s ? property_schema(*s, n.entries[i].key) : nullptr, visit);
}

// ------------------------------------------------------------ words for kinds

std::vector<const units::Kind*> unit_kinds(const ojson& s) {
  std::vector<const units::Kind*> kinds;
  if (const ojson* unit = keyword(s, "x-unit")) {
    for (const ojson& name : unit->is_array() ? *unit : ojson::array({*unit}))
      kinds.push_back(units::find_kind(name.get<std::string>()));
  }
  return kinds;
}

// "a length (m), e.g. "0.8 mm"" or "a mass rate (kg/s) or a count rate (1/s), e.g. ...".
std::string describe_kinds(const std::vector<const units::Kind*>& kinds) {
  std::vector<std::string> labels, examples;
  for (const units::Kind* k : kinds) {
    labels.push_back(std::string(k->label) + " (" + std::string(k->si) + ")");
    examples.push_back("\"" + std::string(k->example) + "\"");
  }
  return one_of(labels) + ", e.g. " + one_of(examples);
}

// Whole numbers in full ("1000000", not "1e+06"): bounds read as written.
std::string format_number(double x) {
  if (x == std::floor(x) && std::abs(x) < 1e15) return std::to_string(static_cast<long long>(x));
  std::ostringstream s;
  s << x;
  return s.str();
}

std::string enum_words(const ojson& values) {
  std::vector<std::string> names;
  for (const ojson& v : values) names.push_back(v.is_string() ? v.get<std::string>() : v.dump());
  return one_of(names);
}

// What a subschema accepts, in words.
std::string expected(const ojson& s) {
  if (const auto kinds = unit_kinds(s); !kinds.empty()) return describe_kinds(kinds);
  if (const ojson* values = keyword(s, "enum")) return "one of " + enum_words(*values);
  if (const ojson* value = keyword(s, "const")) return value->dump();
  const ojson* type = keyword(s, "type");
  const std::string t = type && type->is_string() ? type->get<std::string>() : "";
  if (t == "string") return "a string";
  if (t == "integer") return "an integer";
  if (t == "number") return "a number";
  if (t == "boolean") return "true or false";
  if (t == "array") {
    const ojson* n = keyword(s, "minItems");
    const ojson* m = keyword(s, "maxItems");
    if (n && m && *n == *m) return "a list of " + n->dump() + " values";
    return "a list";
  }
  if (t == "object") {
    const ojson* m = keyword(s, "maxProperties");
    if (m && *m == 1) return "a mapping with one of " + one_of(property_names(s));
    return "a mapping";
  }
  return "a value matching the schema";
}

// ------------------------------------------------------------ defaults, units

void add_defaults(Node& n, const ojson* s) {
  if (!n.is_map() || !s) return;
  const ojson* props = keyword(*s, "properties");
  if (!props) return;
  for (const auto& [key, sub] : props->items()) {
    const ojson* value = keyword(sub, "default");
    if (!value || n.find(key)) continue;
    Node filled = from_json(*value, n.mark);
    filled.defaulted = true;
    n.entries.push_back({key, n.mark, std::move(filled)});
  }
}

// A value past its kind's largest magnitude is refused at its line, before
// the bounds of its key: "'1e12 rpm' is 1.05e+11 rad/s, expected an angular
// speed of at most 1e+05 rad/s in magnitude".
void check_magnitude(Node& n, double si, const units::Kind& kind, Diagnostics& diags) {
  if (std::abs(si) <= kind.largest) return;
  std::ostringstream got, most;  // as docs/scene-format.md's table writes the bound
  got << si;
  most << kind.largest;
  const std::string value = n.is_string() ? "'" + excerpt(n.text) + "'" : describe(n);
  diags.error(n, value + " is " + got.str() + " " + std::string(kind.si) + ", expected " +
                     std::string(kind.label) + " of at most " + most.str() + " " +
                     std::string(kind.si) + " in magnitude");
}

void convert_quantity(Node& n, const ojson* s, Diagnostics& diags) {
  if (!s || n.kind != Node::Kind::Scalar || n.reported) return;
  const auto kinds = unit_kinds(*s);
  if (kinds.empty()) return;
  if (n.is_number()) {
    // Zero is zero in every unit; another bare number could mean V or kV,
    // rpm or rad/s, a mass rate or a count rate.
    const ojson* required = keyword(*s, "x-unit-required");
    if (required && required->get<bool>() && n.number() != 0.0)
      diags.error(n,
                  "a number without a unit is ambiguous here, expected " + describe_kinds(kinds));
    else if (kinds.size() == 1)
      check_magnitude(n, n.number(), *kinds[0], diags);
    return;
  }
  if (!n.is_string()) return;  // booleans: the schema reports the type
  const auto parsed = units::parse(n.string());
  if (const auto* error = std::get_if<std::string>(&parsed)) {
    diags.error(n, "'" + excerpt(n.text) + "': " + *error + ", expected " + describe_kinds(kinds));
    return;
  }
  const auto& q = std::get<units::Quantity>(parsed);
  for (const units::Kind* k : kinds) {
    if (k->dimension == q.dimension) {
      check_magnitude(n, q.value, *k, diags);
      n.scalar = q.value;
      n.dimension = k->name;
      return;
    }
  }
  diags.error(n, "'" + excerpt(n.text) + "' is " + units::describe(q.dimension) + ", expected " +
                     describe_kinds(kinds));
}

// ------------------------------------------------------------ validation

std::unique_ptr<valijson::Schema> compile(const ojson& s) {
  const nlohmann::json document = nlohmann::json::parse(s.dump());
  auto compiled = std::make_unique<valijson::Schema>();
  valijson::SchemaParser parser(valijson::SchemaParser::kDraft7);
  parser.populateSchema(valijson::adapters::NlohmannJsonAdapter(document), *compiled);
  return compiled;
}

const valijson::Schema& compiled_schema() {
  static const std::unique_ptr<valijson::Schema> compiled = compile(schema());
  return *compiled;
}

// The node a valijson context ("<root>", "[bodies]", "[0]", ...) names, with
// its subschema. `quiet` when it or a parent was reported already.
struct Located {
  const Node* node = nullptr;
  const ojson* schema = nullptr;
  bool quiet = false;
};

Located locate(const Node& root, const std::vector<std::string>& context) {
  Located at{&root, &scene::schema(), root.reported};
  for (std::size_t i = 1; i < context.size() && at.node; ++i) {
    const std::string key = context[i].substr(1, context[i].size() - 2);  // strip [ ]
    const Node* next = nullptr;
    if (at.node->is_map()) {
      next = at.node->find(key);
      at.schema = at.schema ? property_schema(*at.schema, key) : nullptr;
    } else if (at.node->is_sequence()) {
      const std::size_t index = std::stoul(key);
      next = index < at.node->items.size() ? &at.node->items[index] : nullptr;
      at.schema = at.schema ? item_schema(*at.schema, index) : nullptr;
    }
    at.node = next;
    at.quiet = at.quiet || (next && next->reported);
  }
  return at;
}

std::string child_path(const Node& parent, const std::string& key) {
  return parent.path.empty() ? key : parent.path + "." + key;
}

// "'-1 mm'" for unit strings, "-1" for numbers.
std::string written(const Node& n) {
  return n.dimension.empty() ? describe(n) : "'" + excerpt(n.text) + "'";
}

// The bound a number breaks: "> 0 m", ">= 0", "<= 1".
std::string violated_bound(const Node& n, const ojson& s) {
  const double x = n.number();
  const auto kinds = unit_kinds(s);
  const std::string unit = kinds.size() == 1 ? " " + std::string(kinds[0]->si) : "";
  // Integer bounds as written: 2^63 - 1 is not a double.
  const auto text = [&](const ojson& b) {
    return (b.is_number_integer() ? b.dump() : format_number(b.get<double>())) + unit;
  };
  const auto bound = [&](const char* word, const char* op, auto broken) -> std::string {
    const ojson* b = keyword(s, word);
    return b && broken(x, b->get<double>()) ? std::string(op) + " " + text(*b) : "";
  };
  for (const std::string& b :
       {bound("exclusiveMinimum", ">", [](double v, double m) { return !(v > m); }),
        bound("minimum", ">=", [](double v, double m) { return !(v >= m); }),
        bound("exclusiveMaximum", "<", [](double v, double m) { return !(v < m); }),
        bound("maximum", "<=", [](double v, double m) { return !(v <= m); })})
    if (!b.empty()) return b;
  // A bound that rounds to the value as a double: name them all.
  std::string all;
  for (const auto& [word, op] : {std::pair{"exclusiveMinimum", ">"},
                                 {"minimum", ">="},
                                 {"exclusiveMaximum", "<"},
                                 {"maximum", "<="}})
    if (const ojson* b = keyword(s, word))
      all += (all.empty() ? "" : " and ") + std::string(op) + " " + text(*b);
  return all.empty() ? "a value in range" : all;
}

std::string count_phrase(const ojson& s, const char* min_word, const char* max_word,
                         const char* noun) {
  const ojson* n = keyword(s, min_word);
  const ojson* m = keyword(s, max_word);
  if (n && m && *n == *m) return "exactly " + n->dump() + " " + noun;
  if (n && m) return "between " + n->dump() + " and " + m->dump() + " " + noun;
  if (n) return "at least " + n->dump() + " " + noun;
  return "at most " + (m ? m->dump() : std::string("?")) + " " + noun;
}

std::string quoted(const std::string& description) {
  const auto end = description.rfind('\'');
  const auto begin = description.rfind('\'', end - 1);
  return description.substr(begin + 1, end - begin - 1);
}

class ErrorMapper {
 public:
  ErrorMapper(const Node& root, Diagnostics& diags) : root_(root), diags_(diags) {}

  void map(const valijson::ValidationResults::Error& error) {
    const Located at = locate(root_, error.context);
    if (!at.node || at.quiet) return;
    const std::string& d = error.description;
    if (d.starts_with("Object contains a property")) return unknown_keys(at);
    if (d.starts_with("Missing required property")) return missing_key(at, quoted(d));
    if (!at.schema || is_cascade(d) || !value_errors_.insert(at.node).second) return;
    diags_.error(*at.node, value_message(*at.node, *at.schema, d));
  }

 private:
  // valijson reports a failed child again at each enclosing level.
  static bool is_cascade(const std::string& d) {
    return d.starts_with("Failed to validate item") ||
           d.starts_with("Failed to validate against") || d.starts_with("Cannot validate item");
  }

  // valijson names only the first key it does not know, and quotes it
  // without escaping ("'typo'd key'"): every key of the mapping is checked
  // here instead, once per mapping.
  void unknown_keys(const Located& at) {
    if (!at.schema || !unknown_checked_.insert(at.node).second) return;
    const std::vector<std::string> allowed = property_names(*at.schema);
    for (const Entry& e : at.node->entries) {
      if (e.value.reported || property_schema(*at.schema, e.key)) continue;
      std::string message = "unknown key '" + excerpt(e.key) + "'";
      const std::string guess = did_you_mean(e.key, allowed);
      message += guess.empty() ? ", expected " + one_of(allowed) : guess;
      diags_.error(e.key_mark, child_path(*at.node, e.key), message);
    }
  }

  void missing_key(const Located& at, const std::string& key) {
    const ojson* sub = at.schema ? property_schema(*at.schema, key) : nullptr;
    diags_.error(
        at.node->mark, child_path(*at.node, key),
        "missing required key '" + key + "'" + (sub ? ", expected " + expected(*sub) : ""));
  }

  static std::string value_message(const Node& n, const ojson& s, const std::string& d) {
    if (d.starts_with("Value type not permitted") || d.starts_with("Failed to match regex"))
      return "got " + describe(n) + ", expected " + expected(s);
    if (d.starts_with("Failed to match against any enum")) {
      const ojson& values = *keyword(s, "enum");
      std::vector<std::string> names;
      for (const ojson& v : values) names.push_back(v.get<std::string>());
      const std::string guess = n.is_string() ? did_you_mean(n.string(), names) : "";
      return "got " + describe(n) + ", expected one of " + enum_words(values) + guess;
    }
    if (d.starts_with("Expected number"))
      return written(n) + " is out of range, expected " + violated_bound(n, s);
    if (d.starts_with("Array should contain"))
      return "got " + describe(n) + ", expected " +
             count_phrase(s, "minItems", "maxItems", "items");
    if (d.starts_with("Object should have")) return one_key_message(n, s);
    if (d.starts_with("Failed to match expected value set by 'const'"))
      return "got " + describe(n) + ", expected " + keyword(s, "const")->dump();
    if (d.starts_with("String should be no fewer")) return "got an empty string, expected a name";
    return d;
  }

  // Objects that hold exactly one of several alternatives (geometry, size).
  static std::string one_key_message(const Node& n, const ojson& s) {
    std::vector<std::string> given;
    for (const Entry& e : n.entries) given.push_back(e.key);
    const ojson* m = keyword(s, "maxProperties");
    const std::string wanted =
        (m && *m == 1 ? "exactly one of " : "at least one of ") + one_of(property_names(s));
    if (given.empty()) return "empty, expected " + wanted;
    return "got " + std::to_string(given.size()) + " (" + one_of(given, "and") + "), expected " +
           wanted;
  }

  const Node& root_;
  Diagnostics& diags_;
  std::set<const Node*> value_errors_;  // one value complaint per node is enough
  std::set<const Node*> unknown_checked_;
};

// `s` with every child's subschema `{}`: the keywords of the value itself.
ojson shell_schema(const ojson& s) {
  if (const auto ref = s.find("$ref"); ref != s.end()) return shell_schema(dereference(*ref));
  ojson shell = s;
  if (const auto props = shell.find("properties"); props != shell.end())
    for (auto& [key, sub] : props->items()) sub = ojson::object();
  if (const auto items = shell.find("items"); items != shell.end())
    *items =
        items->is_array() ? ojson(ojson::array_t(items->size(), ojson::object())) : ojson::object();
  if (const auto extra = shell.find("additionalProperties");
      extra != shell.end() && extra->is_object())
    *extra = ojson::object();
  if (const auto parts = shell.find("allOf"); parts != shell.end())
    for (ojson& part : *parts) part = shell_schema(part);
  return shell;
}

// `n` with every child a null: what its shell schema checks.
nlohmann::json shell_value(const Node& n) {
  if (n.is_sequence()) return nlohmann::json(nlohmann::json::array_t(n.items.size()));
  if (!n.is_map()) return to_json(n);
  nlohmann::json shell = nlohmann::json::object();
  for (const Entry& e : n.entries) shell[e.key] = nullptr;
  return shell;
}

// The values in `n`, itself included, counted up to just past `limit`.
std::size_t count_values(const Node& n, std::size_t limit) {
  std::size_t count = 1;
  for (const Node& item : n.items) {
    if (count > limit) return count;
    count += count_values(item, limit - count);
  }
  for (const Entry& e : n.entries) {
    if (count > limit) return count;
    count += count_values(e.value, limit - count);
  }
  return count;
}

// valijson keeps every error it finds, several per bad value and each with
// its path: their memory grows with the faults of the whole document, and
// an alias repeated into the values a load allows repeats its faults too.
// So a value of more than `piece_values` values is checked a piece at a
// time: its own keywords on its shell, then each child
// against the child's subschema, recursively. That is exact because the
// schema composes only through $ref and allOf (no oneOf, anyOf, not, if or
// uniqueItems; a test keeps it so): a value is valid when its own keywords
// hold and each child is valid against its subschema.
class PieceValidator {
 public:
  PieceValidator(ErrorMapper& mapper, std::size_t piece_values)
      : mapper_(mapper), piece_values_(piece_values) {}

  // `context` is valijson's path to `n` ("<root>", "[feeds]", "[0]").
  void check(const Node& n, const ojson& s, std::vector<std::string>& context) {
    if (count_values(n, piece_values_) <= piece_values_)
      return report(to_json(n), compiled(s, false), context);
    report(shell_value(n), compiled(s, true), context);
    for (std::size_t i = 0; i < n.items.size(); ++i)
      check_child(n.items[i], item_schema(s, i), std::to_string(i), context);
    for (const Entry& e : n.entries)
      check_child(e.value, property_schema(s, e.key), e.key, context);
  }

 private:
  void check_child(const Node& child, const ojson* s, const std::string& key,
                   std::vector<std::string>& context) {
    if (!s) return;  // an unknown key: its parent's shell reports it
    context.push_back("[" + key + "]");
    check(child, *s, context);
    context.pop_back();
  }

  void report(const nlohmann::json& value, const valijson::Schema& schema,
              const std::vector<std::string>& context) {
    valijson::ValidationResults results;
    if (validator_.validate(schema, valijson::adapters::NlohmannJsonAdapter(value), &results))
      return;
    valijson::ValidationResults::Error error;
    while (results.popError(error)) {
      error.context.erase(error.context.begin());  // "<root>" of the piece
      error.context.insert(error.context.begin(), context.begin(), context.end());
      mapper_.map(error);
    }
  }

  // A subschema (or its shell) as a document of its own, with the
  // definitions its references name.
  const valijson::Schema& compiled(const ojson& s, bool shell) {
    if (&s == &schema() && !shell) return compiled_schema();
    std::unique_ptr<valijson::Schema>& slot = cache_[{&s, shell}];
    if (!slot) {
      ojson body = shell ? shell_schema(s) : s;
      if (&s != &schema())
        body = ojson{{"definitions", schema().at("definitions")}, {"allOf", ojson::array({body})}};
      slot = compile(body);
    }
    return *slot;
  }

  ErrorMapper& mapper_;
  std::size_t piece_values_;
  valijson::Validator validator_{valijson::Validator::kStrongTypes};  // caches its regexes
  std::map<std::pair<const ojson*, bool>, std::unique_ptr<valijson::Schema>> cache_;
};

}  // namespace

const ojson* keyword(const ojson& s, std::string_view name) {
  if (!s.is_object()) return nullptr;
  const std::string key(name);
  if (const auto it = s.find(key); it != s.end()) return &*it;
  if (const auto it = s.find("$ref"); it != s.end())
    if (const ojson* k = keyword(dereference(*it), name)) return k;
  if (const auto it = s.find("allOf"); it != s.end())
    for (const ojson& sub : *it)
      if (const ojson* k = keyword(sub, name)) return k;
  return nullptr;
}

void walk_schema(Node& root, const std::function<void(Node&, const ojson*)>& visit) {
  walk(root, &schema(), visit);
}

void apply_defaults(Node& root) { walk_schema(root, add_defaults); }

void convert_units(Node& root, Diagnostics& diags) {
  walk_schema(root, [&](Node& n, const ojson* s) { convert_quantity(n, s, diags); });
}

void validate(const Node& root, Diagnostics& diags, std::size_t piece_values) {
  ErrorMapper mapper(root, diags);
  std::vector<std::string> context{"<root>"};
  PieceValidator(mapper, piece_values).check(root, schema(), context);
}

}  // namespace ces::scene
