// The end of a run that lasts until its feed is accounted for
// (time.until: collected, spec/simulation.hpp).
#pragma once
#include <string>

#include "sim/world.hpp"

namespace ces {

// Every feed has stopped and every particle fed has been collected or lost.
bool feed_accounted_for(const World& world);

// Why a run that had to account for its feed was stopped by its time cap:
// "<file:line:col: time.end>: ... N particles (M g) still active: K on
// <body>, ..., J in flight or on other particles; expected ...".
std::string cap_message(const Simulation& sim, const World& world);

}  // namespace ces
