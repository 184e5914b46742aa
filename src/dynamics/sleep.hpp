// Sleep: particles carried at rest by a body that turns in place.
//
// On a roll separator most particles on the drum are insulators pinned by
// their image charge, at rest in the drum's frame from where they settle
// to the brush. Their contacts with the drum and with each other are most
// of a plant-scale step's rows, and the solve finds the same answer for
// them every step. So, as bodies at rest sleep in Box2D and Jolt, a
// particle at rest on such a body sleeps, but in the body's turning frame:
//  - it falls asleep after SleepSettings::time slower than
//    SleepSettings::speed relative to the body's surface, pressed on it
//    (a normal impulse this step) and held there by its forces with half
//    its friction to spare (held(), below);
//  - asleep, it moves rigidly with its carrier (from the body's poses, so
//    it neither drifts nor sags), has infinite mass in the solve, and has
//    no contacts with its carrier or with other sleepers; awake neighbours
//    still touch it;
//  - it wakes when the force its carrier must give it to keep it on its
//    circle (against its weight, its electric force, the pushes of its
//    neighbours, and the centripetal force) would pull it off or take more
//    than half the friction: a conductor whose image charge is gone, a
//    flake turned past where its weight slides it, a neighbour's glancing
//    blow. It also wakes within reach of another body (the brush).
// Half the friction is kept in reserve so that a particle wakes before its
// forces could move it: the awake solve decides whether and when it slips.
// A push is the neighbour's contact impulse over the step, as it acts on
// the sleeper: infinite mass takes a blow as a wall does, which for a
// blow the particle could have yielded to is an upper bound.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "collision/contacts.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces {

class Sleep {
 public:
  // Start of a step: wakes the sleepers within reach of a body other than
  // their carrier, before the contacts are found.
  void wake_near_bodies(const Model& model, const Bodies& bodies, Particles& p);
  // End of a step: moves the sleepers with their carriers, from the
  // bodies' poses `before` to their current ones, at their velocity there.
  static void carry(const std::vector<Pose>& before, const Bodies& bodies, Particles& p);
  // End of a step, from its contacts and their world impulses (on body B):
  // wakes the sleepers no longer held, puts to sleep those at rest long
  // enough. Returns how many sleep.
  std::size_t update(const Model& model, const Bodies& bodies, const Contacts& contacts,
                     const std::vector<Vec3>& impulses, Particles& p);

 private:
  void read_contacts(const Contacts& contacts, const std::vector<Vec3>& impulses,
                     std::size_t np);
  bool held(const Model& model, const Bodies& bodies, const Particles& p, std::size_t i,
            std::size_t body) const;
  // update() for particle i: whether it sleeps after it.
  bool update_one(const Model& model, const Bodies& bodies, Particles& p, std::size_t i) const;

  // Per particle, this step: the body pressing it (-1: none, -2: several),
  // and the sum of its neighbours' impulses on it, in fixed point
  // (kPushUnit) so that the sum is the same in any order.
  std::vector<std::int32_t> pressed_by_;
  std::vector<std::array<std::int64_t, 3>> push_;
  std::vector<std::vector<std::array<std::int64_t, 3>>> more_push_;  // threads' but the first's
  std::vector<geo::Aabb> bounds_;  // per body: its shape's local bounds
};

}  // namespace ces
