// Particle-particle broadphase: a uniform grid stored as a sorted cell list.
// Chosen over Bullet's btDbvtBroadphase by measurement (bench/README.md):
// particles of similar size make every cell hold O(1) particles, and a sort
// is cache friendly and deterministic.
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

#include "common/math.hpp"
#include "common/parallel.hpp"

namespace ces {

class GridBroadphase {
 public:
  // All pairs i < j with |c_i - c_j| < r_i + r_j, sorted by (i, j).
  void find_pairs(const std::vector<Vec3>& centers, const std::vector<double>& radii,
                  std::vector<std::pair<std::int32_t, std::int32_t>>& pairs);

 private:
  struct Entry {
    std::uint64_t cell;
    std::int32_t index;
  };
  // Where particle i's partners j > i are: chunk_partners_[chunk][begin ..
  // begin + count), sorted.
  struct Run {
    std::uint32_t chunk, begin, count;
  };
  void place_in_cells(const std::vector<Vec3>& centers, double inv_cell);
  void sort_entries();
  void sweep(std::size_t chunk, std::size_t begin, std::size_t end,
             const std::vector<Vec3>& centers, const std::vector<double>& radii);
  void write_pairs(std::vector<std::pair<std::int32_t, std::int32_t>>& pairs);
  std::vector<Entry> entries_;  // by cell, then index
  std::vector<Entry> sorted_;   // the merges' other buffer
  std::vector<OwnLine<std::vector<std::int32_t>>> chunk_partners_;
  std::vector<Run> runs_;
  std::vector<std::size_t> block_first_;  // the first pair of each block of particles
};

}  // namespace ces
