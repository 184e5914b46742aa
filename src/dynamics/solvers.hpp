// Solvers of the cone complementarity problem (dynamics/ccp.hpp). Each
// takes x as the warm start and returns the best iterate found in it.
#pragma once
#include "dynamics/ccp.hpp"
#include "model/model.hpp"
#include "model/stats.hpp"

namespace ces {

SolveStats solve_apgd(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);
SolveStats solve_spg(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);
SolveStats solve_pgs(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);
// The one the settings name.
SolveStats solve(const CcpProblem& p, const SolverSettings& s, Span x, SolverWorkspace& ws);

}  // namespace ces
