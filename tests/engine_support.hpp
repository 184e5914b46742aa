#pragma once
// Helpers shared by the engine tests (engine_*_test.cpp): a base model to
// build worlds on, gravity's magnitude, material names and a portable
// random sequence.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "model/model.hpp"

namespace ces::test {

inline constexpr double g0 = 9.81;

// "m0", "m1", ...: appended, not "m" + std::to_string(i), on which GCC 12
// warns falsely (-Wrestrict, GCC bug 105329).
std::string material_name(std::size_t i);

// A model with one material per entry of `frictions`, a unit sphere shape,
// and the given solver settings.
std::shared_ptr<Model> base_model(std::vector<double> frictions = {0.5}, double step = 1e-3);

// Adds a square raft of (2 half + 1)^2 unit spheres `spacing` radii apart
// to m's shapes; returns the turn that lays it flat with its face up (+y).
Quat add_raft_shape(Model& m, int half, double spacing);

// Uniform numbers in [-1, 1) from a 64-bit LCG: the same on every platform.
struct Uniform {
  std::uint64_t state;
  double operator()() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(state >> 11) * 0x1.0p-53 * 2.0 - 1.0;
  }
};

}  // namespace ces::test
