// Body -> contact incidence lists. Per-body sums over a body's contacts (the
// CCP scatter, the DEM force gather) run in contact order, so they give the
// same bits for any number of threads, without atomics.
#pragma once
#include <cstdint>
#include <vector>

namespace ces {

struct ContactAdjacency {
  // Body i's entries are entry[offset[i] .. offset[i+1]), each
  // (contact << 1 | side), side 1 when the body is the contact's B.
  std::vector<std::uint32_t> offset, entry;
  std::vector<std::uint32_t> fill;  // scratch, kept to avoid allocating every step

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
