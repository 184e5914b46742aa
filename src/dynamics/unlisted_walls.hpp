// Walls no listed contact holds. A particle's contacts are found within an
// envelope that bounds its travel from what the step's start knows: its
// velocity, the forces, the blows of the bodies and of its neighbours
// (collision/collide.cpp). What the solve then gives it can take it
// farther: a brush's compressed bristles throw a light flake, or push a
// chain of them, through a gap no faster than it pressed them in, so
// toward a wall beyond its envelope, whose surface it would cross
// unopposed.
// Such a particle is stopped at the wall: its velocity loses what would
// carry its deepest sphere past the overlap aim, as a wall contact with no
// restitution would have taken it, friction aside. The next step lists
// the contact.
#pragma once
#include <cstddef>
#include <span>

#include "dynamics/ccp.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces {

// Stops, in B's final velocities, the awake particles whose step would
// carry them farther than their envelope, at the surfaces of the walls
// they would cross: static or kinematic bodies that do not translate and
// do not yield. Returns how many were stopped.
std::size_t stop_at_unlisted_walls(const Model& model, const Particles& p, const Bodies& bodies,
                                   std::span<const double> envelope, SolverBodies& B);

}  // namespace ces
