#include "scene/tree.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "scene/diagnostics.hpp"
#include "scene/limits.hpp"
#include "scene/text.hpp"

namespace ces::scene {
namespace {

std::size_t skip_sign(std::string_view s, std::size_t i) {
  return i < s.size() && (s[i] == '-' || s[i] == '+') ? i + 1 : i;
}

// [-+]?[0-9]+ (YAML 1.2 core schema). Matched by hand: std::regex recurses
// per character and overflows the stack on long scalars.
bool is_core_int(std::string_view s) {
  const std::size_t i = skip_sign(s, 0);
  return i < s.size() && skip_digits(s, i) == s.size();
}

// [-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?
bool is_core_float(std::string_view s) {
  std::size_t i = skip_sign(s, 0);
  const std::size_t int_end = skip_digits(s, i);
  std::size_t end = int_end;
  if (end < s.size() && s[end] == '.') end = skip_digits(s, end + 1);
  if (int_end == i && end <= int_end + 1) return false;  // no digit before the exponent
  if (end < s.size() && (s[end] == 'e' || s[end] == 'E')) {
    const std::size_t first = skip_sign(s, end + 1);
    end = skip_digits(s, first);
    if (end == first) return false;
  }
  return end == s.size();
}

// Number from a plain scalar known to match the YAML 1.2 core schema;
// nullopt when no double holds it (an underflow is not a zero).
std::optional<nlohmann::json> parse_number(const std::string& s, bool integer) {
  const char* first = s.data() + (s[0] == '+' ? 1 : 0);
  const char* last = s.data() + s.size();
  if (integer) {
    std::int64_t i = 0;
    if (std::from_chars(first, last, i).ec == std::errc()) return i;
    std::uint64_t u = 0;
    if (std::from_chars(first, last, u).ec == std::errc()) return u;
  }
  double d = 0.0;
  const auto [end, ec] = std::from_chars(first, last, d);
  const std::string_view mantissa = std::string_view(s).substr(0, s.find_first_of("eE"));
  const bool zero = mantissa.find_first_of("123456789") == std::string_view::npos;
  if (ec != std::errc() || end != last || !std::isfinite(d) ||
      (d == 0.0 ? !zero : !std::isnormal(d)))
    return std::nullopt;
  return d;
}

// Types of plain (unquoted) scalars by the YAML 1.2 core schema, which is
// also what JSON means: "1 ms" stays a string, "1e-3" is a number, "yes" is
// a string (not a YAML 1.1 boolean). nullopt: a number out of range.
std::optional<nlohmann::json> resolve_plain(const std::string& s) {
  if (s == "true" || s == "True" || s == "TRUE") return true;
  if (s == "false" || s == "False" || s == "FALSE") return false;
  if (is_core_int(s)) return parse_number(s, true);
  if (is_core_float(s)) return parse_number(s, false);
  return s;
}

std::string nested_too_deep() {
  return "nested deeper than " + std::to_string(limits::kNesting) + " levels, expected at most " +
         std::to_string(limits::kNesting) + " levels of mappings and lists";
}

// The place of byte `offset` of `text`.
Mark mark_at(const std::string& text, std::size_t offset, const std::string& file) {
  const auto at = text.begin() + std::ptrdiff_t(offset);
  const auto line_start = std::find(std::make_reverse_iterator(at), text.rend(), '\n').base();
  return {file, int(std::count(text.begin(), at, '\n')) + 1, int(at - line_start) + 1};
}

// A byte as messages show it: "0x1b".
std::string hex_byte(char c) {
  char byte[8];
  std::snprintf(byte, sizeof byte, "0x%02x", static_cast<unsigned char>(c));
  return byte;
}

class Converter {
 public:
  Converter(const std::string& text, const std::string& file, Budget& budget, Diagnostics& diags)
      : text_(text), file_(file), budget_(budget), diags_(diags) {}

  Mark mark(const YAML::Mark& m) const { return {file_, m.line + 1, m.column + 1}; }

  // True when a bound was broken (reported): the tree is then incomplete.
  bool stopped() const { return stopped_; }

  // `holder` is where the user sees the value start: the key for values in
  // a mapping (yaml-cpp marks an empty value at the next token). `path`
  // names the value in messages; `depth` counts the collections around it.
  Node convert(const YAML::Node& y, const Mark& holder, const std::string& path = "",
               int depth = 0) {
    Node n;
    n.mark = holder;
    if (!admit(y, holder, path, depth)) return n;
    if (y.IsScalar()) {
      n.kind = Node::Kind::Scalar;
      n.mark = mark(y.Mark());
      n.text = y.Scalar();
      if (!printable(n.text, n.mark, path)) {
        n.reported = true;
        return n;
      }
      const bool quoted = y.Tag() == "!" || y.Tag() == "tag:yaml.org,2002:str";
      std::optional<nlohmann::json> value = quoted ? nlohmann::json(n.text) : resolve_plain(n.text);
      n.scalar = value ? std::move(*value) : nlohmann::json(n.text);
      n.text = as_shown(y);
      if (!value) {
        diags_.error(n.mark, path,
                     excerpt(n.text) +
                         " is out of range, expected a number of magnitude "
                         "2.2e-308 to 1.8e308, or 0");
        n.reported = true;
      }
    } else if (y.IsSequence()) {
      n.kind = Node::Kind::Sequence;
      for (const YAML::Node& item : y) {
        const std::string item_path = path + "[" + std::to_string(n.items.size()) + "]";
        n.items.push_back(convert(item, mark(item.Mark()), item_path, depth + 1));
        if (stopped_) break;
      }
    } else if (y.IsMap()) {
      n.kind = Node::Kind::Map;
      convert_map(y, n, path, depth);
    }
    return n;
  }

 private:
  // Counts a value against the load's budget and checks the bounds on
  // nesting and key paths; false (reported once) when one is broken.
  bool admit(const YAML::Node& y, const Mark& holder, const std::string& path, int depth) {
    if (stopped_) return false;
    const std::size_t bytes = path.size() + (y.IsScalar() ? y.Scalar().size() : 0);
    std::string broken;
    if (depth > limits::kNesting) {
      broken = nested_too_deep();
    } else if (path.size() > limits::kPathBytes) {
      broken = "a key path longer than " + std::to_string(limits::kPathBytes) +
               " characters, expected shorter keys or less nesting";
    } else if (y.IsMap() && y.size() > limits::kKeys) {
      broken = "a mapping of " + std::to_string(y.size()) + " keys, expected at most " +
               std::to_string(limits::kKeys);
    } else if (budget_.values == 0 || budget_.text_bytes < bytes) {
      broken = "the scene expands to more than " + std::to_string(limits::kValues) + " values or " +
               std::to_string(limits::kTextBytes >> 20) +
               " MB of text (each use of a YAML alias counts its value again), expected a "
               "smaller scene";
    }
    if (broken.empty()) {
      --budget_.values;
      budget_.text_bytes -= bytes;
      return true;
    }
    const Mark at = y.IsScalar() || y.IsNull() ? mark(y.Mark()) : holder;
    diags_.error(at, excerpt(path, limits::kPathBytes), broken);
    stopped_ = true;
    return false;
  }

  // A scalar for messages, as far as its first line in the file goes: a
  // value folded from several lines (a file that is not a scene, included
  // by mistake) shows that line only.
  std::string as_shown(const YAML::Node& y) const {
    const std::string& value = y.Scalar();
    std::size_t pos = std::min<std::size_t>(std::size_t(std::max(y.Mark().pos, 0)), text_.size());
    // A block scalar ("|", ">") starts on the line after its indicator.
    if (pos < text_.size() && (text_[pos] == '|' || text_[pos] == '>'))
      pos = text_.find_first_not_of(" \t", std::min(text_.find('\n', pos), text_.size() - 1) + 1);
    pos = std::min(pos, text_.size());
    const std::size_t end = std::min(text_.find('\n', pos), text_.size());
    const std::size_t room = std::max<std::size_t>(end - pos, 1);
    if (value.size() <= room && value.find('\n') == std::string::npos) return value;
    return excerpt(value, room);
  }

  // A control character written as an escape ("\e[2J", "\u0000") passes
  // the file's own check and would reach a terminal or a file name as it
  // is: refused like one written raw.
  bool printable(const std::string& text, const Mark& at, const std::string& path) {
    const auto bad = control_character(text);
    if (!bad) return true;
    diags_.error(at, path,
                 "a control character (byte " + hex_byte(text[*bad]) +
                     ", written as an escape), expected printable text");
    return false;
  }

  // yaml-cpp keeps every duplicate key; the first one wins, the others are
  // reported (they are almost always a forgotten edit).
  void convert_map(const YAML::Node& y, Node& n, const std::string& path, int depth) {
    std::map<std::string, Mark> seen;
    for (auto it = y.begin(); it != y.end() && !stopped_; ++it) {
      const Mark key_mark = mark(it->first.Mark());
      if (!it->first.IsScalar()) {
        diags_.error(key_mark, "", "keys must be plain names, not lists or mappings");
        continue;
      }
      const std::string key = it->first.Scalar();
      if (!printable(key, key_mark, path)) continue;
      const std::string key_path = path.empty() ? key : path + "." + key;
      if (key == "<<" && it->first.Tag() == "?") {
        diags_.error(key_mark, excerpt(key_path, limits::kPathBytes),
                     "a YAML merge key ('<<'), which ces-sim does not support; expected the "
                     "keys written out, or shared values in an included file");
        continue;
      }
      const auto [first, inserted] = seen.emplace(key, key_mark);
      if (!inserted) {
        diags_.error(key_mark, excerpt(key_path, limits::kPathBytes),
                     "duplicate key '" + excerpt(key) + "', first given at line " +
                         std::to_string(first->second.line));
        continue;
      }
      n.entries.push_back({key, key_mark, convert(it->second, key_mark, key_path, depth + 1)});
    }
  }

  const std::string& text_;
  const std::string& file_;
  Budget& budget_;
  Diagnostics& diags_;
  bool stopped_ = false;
};

// Checks the syntax of a JSON text without building anything, so that
// nesting or size cost no memory; errors get the place nlohmann gives.
class JsonChecker : public nlohmann::json::json_sax_t {
 public:
  JsonChecker(const std::string& text, const std::string& file, Diagnostics& diags)
      : text_(text), file_(file), diags_(diags) {}

  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  // Past the nesting bound the check stops: the YAML pass reports the
  // bound with its line.
  bool start_object(std::size_t) override { return ++depth_ <= limits::kNesting + 1; }
  bool key(string_t&) override { return true; }
  bool end_object() override { return --depth_, true; }
  bool start_array(std::size_t) override { return ++depth_ <= limits::kNesting + 1; }
  bool end_array() override { return --depth_, true; }

  // `position` counts the bytes read, the offending one last. nlohmann's
  // message ("[json.exception...] parse error at line L, column C: what;
  // last read: 'token'") keeps its words; the token is cut to an excerpt.
  bool parse_error(std::size_t position, const std::string& last_token,
                   const nlohmann::detail::exception& e) override {
    std::string what = e.what();
    if (const auto where = what.find(", column "); where != std::string::npos)
      what = what.substr(what.find(": ", where) + 2);
    else if (const auto tag = what.find("] "); tag != std::string::npos)
      what = what.substr(tag + 2);
    if (const auto read = what.find("; last read: "); read != std::string::npos)
      what = what.substr(0, read) + "; last read: '" + excerpt(last_token) + "'";
    const std::size_t offset = std::min(position, text_.size());
    diags_.error(mark_at(text_, offset == 0 ? 0 : offset - 1, file_), "", "invalid JSON: " + what);
    reported_ = true;
    return false;
  }

  bool reported() const { return reported_; }

 private:
  const std::string& text_;
  const std::string& file_;
  Diagnostics& diags_;
  int depth_ = 0;
  bool reported_ = false;
};

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

namespace {

// The marks of the first two documents' roots. yaml-cpp's LoadAll reads
// every document, and on some malformed text (a leading ',') it yields
// empty documents at the same place for ever, each kept: two are enough to
// tell one document from more, or from a parser that does not move on.
class FirstDocuments : public YAML::EventHandler {
 public:
  explicit FirstDocuments(const std::string& text) {
    std::istringstream in(text);
    YAML::Parser parser(in);
    for (int i = 0; i < 2 && parser.HandleNextDocument(*this); ++i) {
    }
  }
  std::vector<YAML::Mark> roots;  // one per document read

 private:
  void root(const YAML::Mark& m) {
    if (roots.size() < documents_) roots.push_back(m);
  }
  void OnDocumentStart(const YAML::Mark&) override { ++documents_; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& m, YAML::anchor_t) override { root(m); }
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override { root(m); }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t,
                const std::string&) override {
    root(m);
  }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {
    root(m);
  }
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {
    root(m);
  }
  void OnMapEnd() override {}

  std::size_t documents_ = 0;
};

}  // namespace

std::optional<Node> parse(const std::string& text, const std::string& file, bool json,
                          Budget& budget, Diagnostics& diags) {
  if (text.size() > limits::kFileBytes) {
    diags.error({file, 1, 1}, "",
                "the file has " + std::to_string(text.size()) + " bytes, expected at most " +
                    std::to_string(limits::kFileBytes));
    return std::nullopt;
  }
  const auto bad_byte = [&](std::size_t at, const char* what, const char* expected) {
    diags.error(mark_at(text, at, file), "",
                std::string(what) + " (byte " + hex_byte(text[at]) + "), expected " + expected);
  };
  if (const auto at = invalid_utf8(text)) {
    bad_byte(*at, "invalid UTF-8", "UTF-8 text");
    return std::nullopt;
  }
  if (const auto at = control_character(text)) {
    bad_byte(*at, "a control character", "printable text");
    return std::nullopt;
  }
  if (json) {
    JsonChecker checker(text, file, diags);
    if (!nlohmann::json::sax_parse(text, &checker) && checker.reported()) return std::nullopt;
  }
  try {
    // One document: yaml-cpp's Load would read the first and drop what
    // follows a '---' or '...' unseen, however wrong.
    const FirstDocuments documents(text);
    if (documents.roots.size() > 1) {
      const YAML::Mark at = documents.roots[1];
      const bool known = at.line >= 0;
      const bool stuck = at.pos == documents.roots[0].pos;
      diags.error({file, known ? at.line + 1 : 1, known ? at.column + 1 : 1}, "",
                  stuck ? "invalid YAML: the text from here on cannot be read"
                        : "a second YAML document (after '---' or '...'), expected one scene");
      return std::nullopt;
    }
    const YAML::Node root = documents.roots.empty() ? YAML::Node() : YAML::Load(text);
    Converter converter(text, file, budget, diags);
    Node tree = converter.convert(root, {file, 1, 1});
    if (converter.stopped()) return std::nullopt;
    return tree;
  } catch (const YAML::DeepRecursion& e) {
    // yaml-cpp's own guard, far deeper than ours: its message says "bad file".
    diags.error({file, e.mark.line + 1, e.mark.column + 1}, "", nested_too_deep());
    return std::nullopt;
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
  return node.scalar.is_string() ? "'" + excerpt(node.text) + "'" : excerpt(node.text);
}

}  // namespace ces::scene
