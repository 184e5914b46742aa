// Exact particle and mass bookkeeping: fed = collected + lost + active.
//
// Floating-point sums depend on their order, so three sums of doubles never
// balance exactly. Instead every particle's mass is rounded once to an
// integer number of 1e-18 kg (a 50 µm grain is ~1e8 units, so the rounding
// is far below the printed 9 digits) and the same integer is added to "fed"
// and later to exactly one of collected / lost / active. 128 bits hold any
// conceivable feed: a particle weighs from one unit to kMaxParticleMass
// (tally_holds), and a run's 1e7 particles of that sum to far below 2^128.
#pragma once
#include <cmath>
#include <cstdint>

namespace ces {

__extension__ typedef unsigned __int128 MassUnits;

inline constexpr double kMassUnit = 1e-18;  // kg

inline constexpr double kMaxParticleMass = 1e9;  // kg

// Whether one particle's mass is counted exactly: the feeds refuse others.
inline bool tally_holds(double kg) { return kg >= kMassUnit && kg <= kMaxParticleMass; }

// Rounded half away from zero, as llround, but in the 128 bits, so that a
// particle past llround's 9 kg is not wrapped.
inline MassUnits to_mass_units(double kg) { return MassUnits(std::round(kg / kMassUnit)); }
inline double to_kg(MassUnits units) { return double(units) * kMassUnit; }

struct Tally {
  std::uint64_t count = 0;
  MassUnits mass = 0;

  void add(MassUnits m) {
    ++count;
    mass += m;
  }
  Tally& operator+=(const Tally& o) {
    count += o.count;
    mass += o.mass;
    return *this;
  }
  double kg() const { return to_kg(mass); }
  bool operator==(const Tally&) const = default;
};

inline Tally operator+(Tally a, const Tally& b) { return a += b; }

}  // namespace ces
