// Body -> contact incidence lists. Per-body sums over a body's contacts (the
// CCP scatter, the DEM force gather) run in contact order, so they give the
// same bits for any number of threads, without atomics.
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

namespace ces {

struct ContactAdjacency {
  // Body i's entries are entry[offset[i] .. offset[i+1]), each
  // (contact << 1 | side), side 1 when the body is the contact's B.
  std::vector<std::uint32_t> offset, entry;
  std::vector<std::uint32_t> fill;  // scratch, kept to avoid allocating every step

  // Thread t's bodies, of `threads`, for a pass whose cost grows with a
  // body's entries: [first, last) with about the same entries plus
  // kBodyCost per body on every thread. With halves by body count one
  // thread took 61 % of ces_pcb's scatter time (perf samples), the other
  // waiting: the particles are ordered in space, and those resting in
  // piles (many contacts each) come in a run, those in flight (none) in
  // another. Shared so, 54 %. Each body's sum is its own, so the bits do
  // not depend on the split.
  static constexpr std::size_t kBodyCost = 2;
  std::pair<std::size_t, std::size_t> share(int t, int threads) const {
    const std::size_t bodies = offset.size() - 1;
    const auto weight = [&](std::size_t u) { return std::size_t(offset[u]) + kBodyCost * u; };
    const std::size_t total = weight(bodies);
    // The first body whose weight reaches a fraction q / threads of the total.
    const auto start = [&](int q) {
      if (q >= threads) return bodies;
      const std::size_t target = total * std::size_t(q) / std::size_t(threads);
      std::size_t lo = 0, hi = bodies;
      while (lo < hi) {
        const std::size_t mid = (lo + hi) / 2;
        if (weight(mid) < target) lo = mid + 1;
        else hi = mid;
      }
      return lo;
    };
    return {start(t), start(t + 1)};
  }

  // Lists only bodies for which listed(i) is true (e.g. finite mass).
  template <class Listed>
  void build(const std::vector<std::int32_t>& a, const std::vector<std::int32_t>& b,
             std::size_t body_count, Listed listed) {
    offset.assign(body_count + 1, 0);
    for (std::size_t k = 0; k < a.size(); ++k) {
      if (listed(a[k])) ++offset[std::size_t(a[k]) + 1];
      if (listed(b[k])) ++offset[std::size_t(b[k]) + 1];
    }
    for (std::size_t i = 0; i < body_count; ++i) offset[i + 1] += offset[i];
    entry.resize(offset[body_count]);
    fill.assign(offset.begin(), offset.end() - 1);
    // Contacts are visited in order, so each body's list is sorted: fixed sums.
    for (std::size_t k = 0; k < a.size(); ++k) {
      if (listed(a[k])) entry[fill[std::size_t(a[k])]++] = std::uint32_t(k << 1);
      if (listed(b[k])) entry[fill[std::size_t(b[k])]++] = std::uint32_t(k << 1 | 1);
    }
  }
};

}  // namespace ces
