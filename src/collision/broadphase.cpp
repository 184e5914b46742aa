#include "collision/broadphase.hpp"

#include <algorithm>
#include <cmath>

namespace ces {
namespace {

constexpr int kCellBits = 21;
constexpr std::int64_t kCellBias = std::int64_t{1} << (kCellBits - 1);
constexpr std::int64_t kCellMax = (std::int64_t{1} << kCellBits) - 1;
constexpr std::size_t kChunk = 256;  // fixed, so output order never depends on threads

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
  const double inv_cell = 1.0 / (2.0 * max_radius);

  entries_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& c = centers[i];
    entries_[i] = {pack(cell_coord(c.x(), inv_cell), cell_coord(c.y(), inv_cell),
                        cell_coord(c.z(), inv_cell)),
                   std::int32_t(i)};
  }
  std::sort(entries_.begin(), entries_.end(), [](const Entry& a, const Entry& b) {
    return a.cell != b.cell ? a.cell < b.cell : a.index < b.index;
  });

  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  chunk_pairs_.resize(chunks);
#pragma omp parallel for schedule(static) if (chunks > 1)
  for (std::size_t ch = 0; ch < chunks; ++ch) {
    auto& out = chunk_pairs_[ch];
    out.clear();
    const std::size_t end = std::min(n, (ch + 1) * kChunk);
    for (std::size_t i = ch * kChunk; i < end; ++i) {
      const Vec3& c = centers[i];
      const std::int64_t cx = cell_coord(c.x(), inv_cell), cy = cell_coord(c.y(), inv_cell),
                         cz = cell_coord(c.z(), inv_cell);
      const std::size_t first = out.size();
      // z is the key's lowest field, so the three cells z - 1 .. z + 1 of a
      // column (x, y) are one run of the sorted entries: one search a column.
      const std::int64_t z_lo = std::max<std::int64_t>(cz - 1, 0);
      const std::int64_t z_hi = std::min<std::int64_t>(cz + 1, kCellMax);
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          const std::int64_t x = cx + dx, y = cy + dy;
          if (x < 0 || y < 0 || x > kCellMax || y > kCellMax) continue;
          const std::uint64_t lo = pack(x, y, z_lo), hi = pack(x, y, z_hi);
          auto it = std::lower_bound(entries_.begin(), entries_.end(), lo,
                                     [](const Entry& e, std::uint64_t k) { return e.cell < k; });
          for (; it != entries_.end() && it->cell <= hi; ++it) {
            const std::int32_t j = it->index;
            if (std::size_t(j) <= i) continue;
            const double reach = radii[i] + radii[std::size_t(j)];
            if ((centers[std::size_t(j)] - c).squaredNorm() < reach * reach)
              out.emplace_back(std::int32_t(i), j);
          }
        }
      std::sort(out.begin() + std::ptrdiff_t(first), out.end());
    }
  }
  for (const auto& part : chunk_pairs_) pairs.insert(pairs.end(), part.begin(), part.end());
}

}  // namespace ces
