#include "scene/diagnostics.hpp"

#include <algorithm>
#include <tuple>

#include "common/hash.hpp"
#include "scene/text.hpp"

namespace ces::scene {
namespace {

// Optimal string alignment distance: Levenshtein plus adjacent
// transpositions, the commonest typo ("apdg" for "apgd").
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[a.size()][b.size()];
}

}  // namespace

std::string Diagnostic::str() const {
  std::string s = file;
  if (line > 0) {
    s += ':';
    s += std::to_string(line);
    s += ':';
    s += std::to_string(column);
  }
  s += ": ";
  if (warning) s += "warning: ";
  if (!path.empty()) s += path + ": ";
  return one_line(s + message);
}

SceneError::SceneError(std::vector<Diagnostic> d)
    : std::runtime_error(d.empty() ? "invalid scene" : d.front().str()),
      diagnostics_(std::move(d)) {}

// An error found twice (by two passes over one node) is one error: kept
// or counted once. Errors are told apart by a 64-bit hash of their place
// and message, not by their text, so that counting a hostile document's
// millions holds a number per error, not its strings; two different errors
// share a hash with a chance of about n^2 / 2^65 for n errors.
void Diagnostics::error(const Mark& at, std::string path, std::string message) {
  const std::string place = std::to_string(at.line) + ':' + std::to_string(at.column);
  std::uint64_t h = fnv1a(at.file);
  for (const std::string_view part :
       {std::string_view(place), std::string_view(path), std::string_view(message)})
    h = fnv1a(part, fnv1a(std::string_view("\0", 1), h));
  if (!seen_.insert(h).second) return;
  if (list_.size() == kShownErrors) {
    ++unshown_;
    return;
  }
  list_.push_back({at.file, at.line, at.column, std::move(path), std::move(message)});
}

void Diagnostics::error(Node& at, std::string message) {
  at.reported = true;
  error(at.mark, at.path, std::move(message));
}

void Diagnostics::error(const Node& at, std::string message) {
  error(at.mark, at.path, std::move(message));
}

void Diagnostics::warning(const Node& at, std::string message) {
  warnings_.push_back(
      {at.mark.file, at.mark.line, at.mark.column, at.path, std::move(message), true});
}

void Diagnostics::raise() {
  const auto key = [](const Diagnostic& d) {
    return std::tie(d.file, d.line, d.column, d.path, d.message);
  };
  std::stable_sort(list_.begin(), list_.end(),
                   [&](const Diagnostic& a, const Diagnostic& b) { return key(a) < key(b); });
  if (unshown_ > 0)
    list_.push_back({list_.front().file, 0, 0, "",
                     std::to_string(unshown_) + " more errors, not shown (the first " +
                         std::to_string(kShownErrors) + " found are above)"});
  throw SceneError(std::move(list_));
}

std::string did_you_mean(std::string_view word, const std::vector<std::string>& candidates) {
  // Up to a third of the word may be wrong (at least one letter): "densty",
  // "frcition" and "apdg" are caught; unrelated names are not suggested.
  constexpr std::size_t kLongest = 64;
  if (word.size() > kLongest) return "";
  const std::size_t limit = std::max<std::size_t>(1, word.size() / 3);
  const std::string* best = nullptr;
  std::size_t best_distance = limit + 1;
  for (const std::string& c : candidates) {
    if (c.size() > kLongest) continue;
    const std::size_t d = edit_distance(word, c);
    if (d < best_distance) {
      best = &c;
      best_distance = d;
    }
  }
  return best ? " (did you mean '" + *best + "'?)" : "";
}

std::string one_of(const std::vector<std::string>& names, std::string_view last) {
  std::string s;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) {
      if (i + 1 < names.size()) {
        s += ", ";
      } else {
        s += ' ';
        s += last;
        s += ' ';
      }
    }
    s += names[i];
  }
  return s;
}

}  // namespace ces::scene
