// Collects every problem of a scene before anything is thrown.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_set>
#include <vector>

#include "scene/scene.hpp"
#include "scene/tree.hpp"

namespace ces::scene {

class Diagnostics {
 public:
  // Errors kept for the report; past them only a count is kept, so a
  // hostile document cannot make a report of millions of lines. An error
  // reported again is neither kept nor counted twice.
  static constexpr std::size_t kShownErrors = 100;

  void error(const Mark& at, std::string path, std::string message);
  // At a node of the tree; marks it reported so later passes stay quiet.
  void error(Node& at, std::string message);
  void error(const Node& at, std::string message);
  // A warning: reported, but the scene loads.
  void warning(const Node& at, std::string message);
  const std::vector<Diagnostic>& warnings() const { return warnings_; }

  bool empty() const { return list_.empty(); }
  // Throws SceneError with the errors kept, sorted by place, and a last
  // line with the number of the others.
  [[noreturn]] void raise();

 private:
  std::vector<Diagnostic> list_;
  std::size_t unshown_ = 0;
  std::unordered_set<std::uint64_t> seen_;  // every error's hash, shown or not
  std::vector<Diagnostic> warnings_;
};

// " (did you mean 'density'?)" when a candidate is a plausible typo of
// `word`, else "". Words longer than any name are not compared (the cost
// grows with the product of the lengths).
std::string did_you_mean(std::string_view word, const std::vector<std::string>& candidates);

// "a, b or c" ("a, b and c" with last = "and").
std::string one_of(const std::vector<std::string>& names, std::string_view last = "or");

}  // namespace ces::scene
