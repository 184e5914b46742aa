#include "scene/resolve.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/path.hpp"
#include "scene/diagnostics.hpp"
#include "scene/limits.hpp"
#include "scene/schema.hpp"
#include "scene/text.hpp"

namespace ces::scene {
namespace {

namespace fs = std::filesystem;

bool is_json(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".json";
}

std::optional<std::string> read_file(const std::string& path, std::string& why) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    why = fs::exists(path, ec) ? "not a regular file" : "no such file";
    return std::nullopt;
  }
  why = too_large(path, limits::kFileBytes);
  if (!why.empty()) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in) {
    why = "cannot read it";
    return std::nullopt;
  }
  return text.str();
}

// Later values win: maps merge key by key, lists concatenate.
void merge(Node& into, Node&& from) {
  if (into.is_map() && from.is_map()) {
    for (Entry& e : from.entries) {
      auto same = std::find_if(into.entries.begin(), into.entries.end(),
                               [&](const Entry& x) { return x.key == e.key; });
      if (same == into.entries.end()) {
        into.entries.push_back(std::move(e));
      } else {
        same->key_mark = e.key_mark;
        merge(same->value, std::move(e.value));
      }
    }
  } else if (into.is_sequence() && from.is_sequence()) {
    for (Node& item : from.items) into.items.push_back(std::move(item));
  } else {
    into = std::move(from);
    return;
  }
  into.mark = from.mark;
}

// An absolute path with symlinks resolved (as far as it exists).
fs::path resolved(const fs::path& path) {
  std::error_code ec;
  return fs::weakly_canonical(fs::absolute(path.empty() ? fs::path(".") : path, ec), ec);
}

// Whether `path` is `folder` or lies below it (both resolved).
bool is_within(const fs::path& path, const fs::path& folder) {
  return std::mismatch(folder.begin(), folder.end(), path.begin(), path.end()).first ==
         folder.end();
}

// The folders includes may come from: the scene's own, then the
// --include-path ones.
std::vector<fs::path> include_roots(const std::string& scene_path,
                                    const std::vector<std::string>& include_paths) {
  std::vector<fs::path> roots{resolved(fs::path(scene_path).parent_path())};
  for (const std::string& folder : include_paths) roots.push_back(resolved(folder));
  return roots;
}

class Includer {
 public:
  Includer(const std::string& scene_path, const std::vector<std::string>& include_paths,
           Budget& budget, Diagnostics& diags)
      : roots_(include_roots(scene_path, include_paths)), budget_(budget), diags_(diags) {}

  // `named_at`: the include entry that asked for the file (none for the scene).
  std::optional<Node> load(const std::string& path, const std::optional<Mark>& named_at) {
    const Mark where = named_at.value_or(Mark{path, 0, 0});
    std::string why;
    const auto text = read_file(path, why);
    if (!text) {
      diags_.error(where, named_at ? "include" : "", "cannot read '" + path + "': " + why);
      return std::nullopt;
    }
    return load_text(*text, path, where);
  }

  std::optional<Node> load_text(const std::string& text, const std::string& path,
                                const Mark& where) {
    std::error_code ec;
    const std::string id = fs::weakly_canonical(path, ec).string();
    const auto cycle = std::find(ids_.begin(), ids_.end(), id);
    if (cycle != ids_.end()) {
      std::string chain;
      for (auto it = cycle; it != ids_.end(); ++it)
        chain += names_[std::size_t(it - ids_.begin())] + " -> ";
      diags_.error(where, "include", "include cycle: " + chain + path);
      return std::nullopt;
    }
    std::optional<Node> root = parse(text, path, is_json(path), budget_, diags_);
    if (!root) return std::nullopt;
    if (!root->is_map()) {
      diags_.error({path, 1, 1}, "",
                   "got " + describe(*root) + ", expected a mapping of scene keys");
      return std::nullopt;
    }
    ids_.push_back(id);
    names_.push_back(path);
    Node merged = expand(std::move(*root), path);
    ids_.pop_back();
    names_.pop_back();
    return merged;
  }

 private:
  // The file's own keys over the merge of its includes.
  Node expand(Node root, const std::string& path) {
    const auto include = std::find_if(root.entries.begin(), root.entries.end(),
                                      [](const Entry& e) { return e.key == "include"; });
    if (include == root.entries.end()) return root;
    const Node list = std::move(include->value);
    root.entries.erase(include);
    Node base;
    base.kind = Node::Kind::Map;
    for (const Node& name : list.is_sequence() ? list.items : std::vector<Node>{list}) {
      if (!name.is_string()) {
        diags_.error(name.mark, "include",
                     "got " + describe(name) + ", expected a file name or a list of file names");
        continue;
      }
      const std::string child =
          (fs::path(path).parent_path() / name.string()).lexically_normal().string();
      if (!admit(name, child)) continue;
      if (auto fragment = load(child, name.mark)) merge(base, std::move(*fragment));
    }
    merge(base, std::move(root));
    return base;
  }

  // Whether the include `name` (in the file on top of the chain) may be
  // read: within the bounds on chains and files, and inside an allowed
  // folder once symlinks are resolved. Refusals do not say whether the file
  // exists: a scene must not be a way to probe a machine's files.
  bool admit(const Node& name, const std::string& child) {
    const auto refuse = [&](const std::string& message) {
      diags_.error(name.mark, "include", message);
      return false;
    };
    if (ids_.size() >= std::size_t(limits::kIncludeDepth))
      return refuse("an include chain of more than " + std::to_string(limits::kIncludeDepth) +
                    " files, expected a shorter chain");
    if (budget_.files < 0) return false;  // reported once, at the first file past the bound
    if (budget_.files-- == 0)
      return refuse("more than " + std::to_string(limits::kIncludeFiles) +
                    " included files in one scene, expected fewer");
    const fs::path target = resolved(child);
    if (std::none_of(roots_.begin(), roots_.end(),
                     [&](const fs::path& root) { return is_within(target, root); }))
      return refuse("'" + excerpt(name.string(), limits::kPathBytes) +
                    "' is outside the folder of " +
                    excerpt(fs::path(names_.front()).filename().string(), limits::kPathBytes) +
                    ", expected a file in " + roots_.front().string() +
                    (roots_.size() > 1 ? " or an --include-path folder" : "") +
                    " (symlinks resolved; another folder can be named with --include-path)");
    return true;
  }

  std::vector<fs::path> roots_;  // folders includes may come from
  Budget& budget_;
  Diagnostics& diags_;
  std::vector<std::string> ids_;    // canonical paths of the files being read
  std::vector<std::string> names_;  // the same, as written, for messages
};

// "bodies[0].material" and "bodies.0.material" both give bodies, 0, material.
std::vector<std::string> split_path(const std::string& key_path) {
  std::string dotted = key_path;
  std::replace(dotted.begin(), dotted.end(), '[', '.');
  dotted.erase(std::remove(dotted.begin(), dotted.end(), ']'), dotted.end());
  std::vector<std::string> segments;
  std::istringstream in(dotted);
  for (std::string s; std::getline(in, s, '.');) segments.push_back(s);
  if (!dotted.empty() && dotted.back() == '.') segments.emplace_back();
  return segments;
}

// An index, or the name of an item of a list of named mappings.
std::optional<std::size_t> find_item(const Node& list, const std::string& segment) {
  if (!segment.empty() && std::all_of(segment.begin(), segment.end(), ::isdigit)) {
    std::size_t i = 0;
    const auto [end, ec] = std::from_chars(segment.data(), segment.data() + segment.size(), i);
    if (ec == std::errc() && i < list.items.size()) return i;
    return std::nullopt;
  }
  for (std::size_t i = 0; i < list.items.size(); ++i) {
    const Node* name = list.items[i].find("name");
    if (name && name->is_string() && name->string() == segment) return i;
  }
  return std::nullopt;
}

void set_marks(Node& n, const Mark& mark) {
  n.mark = mark;
  for (Node& item : n.items) set_marks(item, mark);
  for (Entry& e : n.entries) {
    e.key_mark = mark;
    set_marks(e.value, mark);
  }
}

std::optional<Node> parse_value(const std::string& value, const Mark& mark, Budget& budget,
                                Diagnostics& diags) {
  if (invalid_utf8(value)) {
    diags.error(mark, "", "invalid UTF-8 in the value, expected UTF-8 text");
    return std::nullopt;
  }
  try {
    (void)YAML::Load(value);
  } catch (const YAML::Exception& e) {
    diags.error(mark, "", "cannot parse the value '" + excerpt(value) + "': " + e.msg);
    return std::nullopt;
  }
  std::optional<Node> node = parse(value, mark.file, false, budget, diags);
  if (node) set_marks(*node, mark);
  return node;
}

}  // namespace

std::optional<Node> load_tree(const std::string& path,
                              const std::vector<std::string>& include_paths, Budget& budget,
                              Diagnostics& diags) {
  return Includer(path, include_paths, budget, diags).load(path, std::nullopt);
}

std::optional<Node> load_tree_text(const std::string& text, const std::string& path,
                                   const std::vector<std::string>& include_paths, Budget& budget,
                                   Diagnostics& diags) {
  return Includer(path, include_paths, budget, diags).load_text(text, path, {path, 0, 0});
}

namespace {

// The override path's segments; nullopt: reported (at `mark`, as `shown`).
std::optional<std::vector<std::string>> override_segments(const std::string& key_path,
                                                          const std::string& shown,
                                                          const Mark& mark, Diagnostics& diags) {
  const std::string cut = excerpt(shown, limits::kPathBytes);
  const auto fail = [&](const std::string& key, const std::string& message) {
    diags.error(mark, key, message);
    return std::nullopt;
  };
  if (key_path.size() > limits::kPathBytes)
    return fail(cut, "a key path longer than " + std::to_string(limits::kPathBytes) +
                         " characters, expected a shorter one");
  std::vector<std::string> segments = split_path(key_path);
  const bool blank =
      std::any_of(segments.begin(), segments.end(), [](const auto& s) { return s.empty(); });
  if (segments.empty() || blank)
    return fail(shown, "invalid key path '" + cut +
                           "', expected keys, indices or item names "
                           "joined by dots (feeds.nozzle.rate)");
  if (segments.size() > std::size_t(limits::kNesting))
    return fail(cut, "a key path of " + std::to_string(segments.size()) +
                         " segments, expected at most " + std::to_string(limits::kNesting));
  if (segments.front() == "include" || segments.front() == "set")
    return fail(shown, "'" + segments.front() + "' cannot be overridden, expected a scene key");
  return segments;
}

// The child of a mapping or a list that one path segment names (a key, or
// an item's index or name); nullptr where there is none.
Node* child_of(Node& n, const std::string& segment) {
  if (n.is_map()) return n.find(segment);
  if (!n.is_sequence()) return nullptr;
  const auto index = find_item(n, segment);
  return index ? &n.items[*index] : nullptr;
}

// The node the path names, maps created on the way; nullptr: reported.
Node* override_target(Node& root, const std::vector<std::string>& segments,
                      const std::string& shown, const Mark& mark, Diagnostics& diags) {
  Node* n = &root;
  std::string walked;
  for (const std::string& s : segments) {
    if (n->kind == Node::Kind::Null) n->kind = Node::Kind::Map;  // "trajectories:" left empty
    Node* child = child_of(*n, s);
    if (!child && n->is_map()) {
      n->entries.push_back({s, mark, Node{}});
      child = &n->entries.back().value;
      child->mark = mark;
    } else if (!child && n->is_sequence()) {
      const std::string expected =
          !n->items.empty() ? "expected an index below " + std::to_string(n->items.size()) +
                                  " or the name of an item"
          : mark.file == "--set"
              ? "the list is empty here (every --unset applies before the --set values)"
              : "the list is empty, expected an item to set a key of";
      diags.error(
          mark, shown,
          "invalid override path: '" + walked + "' has no item '" + excerpt(s) + "', " + expected);
      return nullptr;
    } else if (!child) {
      diags.error(mark, shown,
                  "invalid override path: '" + walked + "' is " + describe(*n) +
                      ", not a mapping or a list");
      return nullptr;
    }
    n = child;
    walked += (walked.empty() ? "" : ".") + s;
  }
  return n;
}

}  // namespace

void apply_override(Node& root, const std::string& key_path, const std::string& value, int ordinal,
                    Budget& budget, Diagnostics& diags) {
  const Mark mark{"--set", ordinal, 1};
  const auto segments = override_segments(key_path, key_path, mark, diags);
  if (!segments) return;
  std::optional<Node> replacement = parse_value(value, mark, budget, diags);
  if (!replacement) return;
  if (Node* target = override_target(root, *segments, key_path, mark, diags))
    *target = std::move(*replacement);
}

void apply_removal(Node& root, const std::string& key_path, int ordinal, Diagnostics& diags) {
  const Mark mark{"--unset", ordinal, 1};
  const auto segments = override_segments(key_path, key_path, mark, diags);
  if (!segments) return;
  const auto missing = [&] {
    diags.error(mark, key_path, "the scene sets no '" + excerpt(key_path) +
                                    "', expected a key or list item it sets");
  };
  // Down to the parent, creating nothing.
  Node* parent = &root;
  for (std::size_t s = 0; s + 1 < segments->size(); ++s) {
    parent = child_of(*parent, (*segments)[s]);
    if (parent == nullptr) return missing();
  }
  const std::string& last = segments->back();
  if (parent->is_map()) {
    const auto at = std::find_if(parent->entries.begin(), parent->entries.end(),
                                 [&](const Entry& e) { return e.key == last; });
    if (at == parent->entries.end()) return missing();
    parent->entries.erase(at);
  } else if (const auto item = parent->is_sequence() ? find_item(*parent, last) : std::nullopt) {
    parent->items.erase(parent->items.begin() + std::ptrdiff_t(*item));
  } else {
    missing();
  }
}

void apply_scene_set(Node& root, Diagnostics& diags) {
  const auto at = std::find_if(root.entries.begin(), root.entries.end(),
                               [](const Entry& e) { return e.key == "set"; });
  if (at == root.entries.end()) return;
  Node set = std::move(at->value);
  root.entries.erase(at);
  if (!set.is_map())
    return diags.error(set.mark, "set",
                       "got " + describe(set) + ", expected a mapping of key paths to values");
  for (Entry& e : set.entries) {
    const std::string shown = "set." + e.key;
    const auto segments = override_segments(e.key, shown, e.key_mark, diags);
    if (!segments) continue;
    if (Node* target = override_target(root, *segments, shown, e.key_mark, diags))
      *target = std::move(e.value);
  }
}

std::string too_large(const std::filesystem::path& file, std::uintmax_t max_bytes) {
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(file, ec);
  if (ec || size <= max_bytes) return "";
  return std::to_string(size) + " bytes, expected at most " + std::to_string(max_bytes);
}

void rebase_paths(Node& root, const std::string& scene_path) {
  const fs::path scene_dir = absolute_path(fs::path(scene_path).parent_path());
  walk_schema(root, [&](Node& n, const nlohmann::ordered_json* s) {
    if (!s || !n.is_string() || !keyword(*s, "x-path")) return;
    const fs::path written(n.string());
    if (written.is_absolute()) return;
    const fs::path base = n.mark.file == "--set" ? fs::path() : fs::path(n.mark.file).parent_path();
    const fs::path target = (absolute_path(base) / written).lexically_normal();
    const fs::path relative = target.lexically_relative(scene_dir);
    n.scalar = n.text = (relative.empty() ? target : relative).generic_string();
  });
}

}  // namespace ces::scene
