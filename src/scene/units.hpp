// Quantities written with units: "0.8 mm", "44.8 rpm", "-35 kV", "20 g/s",
// "2000 /s", "8960 kg/m^3". Parsed to SI with their dimension, so a key can
// reject a value of the wrong kind ("20 g/s" given for a length).
#pragma once
#include <array>
#include <string>
#include <string_view>
#include <variant>

namespace ces::scene::units {

// Exponents of the base dimensions. Plane angle is a base dimension here (as
// in Boost.Units) so that "44.8 rpm" is not accepted as a count rate.
struct Dimension {
  enum Base { kMass, kLength, kTime, kCurrent, kAngle, kCount };
  std::array<int, kCount> exponent{};
  bool operator==(const Dimension&) const = default;
};

struct Quantity {
  double value = 0.0;  // SI
  Dimension dimension;
};

// A kind of quantity a scene key can ask for, by its name in the schema
// ("x-unit": "length").
struct Kind {
  std::string_view name;     // "mass_rate"
  std::string_view label;    // "a mass rate"
  std::string_view si;       // "kg/s"
  std::string_view example;  // "20 g/s"
  Dimension dimension;
  // The largest magnitude a scene may state, in SI. Like scene/limits.hpp's
  // bounds it sits far above any real separator, and above the values
  // users give on purpose (a plant's site coordinates, 100 km; a body
  // heavy enough not to move): a value past it is a typo or hostile input,
  // and no step the engine takes resolves it (1e12 rpm, gravity of 1e30
  // m/s^2, -1e12 kV ran to plausible-looking products).
  double largest = 0.0;
};

// nullptr for an unknown name.
const Kind* find_kind(std::string_view name);

// A number, optionally followed by a unit expression: symbols with SI
// prefixes, "^n" powers, products by space or "*", quotients by "/"
// ("kg/m^3", "N m", "/s"). Decimal scalings are applied to the decimal
// exponent before rounding, so "0.8 mm" is bit-identical to 0.0008.
// Returns the quantity, or a message saying what is wrong.
std::variant<Quantity, std::string> parse(std::string_view text);

// "a mass rate (kg/s)", or the bare unit ("kg m/s") for unnamed dimensions.
std::string describe(const Dimension& dimension);

}  // namespace ces::scene::units
