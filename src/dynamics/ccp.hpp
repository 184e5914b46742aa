// The cone complementarity problem of one time step (DESIGN.md §4):
//   find gamma in K with  N gamma + r in K°,  gamma ⟂ N gamma + r,
// N = D^T M^-1 D, r = D^T v_free + b. It is the optimality condition of
//   min f(gamma) = 1/2 gamma^T N gamma + r^T gamma  over K,
// K the product of friction cones (3 rows per contact) and of intervals
// (bilateral rows: unbounded, or bounded for motors).
//
// N is never formed: N x is "scatter impulses into body velocities, gather
// constraint velocities". Scatter runs per body over a body->contact adjacency
// list and gather per contact, so every sum has a fixed order and the result
// is bitwise the same for any number of threads.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "collision/contacts.hpp"
#include "common/math.hpp"
#include "dynamics/adjacency.hpp"
#include "dynamics/model.hpp"

namespace ces {

using Eigen::VectorXd;

// Bodies as the solver sees them: particles, then machine bodies.
struct SolverBodies {
  std::vector<Vec3> x;               // centre of mass (lever arms)
  std::vector<Vec3> v, w;            // velocities at the start of the step
  std::vector<Vec3> v_free, w_free;  // after external forces, before contacts
  std::vector<double> inv_mass;      // 0 for static and kinematic bodies
  std::vector<Mat3> inv_inertia;     // world frame
  void resize(std::size_t n);
};

// One bilateral row: J v + bias = 0 with impulse in [lo, hi].
struct BilateralRow {
  int a = -1, b = -1;  // solver body indices, -1: the ground
  Vec3 lin_a = Vec3::Zero(), ang_a = Vec3::Zero(), lin_b = Vec3::Zero(), ang_b = Vec3::Zero();
  double bias = 0.0;
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
};

struct SolveStats {
  int iterations = 0;
  double residual = 0.0;      // RMS over rows of the projected-gradient residual (m/s)
  double residual_max = 0.0;  // its largest row (m/s)
  bool converged = false;
};

class CcpProblem {
 public:
  // Builds the problem for this step. `rows` are the joints' and motors' rows.
  void assemble(const Contacts& contacts, const SolverBodies& bodies,
                std::vector<BilateralRow> rows, double h, const ContactSettings& settings);

  std::size_t contact_count() const { return a_.size(); }
  std::size_t row_count() const { return 3 * a_.size() + rows_.size(); }

  // g = N x + r = J (v_free + M^-1 J^T x) + b.
  void gradient(const VectorXd& x, VectorXd& g) const;
  // y = N x.
  void multiply(const VectorXd& x, VectorXd& y) const;
  void project(VectorXd& x) const;
  // Projected-gradient residual (x - Π(x - s g)) / s, s = 1 / max diag N.
  void residual(const VectorXd& x, const VectorXd& g, double& rms, double& max) const;
  // Upper bound on the largest eigenvalue of N (Gershgorin-like, cheap).
  double diagonal_max() const { return diag_max_; }

  // Final velocities v_free + M^-1 J^T x.
  void velocities(const VectorXd& x, std::vector<Vec3>& v, std::vector<Vec3>& w) const;

  // Contact impulses as world vectors (normal + friction), for warm starts:
  // a world vector survives the rotation of the tangent frame between steps.
  void world_impulses(const VectorXd& x, std::vector<Vec3>& out) const;
  // Initial guess: each contact's previous world impulse (matched by key;
  // prev_keys sorted) re-expressed in its new frame; bilateral rows
  // keep their previous values.
  void warm_start(const std::vector<ContactKey>& keys, const std::vector<ContactKey>& prev_keys,
                  const std::vector<Vec3>& prev_impulse, const VectorXd& prev_x,
                  VectorXd& x) const;

  // Projected Gauss-Seidel sweeps, in place (needs row access).
  SolveStats solve_pgs(VectorXd& x, const SolverSettings& s) const;

 private:
  // dv = M^-1 J^T x (+ v_free); y = J v (+ b).
  void scatter(const VectorXd& x, bool add_free, std::vector<Vec3>& dv, std::vector<Vec3>& dw) const;
  void gather(const std::vector<Vec3>& v, const std::vector<Vec3>& w, bool add_bias, VectorXd& y) const;

  const SolverBodies* bodies_ = nullptr;
  // Contacts, structure of arrays.
  std::vector<std::int32_t> a_, b_;
  std::vector<Vec3> n_, t1_, t2_, ra_, rb_;
  std::vector<double> mu_, bias_, diag_;
  std::vector<BilateralRow> rows_;
  std::vector<double> row_diag_;
  ContactAdjacency adj_;  // bodies with finite mass
  double diag_max_ = 1.0;
  mutable std::vector<Vec3> dv_, dw_, impulse_;
  mutable std::vector<double> partial_sum_, partial_max_;
};

SolveStats solve_apgd(const CcpProblem& p, const SolverSettings& s, VectorXd& x);
SolveStats solve_spg(const CcpProblem& p, const SolverSettings& s, VectorXd& x);
SolveStats solve(const CcpProblem& p, const SolverSettings& s, VectorXd& x);

// Projection of (gn, gt1, gt2) onto the cone |gt| <= mu gn. Inline: it runs
// twice per contact per iteration.
inline void project_cone(double mu, double& gn, double& gt1, double& gt2) {
  if (mu <= 0.0) {  // frictionless: a half-line
    gn = std::max(gn, 0.0);
    gt1 = gt2 = 0.0;
    return;
  }
  // Plain sqrt, not std::hypot: impulses cannot overflow, and hypot's
  // careful scaling made it a quarter of the solve time.
  const double s = std::sqrt(gt1 * gt1 + gt2 * gt2);
  if (s <= mu * gn) return;  // inside the cone
  if (mu * s <= -gn) {       // inside the polar cone: the apex
    gn = gt1 = gt2 = 0.0;
    return;
  }
  const double n = (mu * s + gn) / (mu * mu + 1.0);
  const double scale = mu * n / s;
  gn = n;
  gt1 *= scale;
  gt2 *= scale;
}

}  // namespace ces
