#include "collision/broadphase.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <omp.h>

#include "common/parallel.hpp"

namespace ces {
namespace {

constexpr int kCellBits = 21;
constexpr std::int64_t kCellBias = std::int64_t{1} << (kCellBits - 1);
constexpr std::int64_t kCellMax = (std::int64_t{1} << kCellBits) - 1;
constexpr std::size_t kSortChunk = 256;  // sorted entries per task
constexpr std::size_t kBlock = 1024;  // particles per block of the pairs' placement

std::int64_t cell_coord(double x, double inv_cell) {
  const double c = std::floor(x * inv_cell);
  const double clamped = std::clamp(c, double(-kCellBias), double(kCellBias - 1));
  return std::int64_t(clamped) + kCellBias;
}

std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return (std::uint64_t(x) << (2 * kCellBits)) | (std::uint64_t(y) << kCellBits) |
         std::uint64_t(z);
}

}  // namespace

void GridBroadphase::find_pairs(const std::vector<Vec3>& centers,
                                const std::vector<double>& radii,
                                std::vector<std::pair<std::int32_t, std::int32_t>>& pairs) {
  pairs.clear();
  const std::size_t n = centers.size();
  if (n < 2) return;
  const double max_radius = *std::max_element(radii.begin(), radii.end());
  // Cells twice the largest radius: any overlapping pair sits in adjacent cells.
  place_in_cells(centers, 1.0 / (2.0 * max_radius));
  const std::size_t chunks = chunk_count(n, kSortChunk);
  if (chunk_partners_.size() < chunks) chunk_partners_.resize(chunks);  // keeps capacities
  runs_.resize(n);
  // Dense regions of the flow cost more per entry: for_each_range's chunks
  // even them out, as in collide.cpp.
  for_each_range(n, kSortChunk, true, [&](std::size_t ch, std::size_t begin, std::size_t end) {
    sweep(ch, begin, end, centers, radii);
  });
  write_pairs(pairs);
}

// Each centre's cell, and the entries sorted by it.
void GridBroadphase::place_in_cells(const std::vector<Vec3>& centers, double inv_cell) {
  const std::size_t n = centers.size();
  entries_.resize(n);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(n); ++s) {
    const Vec3& c = centers[std::size_t(s)];
    entries_[std::size_t(s)] = {pack(cell_coord(c.x(), inv_cell), cell_coord(c.y(), inv_cell),
                                     cell_coord(c.z(), inv_cell)),
                                std::int32_t(s)};
  }
  sort_entries();
}

// Each particle's run in index order: the pairs come out sorted by (i, j)
// whatever the chunks and threads. Where a block of particles' runs start
// is a prefix sum over the blocks' pair counts, so that neither pass is
// serial.
void GridBroadphase::write_pairs(std::vector<std::pair<std::int32_t, std::int32_t>>& pairs) {
  const std::size_t n = runs_.size();
  const std::size_t blocks = chunk_count(n, kBlock);
  block_first_.assign(blocks + 1, 0);
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::size_t b = 0; b < blocks; ++b) {
    std::size_t count = 0;
    for (std::size_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i)
      count += runs_[i].count;
    block_first_[b + 1] = count;
  }
  for (std::size_t b = 0; b < blocks; ++b) block_first_[b + 1] += block_first_[b];
  pairs.resize(block_first_[blocks]);
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (std::size_t b = 0; b < blocks; ++b) {
    auto* out = pairs.data() + block_first_[b];
    for (std::size_t i = b * kBlock; i < std::min(n, (b + 1) * kBlock); ++i) {
      const Run& run = runs_[i];
      const std::int32_t* partner = &chunk_partners_[run.chunk][run.begin];
      for (std::uint32_t k = 0; k < run.count; ++k) *out++ = {std::int32_t(i), partner[k]};
    }
  }
}

// By (cell, index), which no two entries share, so the order is the same
// whatever sorts them: each thread sorts a piece, and pieces are merged in
// pairs, where one thread sorting them all would keep the others waiting.
void GridBroadphase::sort_entries() {
  const auto less = [](const Entry& a, const Entry& b) {
    return a.cell != b.cell ? a.cell < b.cell : a.index < b.index;
  };
  const std::size_t n = entries_.size();
  const std::size_t pieces =
      std::ptrdiff_t(n) > 4 * kParallelMin ? std::size_t(omp_get_max_threads()) : 1;
  if (pieces == 1) {
    std::sort(entries_.begin(), entries_.end(), less);
    return;
  }
  auto bound = [&](std::size_t p) { return std::ptrdiff_t(n * std::min(p, pieces) / pieces); };
#pragma omp parallel for schedule(static, 1)
  for (std::size_t p = 0; p < pieces; ++p)
    std::sort(entries_.begin() + bound(p), entries_.begin() + bound(p + 1), less);
  sorted_.resize(n);
  for (std::size_t width = 1; width < pieces; width *= 2) {
    const auto from = entries_.begin();
    const auto to = sorted_.begin();
#pragma omp parallel for schedule(static, 1)
    for (std::size_t p = 0; p < pieces; p += 2 * width) {
      const auto lo = bound(p), mid = bound(p + width), hi = bound(p + 2 * width);
      std::merge(from + lo, from + mid, from + mid, from + hi, to + lo, less);
    }
    entries_.swap(sorted_);
  }
}

// The entries of chunk ch in sorted order, each against the nine columns
// (x, y) around its cell: z is the key's lowest field, so the cells z - 1 ..
// z + 1 of a column are one run of the sorted entries. A column's first
// cell, shifted by a fixed (dx, dy), grows with the entry's key, so nine
// cursors only move forward: no search per entry (nine binary searches of
// all entries each would cost most of the broadphase).
void GridBroadphase::sweep(std::size_t ch, std::size_t begin, std::size_t end,
                           const std::vector<Vec3>& centers, const std::vector<double>& radii) {
  constexpr std::size_t kUnset = ~std::size_t{0};
  constexpr std::size_t kWalk = 8;  // cursor steps before it searches instead
  const std::size_t n = entries_.size();
  auto& partners = chunk_partners_[ch];
  partners.clear();
  std::array<std::size_t, 9> cursor;
  cursor.fill(kUnset);
  auto seek = [&](std::size_t& c, std::uint64_t key) {
    const auto below = [](const Entry& e, std::uint64_t k) { return e.cell < k; };
    if (c == kUnset) {
      c = std::size_t(std::lower_bound(entries_.begin(), entries_.end(), key, below) -
                      entries_.begin());
      return;
    }
    for (std::size_t step = 0; step < kWalk; ++step, ++c)
      if (c == n || entries_[c].cell >= key) return;
    c = std::size_t(std::lower_bound(entries_.begin() + std::ptrdiff_t(c), entries_.end(), key,
                                     below) -
                    entries_.begin());
  };
  constexpr std::uint64_t kMask = (std::uint64_t{1} << kCellBits) - 1;
  for (std::size_t s = begin; s < end; ++s) {
    const Entry& e = entries_[s];
    const auto i = std::size_t(e.index);
    const auto cx = std::int64_t(e.cell >> (2 * kCellBits));
    const auto cy = std::int64_t((e.cell >> kCellBits) & kMask);
    const auto cz = std::int64_t(e.cell & kMask);
    const std::int64_t z_lo = std::max<std::int64_t>(cz - 1, 0);
    const std::int64_t z_hi = std::min<std::int64_t>(cz + 1, kCellMax);
    const std::size_t first = partners.size();
    for (std::size_t col = 0; col < 9; ++col) {
      const std::int64_t x = cx + std::int64_t(col / 3) - 1, y = cy + std::int64_t(col % 3) - 1;
      if (x < 0 || y < 0 || x > kCellMax || y > kCellMax) continue;
      const std::uint64_t hi = pack(x, y, z_hi);
      seek(cursor[col], pack(x, y, z_lo));
      for (std::size_t t = cursor[col]; t < n && entries_[t].cell <= hi; ++t) {
        const std::int32_t j = entries_[t].index;
        if (std::size_t(j) <= i) continue;
        const double reach = radii[i] + radii[std::size_t(j)];
        if ((centers[std::size_t(j)] - centers[i]).squaredNorm() < reach * reach)
          partners.push_back(j);
      }
    }
    std::sort(partners.begin() + std::ptrdiff_t(first), partners.end());
    runs_[i] = {std::uint32_t(ch), std::uint32_t(first), std::uint32_t(partners.size() - first)};
  }
}

}  // namespace ces
