// Particles sorted along a Morton curve of cells a particle across, so that
// neighbours sit near each other in memory: the broadphase and the solver's
// passes then read their partners from the same cache lines. Part of the
// broadphase stage, every Model::reorder_interval steps.
#pragma once
#include <cstdint>
#include <vector>

#include "model/model.hpp"
#include "model/state.hpp"

namespace ces {

class SpatialOrder {
 public:
  // Permutes every particle array (by cell, then id: the order depends on
  // the state only). Below Model::reorder_min_particles it does nothing.
  void apply(const Model& model, Particles& particles);

 private:
  struct SortKey {
    std::uint64_t cell, id;
    std::uint32_t index;
  };
  std::vector<SortKey> sort_keys_;
  std::vector<std::uint32_t> order_;
  Particles scratch_;
};

}  // namespace ces
