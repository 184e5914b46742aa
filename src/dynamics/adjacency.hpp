// Body -> contact incidence lists. Per-body sums over a body's contacts (the
// CCP scatter, the DEM force gather) run in contact order, so they give the
// same bits for any number of threads, without atomics.
#pragma once
#include <cstdint>
#include <vector>

#include "common/parallel.hpp"

namespace ces {

struct ContactAdjacency {
  // Body i's entries are entry[offset[i] .. offset[i+1]), each
  // (contact << 1 | side), side 1 when the body is the contact's B.
  std::vector<std::uint32_t> offset, entry;
  // Scratch, kept to avoid allocating every step: per share of the
  // contacts, each body's count, then where the share's entries go.
  std::vector<std::vector<std::uint32_t>> fill;

  // Lists only bodies for which listed(i) is true (e.g. finite mass).
  // A counting sort in parallel: each thread counts and places one
  // contiguous share of the contacts, the shares' entries of a body
  // following each other in share order. Each body's list is then its
  // contacts in order, the same whatever the shares.
  template <class Listed>
  void build(const std::vector<std::int32_t>& a, const std::vector<std::int32_t>& b,
             std::size_t body_count, Listed listed) {
    const std::size_t nc = a.size();
    const std::size_t shares =
        std::ptrdiff_t(nc) > kParallelMin ? std::size_t(omp_get_max_threads()) : 1;
    if (fill.size() < shares) fill.resize(shares);
    auto share = [&](std::size_t s) { return std::pair{nc * s / shares, nc * (s + 1) / shares}; };
    auto each_share = [&](auto&& fn) {
#pragma omp parallel for schedule(static, 1) if (shares > 1)
      for (std::size_t s = 0; s < shares; ++s) {
        const auto [begin, end] = share(s);
        fn(fill[s], begin, end);
      }
    };
    auto for_listed = [&](std::size_t begin, std::size_t end, auto&& fn) {
      for (std::size_t k = begin; k < end; ++k) {
        if (listed(a[k])) fn(std::size_t(a[k]), std::uint32_t(k << 1));
        if (listed(b[k])) fn(std::size_t(b[k]), std::uint32_t(k << 1 | 1));
      }
    };
    each_share([&](std::vector<std::uint32_t>& count, std::size_t begin, std::size_t end) {
      count.assign(body_count, 0);
      for_listed(begin, end, [&](std::size_t i, std::uint32_t) { ++count[i]; });
    });
    place_shares(shares, body_count);
    entry.resize(offset[body_count]);
    each_share([&](std::vector<std::uint32_t>& at, std::size_t begin, std::size_t end) {
      for_listed(begin, end, [&](std::size_t i, std::uint32_t e) { entry[at[i]++] = e; });
    });
  }

 private:
  // offset from the shares' counts, and each share's counts turned into
  // where its first entry of each body goes.
  void place_shares(std::size_t shares, std::size_t body_count) {
    offset.resize(body_count + 1);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(body_count) > kParallelMin)
    for (std::size_t i = 0; i < body_count; ++i) {
      std::uint32_t total = 0;
      for (std::size_t s = 0; s < shares; ++s) total += fill[s][i];
      offset[i] = total;
    }
    offset[body_count] = 0;
    exclusive_scan(offset);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(body_count) > kParallelMin)
    for (std::size_t i = 0; i < body_count; ++i) {
      std::uint32_t at = offset[i];
      for (std::size_t s = 0; s < shares; ++s) {
        const std::uint32_t count = fill[s][i];
        fill[s][i] = at;
        at += count;
      }
    }
  }
};

}  // namespace ces
