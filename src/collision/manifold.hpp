// The manifold reduction: of one pair's candidate contacts (sphere on
// sphere, or sphere on a body's surface), the few that hold it.
#pragma once
#include <cstdint>
#include <vector>

#include "collision/contacts.hpp"
#include "common/math.hpp"
#include "model/contact_memory.hpp"
#include "model/model.hpp"

namespace ces {

// The most a particle's velocity can change within a step, besides what
// the contacts being reduced give it: at a point d from its centre, by
// linear + angular * d (m/s).
struct SpeedChange {
  double linear = 0.0, angular = 0.0;
};

// One pair's contacts before the manifold reduction, side by side: most
// are dropped (a flake on the drum keeps its hull's corners), so they go
// to Contacts' arrays only once kept.
struct Candidate {
  Vec3 normal, point;
  double gap, radius;
  ContactKey key;
};

// The motion of a pair's B side relative to its A side at the step's
// start: how far a point of B moves against A in one step.
struct PairMotion {
  Vec3 xa, va, wa, xb, vb, wb;
  double h;
  SpeedChange ca, cb;  // what each side's velocity can change by within the step
  double travel(const Vec3& p) const {
    return h * (vb + wb.cross(p - xb) - va - wa.cross(p - xa)).norm();
  }
  // The most the pair can close at p this step: the start's travel plus
  // each side's change of velocity there, over the step.
  double reach(const Vec3& p) const {
    const double a = ca.linear + ca.angular * (p - xa).norm();
    const double b = cb.linear + cb.angular * (p - xb).norm();
    return travel(p) + h * (a + b);
  }
  // How far apart the pair's candidates need be looked for: a candidate
  // whose gap is this or more is one the cull by reach (a gap above
  // `resting` plus the reach at its point) drops, wherever its point lies
  // within `bounds` (the two bounding radii) plus half the gap of both
  // centres. At most `envelopes`, the two particles' own, which are their
  // own travels: two flakes riding the drum together close far less.
  double search_envelope(double resting, double bounds, double envelopes) const;
};

// How reduce_manifold reduces a group: the scene's choice, and the overlap
// aim Manifold::Hold holds the members to.
struct Reduction {
  Manifold manifold;
  double tolerance;
};

// A flat face resting on another touches it with many of its spheres at
// once (a flake lying on the drum: 19). The corners of the face's hull hold
// it as well and cost less, so per group of nearly parallel normals a
// pair's candidates keep the deepest (it carries the overlap) and the
// hull's corners (manifold reduction, as Box2D and Jolt do it): under
// Manifold::Hold all the corners and the members those cannot hold
// (keep_unheld), under Manifold::Four three corners (keep_four). A group
// with other normals (a corner) keeps its own. The kept go to `out` in the
// candidates' order.
void reduce_manifold(const std::vector<Candidate>& c, int body_a, int body_b,
                     std::uint32_t surfaces, const PairMotion& motion, Reduction rule,
                     Contacts& out);

}  // namespace ces
