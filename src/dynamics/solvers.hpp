// Solvers of the cone complementarity problem (dynamics/ccp.hpp). Each
// takes x as the warm start and returns the best iterate found in it.
#pragma once
#include <array>
#include <vector>

#include "dynamics/ccp.hpp"
#include "model/model.hpp"
#include "model/stats.hpp"

namespace ces {

// A vector over the CCP's rows, kept across steps. It only grows
// (std::vector keeps its capacity), so a run stops allocating once its
// contact count peaks. take(m) gives m rows and a spare past them: the
// APGD kernel loads a contact's three rows as a four-number vector.
class RowBuffer {
 public:
  Span take(std::size_t m) {
    data_.resize(m + 1);
    return Span(data_.data(), m);
  }

 private:
  AlignedVector<double> data_;
};

// The solvers' vectors, by solver and by what it keeps in them. A run
// uses one solver; the others' stay empty.
struct SolverWorkspace {
  struct Apgd {
    // Iterates and gradients, whose roles solve_apgd passes round among
    // them instead of copying: x, x_old, the best so far, the trial x1 and
    // the next trial; gx, g_old and x1's.
    std::array<RowBuffer, 5> iterates;
    std::array<RowBuffer, 3> gradients;
  } apgd;
  struct Spg {
    RowBuffer bias;       // r, the gradient at 0
    RowBuffer gradient;   // g = N x + r
    RowBuffer direction;  // d = Π(x - alpha g) - x
    RowBuffer product;    // N d
    RowBuffer best;       // the best iterate so far
  } spg;
  struct Pgs {
    RowBuffer steps;         // per contact: its block's step
    RowBuffer gradient;      // N x + r, for the residual
    std::vector<Vec3> v, w;  // the running velocities
  } pgs;
};


SolveStats solve_apgd(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);
SolveStats solve_spg(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);
SolveStats solve_pgs(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);
// The one the settings name.
SolveStats solve(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);

}  // namespace ces
