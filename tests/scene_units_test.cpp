// Scene files in: units (quantities to SI with their dimension, prefixes,
// bounds) and the schema (draft-07, known units, a minimal scene's
// defaults).
#include "scene/scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <set>
#include <variant>

#include "scene/units.hpp"
#include "scene_support.hpp"

namespace ces::scene {
namespace {

using test::kMinimal;
using test::TempDir;

// ------------------------------------------------------------------ units

struct UnitCase {
  const char* text;
  double si;
  const char* kind;
};

TEST(SceneUnits, ParsesToSiWithDimension) {
  const double pi = std::numbers::pi;
  const UnitCase cases[] = {
      {"0.8 mm", 0.0008, "length"},
      {"1.5e-3 km", 1.5, "length"},
      {"5 um", 5e-6, "length"},
      {"5 \u00b5m", 5e-6, "length"},
      {"12", 12.0, nullptr},
      {"1 ms", 0.001, "time"},
      {"2 min", 120.0, "time"},
      {"44.8 rpm", 44.8 * 2.0 * pi / 60.0, "angular_speed"},
      {"30 deg", 30.0 * pi / 180.0, "angle"},
      {"-35 kV", -35000.0, "voltage"},
      {"20 g/s", 0.02, "mass_rate"},
      {"3.6 t/h", 1.0, "mass_rate"},
      {"2000 /s", 2000.0, "count_rate"},
      {"2000 1/s", 2000.0, "count_rate"},
      {"50 Hz", 50.0, "count_rate"},
      {"8960 kg/m^3", 8960.0, "density"},
      {"8.96 g/cm^3", 8960.0, "density"},
      {"9.81 m/s^2", 9.81, "acceleration"},
      {"0.5 m/s", 0.5, "speed"},
      {"0.02 kg m^2", 0.02, "inertia"},
      {"2 N m", 2.0, "torque"},
      {"10 N", 10.0, "force"},
      {"1e12 ohm m", 1e12, "resistivity"},
      {"+2 kg", 2.0, "mass"},
  };
  for (const UnitCase& c : cases) {
    SCOPED_TRACE(c.text);
    const auto parsed = units::parse(c.text);
    ASSERT_TRUE(std::holds_alternative<units::Quantity>(parsed)) << std::get<std::string>(parsed);
    const auto& q = std::get<units::Quantity>(parsed);
    EXPECT_DOUBLE_EQ(q.value, c.si);
    if (c.kind)
      EXPECT_EQ(q.dimension, units::find_kind(c.kind)->dimension);
    else
      EXPECT_EQ(q.dimension, units::Dimension{});
  }
}

// Powers of ten are applied to the decimal exponent, so a value written with
// a prefix is the same double as the SI value written out.
TEST(SceneUnits, DecimalPrefixesAreExact) {
  const std::pair<const char*, double> cases[] = {
      {"0.8 mm", 0.0008}, {"0.1 mm", 1e-4},       {"1.2 mm", 0.0012},
      {"0.3 ms", 3e-4},   {"2.5 g/cm^3", 2500.0},
  };
  for (const auto& [text, si] : cases)
    EXPECT_EQ(std::get<units::Quantity>(units::parse(text)).value, si) << text;
}

TEST(SceneUnits, RejectsWhatIsNotAQuantity) {
  for (const char* text : {"mm", "5 parsecs", "5 m/", "5 ^2", "", "1 m^x"}) {
    EXPECT_TRUE(std::holds_alternative<std::string>(units::parse(text))) << text;
  }
  EXPECT_EQ(std::get<std::string>(units::parse("5 parsecs")), "unknown unit 'parsecs'");
}

// Out of a double's range, or past the bounds on powers: refused, never
// read as another number (with its exponent dropped, 4e99999 s would be 4 s).
TEST(SceneUnits, RefusesNumbersOutOfRange) {
  for (const char* text : {"4e99999999999 s", "4e-99999999999 s", "1e309 m", "1e-320 s", "1e-400",
                           "2e308", "1e-300 mm^3", "1e303 km^2"}) {
    const auto parsed = units::parse(text);
    ASSERT_TRUE(std::holds_alternative<std::string>(parsed)) << text;
    EXPECT_NE(std::get<std::string>(parsed).find("number out of range"), std::string::npos)
        << text << ": " << std::get<std::string>(parsed);
  }
  for (const char* text : {"4 s^99999999999", "1 km^1000000000", "1 m^17", "1 m^-17", "1 m^8 m^9",
                           "1 kg/g kg/g", "1 s^-99999999999999999999"}) {
    const auto parsed = units::parse(text);
    if (std::string(text) == "1 kg/g kg/g") {  // 1e6, dimensionless: within every bound
      EXPECT_EQ(std::get<units::Quantity>(parsed).value, 1e6);
      continue;
    }
    ASSERT_TRUE(std::holds_alternative<std::string>(parsed)) << text;
    EXPECT_NE(std::get<std::string>(parsed).find("a unit power beyond 16"), std::string::npos)
        << text << ": " << std::get<std::string>(parsed);
  }
  // Zero is zero however written; the largest and smallest normal doubles pass.
  EXPECT_EQ(std::get<units::Quantity>(units::parse("0e-99999 s")).value, 0.0);
  EXPECT_EQ(std::get<units::Quantity>(units::parse("1.7976931348623157e308")).value,
            1.7976931348623157e308);
  EXPECT_EQ(std::get<units::Quantity>(units::parse("2.2250738585072014e-305 mm")).value,
            2.2250738585072014e-308);
  EXPECT_EQ(std::get<units::Quantity>(units::parse("1 m^16")).dimension.exponent[1], 16);
}

// A thousand factors cancel to a plain number: bounded all the way.
TEST(SceneUnits, LongExpressionsStayBounded) {
  std::string text = "1";
  for (int i = 0; i < 1000; ++i) text += " kg/g";
  EXPECT_NE(std::get<std::string>(units::parse(text)).find("a unit power beyond 16"),
            std::string::npos);
  text = "1";
  for (int i = 0; i < 17; ++i) text += " m";
  EXPECT_TRUE(std::holds_alternative<std::string>(units::parse(text)));
}

TEST(SceneUnits, DescribesDimensions) {
  EXPECT_EQ(units::describe(units::find_kind("mass_rate")->dimension), "a mass rate (kg/s)");
  EXPECT_EQ(units::describe(std::get<units::Quantity>(units::parse("3 kg m/s")).dimension),
            "kg m/s");
}

// ------------------------------------------------------------------ schema

// Every x-unit of the schema must name a kind the units module knows.
void check_units(const nlohmann::json& s, std::set<std::string>& seen) {
  if (s.is_object()) {
    if (auto it = s.find("x-unit"); it != s.end()) {
      for (const auto& name : it->is_array() ? *it : nlohmann::json::array({*it})) {
        EXPECT_NE(units::find_kind(name.get<std::string>()), nullptr) << name;
        seen.insert(name.get<std::string>());
      }
    }
  }
  if (s.is_structured())
    for (const auto& child : s) check_units(child, seen);
}

TEST(SceneSchema, IsDraft7JsonWithKnownUnits) {
  const nlohmann::json schema = nlohmann::json::parse(schema_text());
  EXPECT_EQ(schema["$schema"], "http://json-schema.org/draft-07/schema#");
  std::set<std::string> seen;
  check_units(schema, seen);
  EXPECT_TRUE(seen.count("length") && seen.count("mass_rate") && seen.count("angular_speed"));
}

TEST(SceneSchema, MinimalSceneGetsDefaults) {
  TempDir dir;
  const Simulation sim = load(dir.write("tiny.yaml", kMinimal));
  EXPECT_EQ(sim.name, "tiny");
  EXPECT_EQ(sim.seed, 0u);
  EXPECT_EQ(sim.model->solver.method, SolverMethod::APGD);
  // The accuracy a scene without a solver section gets, not a fixed count.
  EXPECT_DOUBLE_EQ(sim.model->solver.tolerance, 3e-4);
  EXPECT_DOUBLE_EQ(sim.model->solver.penetration_tolerance, 0.1);
  EXPECT_EQ(sim.model->solver.max_iterations, 200);
  EXPECT_DOUBLE_EQ(sim.model->contact.envelope_fraction, 0.25);
  EXPECT_EQ(sim.model->contact.manifold, Manifold::Hold);
  EXPECT_EQ(sim.model->gravity, Vec3::Zero());
  EXPECT_EQ(sim.output.dir, "out");
  EXPECT_TRUE(sim.active_components.empty());
  EXPECT_NE(sim.resolved_yaml.find("warm_start: true"), std::string::npos);
}

}  // namespace
}  // namespace ces::scene
