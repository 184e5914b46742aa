// Scene files in: the bad-scene suite (tests/bad_scenes/), each file's
// problems reported at their file:line, and the diagnostics' format.
#include "scene/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <functional>
#include <optional>
#include <set>

#include "scene/diagnostics.hpp"
#include "scene/resolve.hpp"
#include "scene/schema.hpp"
#include "scene_support.hpp"

namespace ces::scene {
namespace {

namespace fs = std::filesystem;

const std::string kBadSceneDir = std::string(CES_TEST_DIR) + "/bad_scenes/";

using test::all;
using test::load_errors;

// ------------------------------------------------------------------ bad scenes

struct Expected {
  const char* file;   // in tests/bad_scenes/
  const char* where;  // the file the diagnostic names (may be a fragment)
  int line;
  const char* message;  // a substring of "key.path: message"
};

const Expected kExpectations[] = {
    {"aspect_on_sphere.yaml", "aspect_on_sphere.yaml", 13,
     "feeds[0].mix[0].aspect: 'sphere' has no aspect, expected aspect only with flake or rod"},
    {"bad_enum.yaml", "bad_enum.yaml", 3,
     "solver.method: got 'apdg', expected one of apgd, spg, psor or pgs (did you mean 'apgd'?)"},
    {"bins_count_zero.yaml", "bins_count_zero.yaml", 6,
     "collectors[0].bins.count: 0 is out of range, expected >= 1"},
    {"bins_reversed.yaml", "bins_reversed.yaml", 6,
     "collectors[0].bins.to: to 0.1 m is not above from 0.4 m"},
    {"corrupt_mesh.yaml", "corrupt_mesh.yaml", 9, "bodies[0].geometry.mesh.file: cannot load mesh"},
    {"dem_modulus_not_a_pressure.yaml", "dem_modulus_not_a_pressure.yaml", 5,
     "contact.dem.youngs_modulus: '10 mm' is a length (m), expected a pressure (Pa)"},
    {"dem_poisson_out_of_range.yaml", "dem_poisson_out_of_range.yaml", 8,
     "materials.rubber.poisson_ratio: 0.5 is out of range, expected < 0.5"},
    {"dem_unknown_model.yaml", "dem_unknown_model.yaml", 3,
     "contact.model: got 'dme', expected one of dvi or dem (did you mean 'dem'?)"},
    {"flat_faces_under_dem.yaml", "flat_faces_under_dem.yaml", 3,
     "contact.flake_faces: flake_faces flat needs contact.model dvi: dem's forces are sphere on "
     "sphere"},
    {"sleep_under_dem.yaml", "sleep_under_dem.yaml", 5,
     "solver.sleep: sleep needs contact.model dvi: it reads the contact impulses"},
    {"sleep_without_time.yaml", "sleep_without_time.yaml", 4,
     "solver.sleep.time: missing required key 'time', expected a time (s), e.g. \"1 ms\""},
    {"duplicate_body.yaml", "duplicate_body.yaml", 10,
     "duplicate body name 'drum', first given at line 7"},
    {"duplicate_key.json", "duplicate_key.json", 6,
     "materials.copper: duplicate key 'copper', first given at line 5"},
    {"duplicate_key.yaml", "duplicate_key.yaml", 7,
     "materials.copper.density: duplicate key 'density', first given at line 5"},
    {"dynamic_mesh.yaml", "dynamic_mesh.yaml", 10,
     "a mesh has no volume to take a mass from, expected mass and inertia"},
    {"es_bipolar_two_electrodes.yaml", "es_bipolar_two_electrodes.yaml", 20,
     "electrostatics.field.model: bipolar is the field of exactly one electrode, the scene lists "
     "2"},
    {"es_conduction_unknown.yaml", "es_conduction_unknown.yaml", 5,
     "materials.copper: material 'copper' is fed into the separator but does not say how it "
     "conducts"},
    {"es_corona_below_onset.yaml", "es_corona_below_onset.yaml", 22,
     "electrostatics.electrodes[0].voltage: at 5 kV the wire is below its corona onset of 8.91 kV "
     "(Peek's 126 kV/cm at its surface), expected a voltage above onset"},
    {"es_corona_bipolar.yaml", "es_corona_bipolar.yaml", 22,
     "electrostatics.electrodes[0].type: a corona electrode needs the field of every electrode at "
     "the wire, expected field.model: line_charges"},
    {"es_corona_reversed.yaml", "es_corona_reversed.yaml", 23,
     "electrostatics.corona[0].to: the sector from 75 deg to 30 deg is empty or reversed"},
    {"es_corona_keys_on_static.yaml", "es_corona_keys_on_static.yaml", 23,
     "electrostatics.electrodes[0].mobility: mobility is read for a corona electrode only, "
     "expected type: corona on this electrode or no mobility"},
    {"es_corona_thick_wire.yaml", "es_corona_thick_wire.yaml", 22,
     "electrostatics.electrodes[0].radius: a corona wire of radius 5 mm does not ionise, expected "
     "a radius of at most 1 mm"},
    {"es_electrode_in_drum.yaml", "es_electrode_in_drum.yaml", 21,
     "electrostatics.electrodes[0].polar: electrode 'hv' reaches 0.131 m from the drum axis, "
     "inside the drum (radius 0.16 m)"},
    {"es_electrodes_overlap.yaml", "es_electrodes_overlap.yaml", 23,
     "electrostatics.electrodes[1]: overlaps electrode 'hv'"},
    {"es_grid_bad_row.yaml", "es_grid_bad_row.yaml", 20,
     "fields/bad_row.csv:3: z is not a finite number: 'zero'"},
    {"es_grid_missing.yaml", "es_grid_missing.yaml", 20,
     "fields/nowhere.csv: cannot open the file"},
    {"es_insulator_without_permittivity.yaml", "es_insulator_without_permittivity.yaml", 6,
     "materials.fr4: material 'fr4' is (partly) an insulator, whose corona charge needs its "
     "relative_permittivity"},
    {"es_unknown_brush.yaml", "es_unknown_brush.yaml", 20,
     "electrostatics.brush: unknown body 'brsh'"},
    {"es_unknown_drum.yaml", "es_unknown_drum.yaml", 19,
     "electrostatics.drum: unknown body 'drun' (did you mean 'drum'?)"},
    {"feed_outside_domain.yaml", "feed_outside_domain.yaml", 8,
     "feeds[0].region: the region reaches outside the domain"},
    {"feed_too_small.yaml", "feed_too_small.yaml", 8,
     "the region is 0.0005 m wide along x but the largest particles are 0.001 m across"},
    {"field_picture_without_field.yaml", "field_picture_without_field.yaml", 8,
     "output.field: the field picture needs a field, expected an electrostatics section"},
    {"fractions_sum.yaml", "fractions_sum.yaml", 11,
     "feeds[0].mix: the fractions add up to 0.9, expected 1"},
    {"geometry_two_shapes.yaml", "geometry_two_shapes.yaml", 8,
     "got 2 (box and cylinder), expected exactly one of plane, box, cylinder or mesh"},
    {"include_cycle.yaml", "fragments/cycle_b.yaml", 1, "include cycle: "},
    {"include_missing.yaml", "include_missing.yaml", 4,
     "fragments/no_such_machine.yaml': no such file"},
    {"joint_without_dynamic_body.yaml", "joint_without_dynamic_body.yaml", 11,
     "joints[0].body_b: neither body is dynamic"},
    {"json_syntax.json", "json_syntax.json", 4, "invalid JSON: syntax error"},
    {"many_errors.yaml", "many_errors.yaml", 3, "got 'apdg'"},
    {"many_errors.yaml", "many_errors.yaml", 5,
     "materials.copper.density: -1 is out of range, expected > 0 kg/m^3"},
    {"many_errors.yaml", "many_errors.yaml", 5,
     "unknown key 'restitutoin' (did you mean 'restitution'?)"},
    {"many_errors.yaml", "many_errors.yaml", 6,
     "gravity[1]: '-9.81 m/s' is a speed (m/s), expected an acceleration (m/s^2)"},
    {"material_without_density.yaml", "material_without_density.yaml", 11,
     "feeds[0].mix[0].material: material 'steel' has no density"},
    {"missing_end.yaml", "missing_end.yaml", 2,
     "time.end: missing required key 'end', expected a time (s)"},
    {"missing_mesh.yaml", "missing_mesh.yaml", 9, "bad_scenes/meshes/nowhere.stl: no such file"},
    {"missing_time.yaml", "missing_time.yaml", 1, "time: missing required key 'time'"},
    {"motion_and_dynamic.yaml", "motion_and_dynamic.yaml", 11,
     "a body with a prescribed motion cannot be dynamic"},
    {"motor_wrong_kind.yaml", "motor_wrong_kind.yaml", 15,
     "motors[0].speed: '60 rpm' does not fit a prismatic joint, expected a speed (m/s)"},
    {"negative_density.yaml", "negative_density.yaml", 4,
     "'-8960 kg/m^3' is out of range, expected > 0 kg/m^3"},
    {"negative_friction.yaml", "negative_friction.yaml", 4, "-0.1 is out of range, expected >= 0"},
    {"not_a_mapping.yaml", "not_a_mapping.yaml", 1,
     "got a list of 2 items, expected a mapping of scene keys"},
    {"outlet_oblique.yaml", "outlet_oblique.yaml", 9,
     "got an oblique normal, expected one along x, y or z"},
    {"pose_axis_and_rotation.yaml", "pose_axis_and_rotation.yaml", 11,
     "both axis and rotation given"},
    {"product_outside_bins.yaml", "product_outside_bins.yaml", 9,
     "collectors[0].products.heavy: the range leaves the bins [0, 0.4] m"},
    {"products_overlap.yaml", "products_overlap.yaml", 9,
     "collectors[0].products.heavy: overlaps product 'light'"},
    {"rate_without_unit.yaml", "rate_without_unit.yaml", 9,
     "feeds[0].rate: a number without a unit is ambiguous"},
    {"restitution_above_one.yaml", "restitution_above_one.yaml", 6,
     "1.5 is out of range, expected <= 1"},
    {"shape_file_bad_row.yaml", "shape_file_bad_row.yaml", 8,
     "shapes/bad_row.csv:4: expected a row x,y,z,r of numbers with r > 0"},
    {"shell_too_thick.yaml", "shell_too_thick.yaml", 9,
     "a wall of 0.2 m fills the radius (0.16 m)"},
    {"sieve_not_rising.yaml", "sieve_not_rising.yaml", 17,
     "size.sieve[2]: invalid sieve row: sizes must increase"},
    {"step_longer_than_end.yaml", "step_longer_than_end.yaml", 4,
     "step 1 s is longer than the run (end 0.1 s)"},
    {"unit_dimension.yaml", "unit_dimension.yaml", 8,
     "'20 g/s' is a mass rate (kg/s), expected a length (m)"},
    {"unknown_joint_body.yaml", "unknown_joint_body.yaml", 12,
     "unknown body 'padle' (did you mean 'paddle'?)"},
    {"unknown_key.yaml", "unknown_key.yaml", 4,
     "materials.copper.densty: unknown key 'densty' (did you mean 'density'?)"},
    {"unknown_material.yaml", "unknown_material.yaml", 9,
     "unknown material 'stel' (did you mean 'steel'?)"},
    {"unknown_motor_joint.yaml", "unknown_motor_joint.yaml", 14,
     "motors[0].joint: unknown joint 'hinj'"},
    {"unknown_section.yaml", "unknown_section.yaml", 6,
     "unknown key 'colectors' (did you mean 'collectors'?)"},
    {"unknown_shape.yaml", "unknown_shape.yaml", 13,
     "unknown shape 'flak' (did you mean 'flake'?)"},
    {"unknown_unit.yaml", "unknown_unit.yaml", 2,
     "'1 mss': unknown unit 'mss', expected a time (s)"},
    {"vector_length.yaml", "vector_length.yaml", 3,
     "gravity: got a list of 2 items, expected exactly 3 items"},
    {"version.yaml", "version.yaml", 1, "ces_sim: got 2, expected 1"},
    {"wrong_type.yaml", "wrong_type.yaml", 4,
     "solver.max_iterations: got 'many', expected an integer"},
    {"yaml_syntax.yaml", "yaml_syntax.yaml", 4, "invalid YAML: end of sequence flow not found"},
    {"zero_axis.yaml", "zero_axis.yaml", 10,
     "bodies[0].pose.axis: got a zero vector, expected a direction"},
    {"zero_step.yaml", "zero_step.yaml", 3, "time.step: '0 s' is out of range, expected > 0 s"},
    // Hostile input: bounds, numbers out of range, encodings, includes.
    {"alias_bomb.yaml", "alias_bomb.yaml", 4, "the scene expands to more than 200000 values"},
    {"apostrophe_key.yaml", "apostrophe_key.yaml", 3, "typo'd key: unknown key 'typo'd key'"},
    {"bins_count_huge.yaml", "bins_count_huge.yaml", 6,
     "collectors[0].bins.count: 1000000000 is out of range, expected <= 100000"},
    {"data_file_not_regular.yaml", "data_file_not_regular.yaml", 7,
     "shapes.grain.file: cannot read the shape: /dev/zero: not a regular file"},
    {"feed_mass_rate_too_high.yaml", "feed_mass_rate_too_high.yaml", 14,
     "feeds[1].rate: feed 'dust' makes about 4263"},
    {"feed_rate_too_high.yaml", "feed_rate_too_high.yaml", 9,
     "feeds[0].rate: feed 'feeder' makes about 100000000 particles over the run (all feeds "
     "100000000), expected at most 10000000 in all"},
    {"include_outside.yaml", "include_outside.yaml", 4,
     "include: '/etc/passwd' is outside the folder of include_outside.yaml"},
    {"include_outside.yaml", "include_outside.yaml", 5,
     "include: '../../../../../../../../etc/shadow' is outside the folder of include_outside.yaml"},
    {"include_outside.yaml", "include_outside.yaml", 6,
     "include: '../scenes/tiny.yaml' is outside the folder of include_outside.yaml"},
    {"integer_wraps.yaml", "integer_wraps.yaml", 3,
     "solver.max_iterations: 2147483648 is out of range, expected <= 1000000"},
    {"invalid_utf8.yaml", "invalid_utf8.yaml", 3, "invalid UTF-8 (byte 0xa1), expected UTF-8 text"},
    {"two_documents.yaml", "two_documents.yaml", 4,
     "a second YAML document (after '---' or '...'), expected one scene"},
    // At a leading ',' yaml-cpp yields empty documents at the same place
    // for ever: the load reads two at most and names the place.
    {"leading_comma.yaml", "leading_comma.yaml", 1,
     "invalid YAML: the text from here on cannot be read"},
    {"key_too_long.yaml", "key_too_long.yaml", 4, "a key path longer than 256 characters"},
    {"nesting_too_deep.yaml", "nesting_too_deep.yaml", 3, "nested deeper than 32 levels"},
    {"number_overflow.yaml", "number_overflow.yaml", 3,
     "time.end: '4e99999999999 s': number out of range"},
    {"number_underflow.yaml", "number_underflow.yaml", 3,
     "time.step: '4e-99999999999 s': number out of range"},
    {"plain_number_out_of_range.yaml", "plain_number_out_of_range.yaml", 3,
     "contact.envelope: 1e999 is out of range"},
    {"step_subnormal.yaml", "step_subnormal.yaml", 2, "time.step: '1e-320 s': number out of range"},
    {"shape_too_many_spheres.yaml", "shape_too_many_spheres.yaml", 8,
     "shapes.chain.spheres: a shape of 1001 spheres, expected at most 1000"},
    {"shape_too_wide.yaml", "shape_too_wide.yaml", 8,
     "shapes.speck.spheres: a shape 400001 times its smallest sphere's radius across, expected "
     "at most 10000 times"},
    {"shape_size_far.yaml", "shape_size_far.yaml", 9,
     "shapes.giant.size: size 1e+300 is 5e+299 times the spheres' bounding diameter, expected "
     "within a factor 10000 of it"},
    {"too_many_shapes.yaml", "too_many_shapes.yaml", 27,
     "feeds[0].mix[16].shape: a particle shape past the first 16"},
    {"too_many_materials.yaml", "too_many_materials.yaml", 3,
     "materials: 257 materials, expected at most 256"},
    {"bin_tallies.yaml", "bin_tallies.yaml", 5,
     "collectors: 100000 bins for 101 materials make 10100000 tallies, expected at most "
     "10000000 (fewer bins)"},
    {"trajectory_frames.yaml", "trajectory_frames.yaml", 4,
     "output.trajectories.every: a frame every step (0.001 s) makes 1000000 trajectory frames, "
     "expected at most 100000"},
    {"too_many_steps.yaml", "too_many_steps.yaml", 3,
     "time.step: a step of 1e-06 s makes 100000000 steps to the end (100 s), expected at most "
     "10000000"},
    {"unit_power_overflow.yaml", "unit_power_overflow.yaml", 4,
     "time.end: '4 s^99999999999': a unit power beyond 16"},
    {"unit_power_wraps.yaml", "unit_power_wraps.yaml", 7,
     "'1 km^1000000000': a unit power beyond 16"},
    {"utf8_escape_surrogate.yaml", "utf8_escape_surrogate.yaml", 3,
     "invalid YAML: invalid unicode"},
    // Scenes that load but could not do what they say.
    {"bins_outside_domain.yaml", "bins_outside_domain.yaml", 6,
     "collectors[0].bins: the bins [0.6, 0.9] m lie outside the domain"},
    {"body_outside_domain.yaml", "body_outside_domain.yaml", 12,
     "bodies[1].pose: body 'splitter' lies outside the domain"},
    {"body_outside_domain.yaml", "body_outside_domain.yaml", 16,
     "bodies[2].pose: plane 'ceiling' misses the domain"},
    {"feed_inside_body.yaml", "feed_inside_body.yaml", 14,
     "feeds[0].region: the region lies inside body 'drum', so no particle can be placed"},
    {"voltage_without_unit.yaml", "voltage_without_unit.yaml", 20,
     "electrostatics.electrodes[0].voltage: a number without a unit is ambiguous here, expected "
     "a voltage (V)"},
};

class BadScene : public ::testing::TestWithParam<std::string> {};

// Each bad scene reports each expected problem at its line, and nothing it
// does not expect.
TEST_P(BadScene, ReportsTheProblemAtItsLine) {
  const std::vector<Diagnostic> errors = load_errors(kBadSceneDir + GetParam());
  std::size_t expected = 0;
  for (const Expected& e : kExpectations) {
    if (GetParam() != e.file) continue;
    ++expected;
    const bool found = std::any_of(errors.begin(), errors.end(), [&](const Diagnostic& d) {
      return d.file == kBadSceneDir + e.where && d.line == e.line && d.column > 0 &&
             (d.path + ": " + d.message).find(e.message) != std::string::npos;
    });
    EXPECT_TRUE(found) << "expected at " << e.where << ":" << e.line << ": " << e.message
                       << "\ngot:\n"
                       << all(errors);
  }
  EXPECT_EQ(errors.size(), expected) << all(errors);
}

std::vector<std::string> bad_scene_files() {
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(kBadSceneDir))
    if (entry.is_regular_file()) files.push_back(entry.path().filename().string());
  std::sort(files.begin(), files.end());
  return files;
}

INSTANTIATE_TEST_SUITE_P(Scene, BadScene, ::testing::ValuesIn(bad_scene_files()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param;
                           std::replace_if(
                               name.begin(), name.end(), [](char c) { return !std::isalnum(c); },
                               '_');
                           return name;
                         });

TEST(SceneBadScenes, EveryFileHasExpectations) {
  const auto files = bad_scene_files();
  EXPECT_GE(files.size(), 25u);
  for (const std::string& f : files) {
    const bool listed = std::any_of(std::begin(kExpectations), std::end(kExpectations),
                                    [&](const Expected& e) { return f == e.file; });
    EXPECT_TRUE(listed) << f << " has no expectations in kExpectations";
  }
}

// ------------------------------------------------------------------ validation in pieces

// What validate() reports on the tree of `path` (read, defaulted and
// converted as a load does), checking values of more than `piece_values`
// values a piece at a time; empty when the file does not parse.
std::vector<std::string> validation_errors(const std::string& path, std::size_t piece_values) {
  Diagnostics diags;
  Budget budget;
  std::optional<Node> root = load_tree(path, {}, budget, diags);
  if (!root) return {};
  apply_defaults(*root);
  assign_paths(*root);
  convert_units(*root, diags);
  validate(*root, diags, piece_values);
  std::vector<std::string> lines;
  try {
    if (!diags.empty()) diags.raise();
  } catch (const SceneError& e) {
    for (const Diagnostic& d : e.diagnostics()) lines.push_back(d.str());
  }
  return lines;
}

// Pieces down to single values find what the whole document does, on every
// bad scene and on a scene with faults at every depth.
TEST(SceneValidation, PiecesOfAnySizeFindWhatTheWholeDocumentFinds) {
  test::TempDir dir;
  const std::string nested = dir.write(
      "nested.yaml", std::string(test::kMinimal) +
                         "seed: -1\nsolver: {method: apdg, max_iterations: 0, bogus: 1}\n"
                         "materials:\n  copper: {density: -1 kg/m^3, friction: x}\n"
                         "  glass: {densty: 1800 kg/m^3}\n"
                         "feeds:\n  - {name: f, rate: 10 /s, region: {min: [0, 0], max: [1, 1, 1]},"
                         " mix: [{shape: sphere, size: 1 mm, material: copper, fraction: 2}, 3]}\n"
                         "  - 7\ncollectors: {}\n");
  std::vector<std::string> paths{nested};
  for (const auto& entry : fs::directory_iterator(kBadSceneDir))
    if (entry.is_regular_file()) paths.push_back(entry.path().string());
  std::size_t compared = 0;
  for (const std::string& path : paths) {
    const std::vector<std::string> whole = validation_errors(path, kPieceValues);
    if (whole.empty()) continue;
    ++compared;
    for (const std::size_t piece_values : {0, 1, 3, 20})
      EXPECT_EQ(validation_errors(path, piece_values), whole)
          << path << " in pieces of " << piece_values << " values";
  }
  EXPECT_GE(compared, 30u);
  EXPECT_GE(validation_errors(nested, kPieceValues).size(), 8u);
}

// The piece-by-piece check is exact only while a value's validity is its
// own keywords' and its children's: every keyword of the schema must be one
// that keeps it so (no oneOf, anyOf, not, if, contains, uniqueItems, ...).
TEST(SceneValidation, TheSchemaUsesOnlyKeywordsThatCheckAPieceAtATime) {
  const std::set<std::string> allowed{"$schema",
                                      "$id",
                                      "$ref",
                                      "title",
                                      "description",
                                      "default",
                                      "definitions",
                                      "allOf",
                                      "type",
                                      "properties",
                                      "additionalProperties",
                                      "required",
                                      "minProperties",
                                      "maxProperties",
                                      "items",
                                      "minItems",
                                      "maxItems",
                                      "enum",
                                      "const",
                                      "pattern",
                                      "minLength",
                                      "minimum",
                                      "maximum",
                                      "exclusiveMinimum",
                                      "exclusiveMaximum"};
  std::vector<std::string> others;
  const std::function<void(const nlohmann::ordered_json&)> visit = [&](const auto& s) {
    if (!s.is_object()) return;
    for (const auto& [key, value] : s.items()) {
      if (key.starts_with("x-") || key == "default" || key == "enum" || key == "const") continue;
      if (!allowed.contains(key)) others.push_back(key);
      if (key == "properties" || key == "definitions")
        for (const auto& [name, sub] : value.items()) visit(sub);
      else if (value.is_array())
        for (const auto& sub : value) visit(sub);
      else
        visit(value);
    }
  };
  visit(schema());
  EXPECT_TRUE(others.empty()) << others.front() << " and " << others.size() - 1 << " more";
}

TEST(SceneBadScenes, DiagnosticFormat) {
  const auto errors = load_errors(kBadSceneDir + "unknown_key.yaml");
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].str(),
            kBadSceneDir +
                "unknown_key.yaml:4:12: materials.copper.densty: unknown key 'densty' "
                "(did you mean 'density'?)");
}

}  // namespace
}  // namespace ces::scene
