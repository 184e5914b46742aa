// What the scene compiler's parts share: reading a vector, numbers in
// messages, and the table of names a section declares.
#pragma once
#include <iomanip>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "common/math.hpp"
#include "scene/diagnostics.hpp"
#include "scene/resolve.hpp"
#include "scene/tree.hpp"

namespace ces::scene {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

inline Vec3 vec3(const Node& n) {
  return {n.items[0].number(), n.items[1].number(), n.items[2].number()};
}

inline std::string format(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

inline std::string metres(double x) { return format(x) + " m"; }

// A count in full ("10000000", not "1e+07") while it is short enough.
inline std::string whole(double x) {
  if (!(x < 1e15)) return format(x);
  std::ostringstream s;
  s << std::fixed << std::setprecision(0) << x;
  return s.str();
}

// Names declared by one section, for duplicate checks and references.
class NameTable {
 public:
  explicit NameTable(std::string what) : what_(std::move(what)) {}

  // False, with a diagnostic, when the name was declared before.
  bool declare(const std::string& name, const Mark& mark, const std::string& path, int index,
               Diagnostics& diags) {
    const auto [it, inserted] = table_.emplace(name, Declared{index, mark.line});
    if (!inserted)
      diags.error(mark, path,
                  "duplicate " + what_ + " name '" + name + "', first given at line " +
                      std::to_string(it->second.line));
    return inserted;
  }

  std::optional<int> find(const std::string& name) const {
    const auto it = table_.find(name);
    return it == table_.end() ? std::nullopt : std::optional<int>(it->second.index);
  }

  // `extra` names that are valid references without being declared ("ground").
  std::optional<int> resolve(const Node& ref, Diagnostics& diags,
                             const std::vector<std::string>& extra = {}) const {
    if (auto index = find(ref.string())) return index;
    std::vector<std::string> names = extra;
    for (const auto& [name, declared] : table_) names.push_back(name);
    std::string message = "unknown " + what_ + " '" + ref.string() + "'";
    const std::string guess = did_you_mean(ref.string(), names);
    if (!guess.empty())
      message += guess;
    else if (names.empty())
      message += ", and the scene defines none";
    else
      message += ", expected " + one_of(names);
    diags.error(ref, message);
    return std::nullopt;
  }

 private:
  struct Declared {
    int index;
    int line;
  };
  std::string what_;
  std::map<std::string, Declared> table_;
};

}  // namespace ces::scene
