// Collision detection: particles against particles and against machine
// bodies, in two stages (broadphase, narrowphase).
#pragma once
#include <span>
#include <vector>

#include "collision/broadphase.hpp"
#include "collision/contacts.hpp"
#include "collision/manifold.hpp"
#include "common/parallel.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces {

// A flake's plate in the world this step (FlatFace): its mid-plane's unit
// normal, its in-plane axes and its origin.
struct PlateFrame {
  Vec3 normal, x_axis, y_axis, origin;
};

// A body's pose and motion over the step (collide.cpp).
struct BodyStep;

class Collider {
 public:
  // Each particle's collision envelope for this step, and the pairs of
  // particles whose envelopes overlap.
  void broadphase(const Model& model, const Particles& particles, const Bodies& bodies);
  // Fills `out` with every pair closer than its collision envelope, in a
  // deterministic order: particle pairs by (i, j), then particle-body
  // contacts by (body, particle, sphere, feature). After broadphase().
  void narrowphase(const Model& model, const Particles& particles, const Bodies& bodies,
                   Contacts& out);
  // Each particle's envelope this step (m): its contacts with bodies were
  // listed as far as its spheres' surfaces plus it. After narrowphase().
  std::span<const double> envelopes() const { return envelope_; }

 private:
  void struck_by_body(const Model& model, const Particles& p, const Bodies& bodies, int body);
  void struck_by_neighbours(const Model& model, const Particles& p);
  void place_spheres(const Model& model, const Particles& p);
  void speed_changes(const Model& model, const Particles& p);
  void particle_pairs(const Model& model, const Particles& p, Contacts& out);
  void widen_by_kicks(const Model& model, const Particles& p, const Contacts& out);
  // The candidate contacts of particles i and j (by id, i first): sphere
  // on sphere, or a sphere on a flake's plate where the scene asks for it.
  void pair_candidates(const Model& model, const Particles& p, std::size_t i, std::size_t j,
                       double envelope, std::vector<Candidate>& candidates) const;
  void body_contacts(const Model& model, const Particles& p, const Bodies& bodies, int body,
                     Contacts& out);
  bool body_candidates(const Model& model, const Particles& p, const BodyStep& frame, int body,
                       std::size_t i, std::vector<geo::SurfaceHit>& hits,
                       std::vector<Candidate>& candidates) const;

  std::vector<std::size_t> sphere_first_;  // particle i's spheres: [first[i], first[i + 1])
  std::vector<Vec3> sphere_centre_;        // in the world, this step
  std::vector<PlateFrame> plate_frame_;    // particle i's, if a flake with flat faces
  std::vector<double> reach_, envelope_;
  // Particle i's resting envelope and bounding radius, made once a step
  // for its every pair (a cluster's smallest sphere is a search).
  std::vector<double> resting_, bounding_;
  std::vector<double> kick_;  // what impacts with neighbours can add to the travel (m)
  // For the manifold's cull (speed_changes): the largest impulses the
  // bodies together and one neighbour can give a particle this step (N s).
  std::vector<double> blow_, neighbour_blow_;
  std::vector<SpeedChange> change_;
  std::vector<std::pair<std::int32_t, std::int32_t>> pairs_;
  std::vector<OwnLine<Contacts>> chunks_;
  std::size_t used_ = 0;  // contacts written to the output so far this step
  GridBroadphase grid_;
};

}  // namespace ces
