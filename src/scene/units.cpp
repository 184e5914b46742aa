#include "scene/units.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <numbers>
#include <optional>
#include <vector>

#include "scene/text.hpp"

namespace ces::scene::units {
namespace {

using D = Dimension;

constexpr D dim(int kg, int m, int s, int a = 0, int rad = 0) { return D{{kg, m, s, a, rad}}; }

constexpr std::array kKinds = {
    Kind{"length", "a length", "m", "0.8 mm", dim(0, 1, 0), 1e5},
    Kind{"time", "a time", "s", "1 ms", dim(0, 0, 1), 1e6},
    Kind{"mass", "a mass", "kg", "2 kg", dim(1, 0, 0), 1e9},
    Kind{"speed", "a speed", "m/s", "0.5 m/s", dim(0, 1, -1), 1e3},
    Kind{"acceleration", "an acceleration", "m/s^2", "9.81 m/s^2", dim(0, 1, -2), 1e4},
    Kind{"angle", "an angle", "rad", "30 deg", dim(0, 0, 0, 0, 1), 1e4},
    Kind{"angular_speed", "an angular speed", "rad/s", "44.8 rpm", dim(0, 0, -1, 0, 1), 1e5},
    Kind{"density", "a density", "kg/m^3", "8960 kg/m^3", dim(1, -3, 0), 1e9},
    Kind{"mass_rate", "a mass rate", "kg/s", "20 g/s", dim(1, 0, -1), 1e3},
    Kind{"count_rate", "a count rate", "1/s", "2000 /s", dim(0, 0, -1), 1e9},
    Kind{"inertia", "a moment of inertia", "kg m^2", "0.02 kg m^2", dim(1, 2, 0), 1e9},
    Kind{"force", "a force", "N", "10 N", dim(1, 1, -2), 1e9},
    Kind{"stiffness", "a stiffness", "N/m", "2 N/m", dim(1, 0, -2), 1e12},
    Kind{"torque", "a torque", "N m", "2 N m", dim(1, 2, -2), 1e9},
    Kind{"voltage", "a voltage", "V", "-35 kV", dim(1, 2, -3, -1), 1e7},
    Kind{"resistivity", "a resistivity", "ohm m", "1e12 ohm m", dim(1, 3, -3, -2), 1e30},
    Kind{"viscosity", "a dynamic viscosity", "Pa s", "1.81e-5 Pa s", dim(1, -1, -1), 1e3},
    Kind{"pressure", "a pressure", "Pa", "100 MPa", dim(1, -1, -2), 1e13},
    Kind{"electric_field", "an electric field", "V/m", "4 kV/cm", dim(1, 1, -3, -1), 1e9},
    Kind{"current_density", "a current density", "A/m^2", "1e-3 A/m^2", dim(0, -2, 0, 1), 1e4},
    Kind{"mobility", "an ion mobility", "m^2/V/s", "2.1 cm^2/V/s", dim(-1, 0, 2, 1), 1},
};

// A unit symbol. Its SI value is factor * 10^decimal: keeping powers of ten
// apart lets them be applied exactly (see parse).
struct Symbol {
  std::string_view name;
  D dimension;
  int decimal = 0;
  double factor = 1.0;
  bool takes_prefix = true;
};

constexpr double kTurn = 2.0 * std::numbers::pi;
constexpr double kDegree = std::numbers::pi / 180.0;

constexpr std::array kSymbols = {
    Symbol{"m", dim(0, 1, 0)},
    Symbol{"g", dim(1, 0, 0), -3},
    Symbol{"t", dim(1, 0, 0), 3, 1.0, false},
    Symbol{"s", dim(0, 0, 1)},
    Symbol{"min", dim(0, 0, 1), 0, 60.0, false},
    Symbol{"h", dim(0, 0, 1), 0, 3600.0, false},
    Symbol{"Hz", dim(0, 0, -1)},
    Symbol{"rpm", dim(0, 0, -1, 0, 1), 0, kTurn / 60.0, false},
    Symbol{"rev", dim(0, 0, 0, 0, 1), 0, kTurn, false},
    Symbol{"rad", dim(0, 0, 0, 0, 1)},
    Symbol{"deg", dim(0, 0, 0, 0, 1), 0, kDegree, false},
    Symbol{"\u00b0", dim(0, 0, 0, 0, 1), 0, kDegree, false},
    Symbol{"N", dim(1, 1, -2)},
    Symbol{"J", dim(1, 2, -2)},
    Symbol{"W", dim(1, 2, -3)},
    Symbol{"Pa", dim(1, -1, -2)},
    Symbol{"V", dim(1, 2, -3, -1)},
    Symbol{"A", dim(0, 0, 0, 1)},
    Symbol{"C", dim(0, 0, 1, 1)},
    Symbol{"ohm", dim(1, 2, -3, -2)},
    Symbol{"\u03a9", dim(1, 2, -3, -2)},
};

struct Prefix {
  std::string_view name;
  int decimal;
};

constexpr std::array kPrefixes = {
    Prefix{"G", 9},  Prefix{"M", 6},       Prefix{"k", 3},       Prefix{"c", -2}, Prefix{"m", -3},
    Prefix{"u", -6}, Prefix{"\u00b5", -6}, Prefix{"\u03bc", -6}, Prefix{"n", -9}, Prefix{"p", -12},
};

// Bounds that keep a unit expression's arithmetic exact and in range: no
// unit of a scene needs a power beyond 4, and no prefix chain moves the
// decimal exponent by more than a few dozen.
constexpr int kMaxPower = 16;
constexpr int kMaxDecimal = 1000;

// A unit expression's running product.
struct Scale {
  D dimension;
  int decimal = 0;
  double factor = 1.0;

  // False when a dimension's exponent or the decimal exponent leaves its
  // bound (|power| <= kMaxPower keeps every product below in int range).
  bool multiply(const Symbol& s, int power) {
    for (int i = 0; i < D::kCount; ++i) {
      dimension.exponent[i] += power * s.dimension.exponent[i];
      if (std::abs(dimension.exponent[i]) > kMaxPower) return false;
    }
    decimal += power * s.decimal;
    factor *= std::pow(s.factor, power);
    return std::abs(decimal) <= kMaxDecimal;
  }
};

std::optional<Symbol> find_symbol(std::string_view name) {
  for (const Symbol& s : kSymbols)
    if (s.name == name) return s;
  for (const Prefix& p : kPrefixes) {
    if (!name.starts_with(p.name)) continue;
    for (Symbol s : kSymbols)
      if (s.takes_prefix && s.name == name.substr(p.name.size())) {
        s.decimal += p.decimal;
        return s;
      }
  }
  return std::nullopt;
}

// Decimal exponents beyond this cannot make a finite, non-zero double
// whatever the mantissa (a scene's numbers are far shorter).
constexpr std::int64_t kMaxExponent = 100000;

// The integer in text[first, last) if all of it is one within +-limit.
std::optional<std::int64_t> read_integer(std::string_view text, std::size_t first, std::size_t last,
                                         std::int64_t limit) {
  const char* begin = text.data() + first + (first < last && text[first] == '+' ? 1 : 0);
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(begin, text.data() + last, value);
  if (ec != std::errc() || end != text.data() + last || value > limit || value < -limit)
    return std::nullopt;
  return value;
}

// The decimal number at the start of `text`: mantissa (sign and digits, no
// exponent) and exponent kept apart. Returns the length read, 0 if none;
// `exponent` is nullopt when it is out of any double's range.
std::size_t read_number(std::string_view text, std::string& mantissa,
                        std::optional<std::int64_t>& exponent) {
  std::size_t i = 0;
  if (i < text.size() && (text[i] == '-' || text[i] == '+')) ++i;
  const std::size_t int_end = skip_digits(text, i);
  std::size_t end = int_end;
  if (end < text.size() && text[end] == '.') end = skip_digits(text, end + 1);
  const bool has_digits = int_end > i || end > int_end + 1;
  if (!has_digits) return 0;
  mantissa.assign(text.substr(text[0] == '+' ? 1 : 0, end - (text[0] == '+' ? 1 : 0)));
  exponent = 0;
  if (end < text.size() && (text[end] == 'e' || text[end] == 'E')) {
    std::size_t j = end + 1;
    if (j < text.size() && (text[j] == '-' || text[j] == '+')) ++j;
    const std::size_t exp_end = skip_digits(text, j);
    if (exp_end > j) {
      exponent = read_integer(text, end + 1, exp_end, kMaxExponent);
      end = exp_end;
    }
  }
  return end;
}

bool all_zero(const std::string& mantissa) {
  return mantissa.find_first_of("123456789") == std::string::npos;
}

bool is_operator(char c) { return c == ' ' || c == '\t' || c == '/' || c == '*' || c == '^'; }

const std::string kPowerBound = "a unit power beyond " + std::to_string(kMaxPower) +
                                " (or a scaling beyond 1e" + std::to_string(kMaxDecimal) + ")";

// Parses "kg/m^3", "N m", "/s", "1/s" into a Scale.
std::variant<Scale, std::string> parse_unit(std::string_view text) {
  Scale scale;
  std::size_t i = 0;
  int sign = 1;  // -1 after '/': the next factor divides
  bool expect_factor = false;
  while (i < text.size()) {
    const char c = text[i];
    if (c == ' ' || c == '\t' || c == '*') {
      ++i;
      continue;
    }
    if (c == '/') {
      if (expect_factor) return std::string("'/' must be followed by a unit");
      sign = -1;
      expect_factor = true;
      ++i;
      continue;
    }
    std::size_t end = i;
    while (end < text.size() && !is_operator(text[end])) ++end;
    const std::string_view name = text.substr(i, end - i);
    int power = 1;
    if (end < text.size() && text[end] == '^') {
      std::size_t p = end + 1;
      if (p < text.size() && text[p] == '-') ++p;
      const std::size_t p_end = skip_digits(text, p);
      if (p_end == p) return "'^' must be followed by an integer power";
      const auto written = read_integer(text, end + 1, p_end, kMaxPower);
      if (!written) return kPowerBound;
      power = int(*written);
      end = p_end;
    }
    if (name == "1") {
      if (power != 1) return std::string("'1' cannot be raised to a power");
    } else if (auto symbol = find_symbol(name)) {
      if (!scale.multiply(*symbol, sign * power)) return kPowerBound;
    } else if (name.empty()) {
      return std::string("missing unit before '^'");
    } else {
      return "unknown unit '" + std::string(name) + "'";
    }
    sign = 1;
    expect_factor = false;
    i = end;
  }
  if (expect_factor) return std::string("'/' must be followed by a unit");
  return scale;
}

void append_power(std::string& out, std::string_view symbol, int power) {
  if (!out.empty() && out.back() != '/') out += ' ';
  out += symbol;
  if (power != 1) {
    out += '^';
    out += std::to_string(power);
  }
}

// "kg m^2/s^2": positive powers, then the negative ones after a slash.
std::string format(const Dimension& d) {
  constexpr std::array<std::string_view, D::kCount> kBase = {"kg", "m", "s", "A", "rad"};
  std::string up, down;
  for (int i = 0; i < D::kCount; ++i) {
    if (d.exponent[i] > 0) append_power(up, kBase[i], d.exponent[i]);
    if (d.exponent[i] < 0) append_power(down, kBase[i], -d.exponent[i]);
  }
  if (down.empty()) return up.empty() ? "no unit" : up;
  return (up.empty() ? "1" : up) + "/" + down;
}

const std::string kOutOfRange =
    "number out of range (in SI units a magnitude from 2.2e-308 to 1.8e308, or 0)";

}  // namespace

const Kind* find_kind(std::string_view name) {
  for (const Kind& k : kKinds)
    if (k.name == name) return &k;
  return nullptr;
}

std::variant<Quantity, std::string> parse(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  std::string mantissa;
  std::optional<std::int64_t> exponent;
  const std::size_t used = read_number(text, mantissa, exponent);
  if (used == 0) return std::string("does not start with a number");
  auto unit = parse_unit(text.substr(used));
  if (auto* error = std::get_if<std::string>(&unit)) return *error;
  const Scale& scale = std::get<Scale>(unit);
  if (!exponent) return kOutOfRange;
  // Shifting the decimal exponent and converting once rounds once, so the
  // result equals the SI value written out in decimal.
  const std::string decimal = mantissa + "e" + std::to_string(*exponent + scale.decimal);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(decimal.data(), decimal.data() + decimal.size(), value);
  if (ec != std::errc() || end != decimal.data() + decimal.size()) return kOutOfRange;
  value *= scale.factor;
  // Zero only when written as zero: an underflow is not a zero.
  if (!std::isfinite(value) || (value == 0.0 ? !all_zero(mantissa) : !std::isnormal(value)))
    return kOutOfRange;
  return Quantity{value, scale.dimension};
}

std::string describe(const Dimension& dimension) {
  for (const Kind& k : kKinds)
    if (k.dimension == dimension) return std::string(k.label) + " (" + std::string(k.si) + ")";
  if (dimension == Dimension{}) return "a plain number (no unit)";
  return format(dimension);
}

}  // namespace ces::scene::units
