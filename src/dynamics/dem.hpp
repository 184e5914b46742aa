// DEM baseline: Hertz-Mindlin penalty contact with viscous damping, for
// comparison with DVI on the same collision detection.
//
// Per overlapping contact (overlap d = -gap > 0, normal n from A to B):
//   normal      F_n = 4/3 E* sqrt(R* d) d - c_n v_n,   clamped to F_n >= 0
//   tangential  F_t = -S_t xi - c_t v_t,   |F_t| <= mu F_n (Coulomb)
// with S_n = 2 E* sqrt(R* d), S_t = 8 G* sqrt(R* d), c = 2 sqrt(5/6) beta
// sqrt(S m*) (the Tsuji et al. 1992 / LIGGGHTS form), xi the tangential
// displacement accumulated over the contact's life and kept per ContactKey.
// R* = Ra Rb / (Ra + Rb) (a machine body counts as flat: R* = the sphere's
// radius), 1/E* = (1-va^2)/Ea + (1-vb^2)/Eb, 1/G* = 2(2-va)(1+va)/Ea + ...,
// m* = 1 / (1/ma + 1/mb).
//
// beta: LIGGGHTS' beta(e) = ln e / sqrt(ln^2 e + pi^2) is exact for a linear
// spring but not for Hertz (with F_n >= 0 it gives e = 0.40 for 0.3, 0.63
// for 0.6, 0.902 for 0.9). With
// Tsuji damping the restitution depends on beta only, not on the impact speed
// or the materials, so beta is calibrated once per restitution value on the
// dimensionless contact equation x'' = -max(0, x^1.5 + sqrt5 beta x^.25 x').
//
// Explicit: forces from the start-of-step state, then semi-implicit Euler in
// the contact dynamics. Stable for h well below the Rayleigh time (see rayleigh_time()).
#pragma once
#include <vector>

#include "collision/contacts.hpp"
#include "dynamics/adjacency.hpp"
#include "dynamics/ccp.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces {

// Damping ratio beta (>= 0) for which a Hertz contact with Tsuji damping
// rebounds with restitution e; 0 for e >= 1. Throws std::invalid_argument
// for e <= 0 (no finite damping gives it).
double hertz_damping_for_restitution(double e);
// The restitution of that contact for damping ratio beta (the forward map).
double hertz_restitution(double beta);

// Smallest Rayleigh time pi R sqrt(rho / G) / (0.1631 nu + 0.8766) over the
// particles (R: the particle's smallest sphere); +inf without particles.
double rayleigh_time(const Model& model, const Particles& particles);

class DemContacts {
 public:
  // Adds h M^-1 (contact forces and torques) to bodies.v_free / w_free and
  // updates the tangential history `springs` (last step's, by key; part of
  // the state). `bodies` holds the start-of-step state.
  void apply(const Model& model, const Particles& particles, const Contacts& contacts, double h,
             ContactMemory& springs, SolverBodies& bodies);

 private:
  struct PairConstants {
    double e_star, g_star, r_star, m_star, beta;
  };
  PairConstants pair_constants(const Model& model, const Particles& p, const Contacts& c,
                               std::size_t k, const SolverBodies& B) const;
  void contact_force(const Model& model, const Particles& p, const Contacts& c, std::size_t k,
                     double h, const SolverBodies& B);
  void cache_damping(const Model& model, const Contacts& c);
  double damping(double e) const;

  std::vector<Vec3> force_, xi_;  // per contact: force on B (world), new history
  const ContactMemory* springs_ = nullptr;  // during apply()
  // beta per restitution value met so far, sorted by e.
  std::vector<std::pair<double, double>> damping_;
  ContactAdjacency adj_;
};

}  // namespace ces
