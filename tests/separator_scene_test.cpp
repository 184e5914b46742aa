// The separator from a scene file, end to end: the scene keys
// compile to the field model, charging zones, electrical materials, drag
// and particle shapes; the runner installs only what a scene asks for; the
// field picture is the field model's; a short feed of the reference machine
// separates copper from FR-4 with an exact balance; and the published
// trends of docs/validation.md hold in short: drum speed, voltage, particle
// size, and the copper landing widening with the feed rate (the seed's
// Figure 10).
//
// Scenes run in-process on one thread, so two tests under ctest -j2 do not
// fight over the two cores.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "feed/shapes.hpp"
#include "fields/charge.hpp"
#include "fields/corona.hpp"
#include "scene/scene.hpp"
#include "sim/run.hpp"
#include "support.hpp"

namespace ces {
namespace {

namespace fs = std::filesystem;
using test::fresh_dir;
using test::read_text;

const std::string kScenes = std::string(CES_SOURCE_DIR) + "/scenes/";
constexpr double kDeg = std::numbers::pi / 180.0;

bool has(const std::vector<std::string>& list, const std::string& item) {
  return std::find(list.begin(), list.end(), item) != list.end();
}

// Loads a scene with overrides, on one thread; includes may come from
// scenes/ (the reference machine).
Simulation load(const std::string& scene,
                const std::vector<std::pair<std::string, std::string>>& overrides = {}) {
  scene::LoadOptions options;
  options.overrides = overrides;
  options.threads = 1;
  options.include_paths = {kScenes};
  return scene::load(scene, options);
}

fs::path run_scene(const Simulation& sim, const std::string& name) {
  const fs::path dir = fresh_dir(name);
  const RunResult result = run(sim, {dir.string(), false, true});
  EXPECT_TRUE(result.complete) << result.reason;
  return dir;
}

// A CSV file as rows of fields, header included.
std::vector<std::vector<std::string>> read_csv(const fs::path& path) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(read_text(path));
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> fields;
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) fields.push_back(cell);
    if (!line.empty() && line.back() == ',') fields.emplace_back();
    rows.push_back(fields);
  }
  return rows;
}

// ------------------------------------------------------------------ compile

TEST(SeparatorScene, ReferenceMachineCompiles) {
  const Simulation sim = load(kScenes + "ces_pcb.yaml");
  ASSERT_TRUE(sim.electrostatics);
  const fields::ElectrostaticsSpec& es = *sim.electrostatics;
  EXPECT_TRUE(std::holds_alternative<fields::LineChargeField>(es.field));
  EXPECT_EQ(es.drum.radius, 0.16);
  EXPECT_EQ(es.drum.half_width, 0.15);
  EXPECT_EQ(sim.model->bodies[std::size_t(es.drum_body)].name, "drum");
  ASSERT_TRUE(es.brush_body);
  EXPECT_EQ(sim.model->bodies[std::size_t(*es.brush_body)].name, "brush");
  ASSERT_EQ(sim.electrodes.size(), 2u);
  const fields::Electrode& e = sim.electrodes[0].electrode;
  EXPECT_NEAR(e.centre.x(), 0.267 * std::cos(30 * kDeg), 1e-15);
  EXPECT_NEAR(e.centre.y(), 0.267 * std::sin(30 * kDeg), 1e-15);
  EXPECT_EQ(e.radius, 0.019);
  EXPECT_EQ(e.potential, -35000.0);
  // The corona wire: no hand-set sector, its band 50 mm under it, 15 deg
  // past the top, at Peek's onset for a 0.1 mm wire (docs/physics.md §4).
  EXPECT_TRUE(es.corona.empty());
  ASSERT_EQ(es.bands.size(), 1u);
  const fields::CoronaBand& b = es.bands[0];
  EXPECT_NEAR(b.foot_angle, 75 * kDeg, 1e-12);
  EXPECT_NEAR(b.height, 0.0501, 1e-9);
  EXPECT_NEAR(b.onset_field, fields::peek_onset_field(1e-4), 1e-6);
  // docs/physics.md §4.2: 8.5 kV for the wire alone, 10.9 kV at 60° beside
  // the static electrode at 30°, which shields it; at 75° it shields less.
  EXPECT_GT(b.onset_voltage, 8.5e3);
  EXPECT_LT(b.onset_voltage, 10.9e3);
  EXPECT_DOUBLE_EQ(b.current, fields::townsend_current(-35e3, b.onset_voltage, 1e-4, b.height, 2.1e-4));
  EXPECT_EQ(b.ion_sign, -1.0);
  EXPECT_DOUBLE_EQ(es.medium_relative_permittivity, 1.0006);
  ASSERT_TRUE(sim.drag);
  EXPECT_EQ(sim.drag->law, fields::DragLaw::SchillerNaumann);
  EXPECT_EQ(sim.drag->air.viscosity, 1.81e-5);
  for (const char* c : {"drag", "electrostatics", "corona_charging", "brush", "clusters"})
    EXPECT_TRUE(has(sim.active_components, c)) << c;
}

TEST(SeparatorScene, MaterialsSayHowTheyConduct) {
  const Simulation sim = load(kScenes + "ces_pcb.yaml");
  const auto& names = sim.model->materials.materials();
  for (std::size_t m = 0; m < names.size(); ++m) {
    const fields::ElectricalMaterial& e = sim.electrostatics->materials[m];
    if (names[m].name == "copper") {
      EXPECT_EQ(e.metal_fraction, 1.0);
    }
    if (names[m].name != "fr4") continue;
    EXPECT_EQ(e.metal_fraction, 0.0);
    EXPECT_EQ(e.relative_permittivity, 4.4);
    // From the resistivity: eps0 epsr rho = 39 s (docs/physics.md §5).
    EXPECT_NEAR(e.decay_time, fields::relaxation_time(4.4, 1e12), 1e-12);
    EXPECT_NEAR(e.decay_time, 38.96, 0.01);
  }
}

// A scene without air and electrodes builds neither (docs/architecture.md).
TEST(SeparatorScene, AbsentSectionsBuildNothing) {
  const Simulation sim = load(kScenes + "default.yaml");
  EXPECT_FALSE(sim.drag);
  EXPECT_FALSE(sim.electrostatics);
  EXPECT_TRUE(sim.electrodes.empty());
  for (const char* c : {"drag", "electrostatics", "corona_charging", "brush"})
    EXPECT_FALSE(has(sim.active_components, c)) << c;
}

TEST(SeparatorScene, MetalFractionAndLineCharges) {
  const fs::path dir = fresh_dir("mixed");
  std::ofstream(dir / "mixed.yaml") << "ces_sim: 1\n"
                                       "include: "
                                    << kScenes
                                    << "machines/ces_machine.yaml\n"
                                       "time: {step: 1 ms, end: 1 ms}\n"
                                       "materials:\n"
                                       "  pcb: {density: 2500, metal_fraction: 0.3,\n"
                                       "        relative_permittivity: 4.4,\n"
                                       "        charge_decay_time: 20 s}\n"
                                       "electrostatics:\n"
                                       "  field: {model: line_charges}\n"
                                       "  electrodes:\n"
                                       "    - {name: wire2, position: [0.1 m, 0.2 m],\n"
                                       "       radius: 0.1 mm, voltage: -30 kV}\n"
                                       "feeds:\n"
                                       "  - name: f\n"
                                       "    region: {box: {min: [-0.01, 0.17, -0.01],\n"
                                       "                   max: [0.01, 0.18, 0.01]}}\n"
                                       "    rate: 10 /s\n"
                                       "    mix: [{material: pcb, size: {constant: 1 mm}}]\n";
  const Simulation sim = load((dir / "mixed.yaml").string());
  const auto* lines = std::get_if<fields::LineChargeField>(&sim.electrostatics->field);
  ASSERT_NE(lines, nullptr);
  EXPECT_EQ(lines->electrodes().size(), 3u);  // the machine's electrode and wire, and this wire
  const auto& materials = sim.model->materials.materials();
  const auto pcb = std::find_if(materials.begin(), materials.end(),
                                [](const Material& m) { return m.name == "pcb"; });
  const fields::ElectricalMaterial& e =
      sim.electrostatics->materials[std::size_t(pcb - materials.begin())];
  EXPECT_EQ(e.metal_fraction, 0.3);
  EXPECT_EQ(e.decay_time, 20.0);
}

// ------------------------------------------------------------------ shapes

TEST(SeparatorScene, BuiltInFlakeIsAContiguousDiscLayer) {
  const feed::SphereList flake = feed::flake_spheres(0.2);
  ASSERT_EQ(flake.centers.size(), 19u);
  double reach = 0.0, nearest = 1.0;
  for (std::size_t i = 0; i < flake.centers.size(); ++i) {
    EXPECT_EQ(flake.radii[i], 0.1);
    EXPECT_EQ(flake.centers[i].z(), 0.0);
    reach = std::max(reach, flake.centers[i].norm() + flake.radii[i]);
    for (std::size_t j = 0; j < i; ++j)
      nearest = std::min(nearest, (flake.centers[i] - flake.centers[j]).norm());
  }
  EXPECT_NEAR(reach, 0.5, 1e-12);   // width 1
  EXPECT_LE(nearest, 0.2 + 1e-12);  // neighbours touch: no gaps
  EXPECT_EQ(feed::flake_spheres(0.1).centers.size(), 91u);
  EXPECT_EQ(feed::flake_spheres(1.0).centers.size(), 1u);
}

TEST(SeparatorScene, BuiltInRodOverlapsByHalfARadius) {
  const feed::SphereList rod = feed::rod_spheres(0.25);
  ASSERT_EQ(rod.centers.size(), 7u);
  EXPECT_NEAR(rod.centers.front().x(), -0.375, 1e-12);
  EXPECT_NEAR(rod.centers.back().x(), 0.375, 1e-12);
  for (std::size_t i = 1; i < rod.centers.size(); ++i)
    EXPECT_LE(rod.centers[i].x() - rod.centers[i - 1].x(), 0.125 + 1e-12);
}

// Sizes of built-ins are equal-volume diameters: a flake's mass is that of
// the sphere of its size, and it is 1.87 sizes across at aspect 0.2.
TEST(SeparatorScene, FeedShapesFromTheScene) {
  const fs::path dir = fresh_dir("shapes");
  std::ofstream(dir / "nugget.csv") << "# two spheres\nx,y,z,r\n0,0,0,0.5\n0.5,0,0,0.5\n";
  std::ofstream(dir / "shapes.yaml")
      << "ces_sim: 1\ntime: {step: 1 ms, end: 1 ms}\n"
         "materials: {cu: {density: 8960}}\n"
         "shapes: {nugget: {file: nugget.csv}}\n"
         "feeds:\n"
         "  - name: f\n"
         "    region: {box: {min: [-0.02, 0, -0.02], max: [0.02, 0.01, 0.02]}}\n"
         "    rate: 10 /s\n"
         "    mix:\n"
         "      - {material: cu, fraction: 0.25, size: {constant: 1 mm}, shape: flake}\n"
         "      - {material: cu, fraction: 0.25, size: {constant: 1 mm}, shape: rod,\n"
         "         aspect: 0.5}\n"
         "      - {material: cu, fraction: 0.25, size: {constant: 1 mm}, shape: nugget}\n"
         "      - {material: cu, fraction: 0.25, size: {constant: 1 mm}}\n";
  const Simulation sim = load((dir / "shapes.yaml").string());
  const auto& mix = sim.feeds[0].mix;
  const auto shape = [&](int c) {
    return sim.model->shapes[std::size_t(mix[std::size_t(c)].shape)];
  };
  EXPECT_EQ(shape(0).centers.size(), 19u);
  const double d = mix[0].shape_size;
  EXPECT_NEAR(std::numbers::pi / 6 * d * d * d, shape(0).volume, 1e-12);
  // 19 touching spheres of radius r, a centre and two hexagonal rings:
  // bounding radius 5 r, equal-volume diameter 2 r 19^(1/3) (1e-5: the
  // union's volume is integrated numerically).
  EXPECT_NEAR(2.0 * shape(0).bounding_radius / d, 5.0 / std::cbrt(19.0), 1e-5);
  EXPECT_EQ(shape(1).centers.size(), 3u);  // aspect 0.5: spheres at -0.25, 0, 0.25
  EXPECT_EQ(shape(2).centers.size(), 2u);
  EXPECT_NEAR(mix[2].shape_size, 1.5, 1e-6);  // a file's cluster: its bounding diameter
  EXPECT_EQ(mix[3].shape_size, 1.0);          // the unit sphere
}

// ------------------------------------------------------------------ field picture

// field.csv holds the field model's values at the grid nodes, to its 9
// printed digits; phi is 0 in the drum and U in the electrode.
TEST(SeparatorScene, FieldCsvIsTheFieldModel) {
  const Simulation sim =
      load(kScenes + "ces_pcb.yaml",
           {{"feeds.nozzle.start", "1 s"}, {"time.until", "end"}, {"time.end", "1 ms"}});
  const fs::path dir = run_scene(sim, "field");
  const auto rows = read_csv(dir / "field.csv");
  ASSERT_GT(rows.size(), 1000u);
  EXPECT_EQ(rows[0],
            (std::vector<std::string>{"x_m", "y_m", "ex_vpm", "ey_vpm", "e_vpm", "phi_v"}));
  const auto& model = std::get<fields::LineChargeField>(sim.electrostatics->field);
  double phi_min = 0.0, phi_max = -1e9;
  for (std::size_t k = 1; k < rows.size(); ++k) {
    ASSERT_EQ(rows[k].size(), 6u);
    phi_min = std::min(phi_min, std::stod(rows[k][5]));
    phi_max = std::max(phi_max, std::stod(rows[k][5]));
  }
  for (std::size_t k = 1; k < rows.size(); k += 37) {
    const auto& r = rows[k];
    const Vec3 p(std::stod(r[0]), std::stod(r[1]), 0.0);
    const Vec3 e = model.field(p);
    const double tol = 1e-8 * e.norm() + 1e-9;
    EXPECT_NEAR(std::stod(r[2]), e.x(), tol) << r[0] << "," << r[1];
    EXPECT_NEAR(std::stod(r[3]), e.y(), tol);
    EXPECT_NEAR(std::stod(r[4]), e.norm(), tol);
    EXPECT_NEAR(std::stod(r[5]), model.potential(p), 1e-8 * 35000);
  }
  EXPECT_NEAR(phi_max, 0.0, 1e-6);  // in the drum (0 there; a rounding above just outside)
  // Down to the electrodes' potential; the line charges overshoot it by a
  // few kV just outside the thin wire (docs/physics.md §3.2).
  EXPECT_LE(phi_min, -35000.0 + 1e-3);
  const std::string svg = read_text(dir / "field.svg");
  EXPECT_TRUE(svg.starts_with("<?xml"));
  EXPECT_NE(svg.find("|E| (kV/cm)"), std::string::npos);
  EXPECT_NE(svg.find("electrode, -35 kV"), std::string::npos);
  EXPECT_EQ(svg.find("nan"), std::string::npos);
}

// ------------------------------------------------------------------ the machine at work

struct Landing {
  std::string material, product;
  double along = 0.0, mass = 0.0, charge = 0.0;
};

std::vector<Landing> landings(const fs::path& dir) {
  const auto rows = read_csv(dir / "crossings.csv");
  const auto& h = rows.at(0);
  const auto col = [&](const char* name) {
    return std::size_t(std::find(h.begin(), h.end(), name) - h.begin());
  };
  std::vector<Landing> out;
  for (std::size_t k = 1; k < rows.size(); ++k)
    out.push_back({rows[k][col("material")], rows[k][col("product")],
                   std::stod(rows[k][col("along_m")]), std::stod(rows[k][col("mass_kg")]),
                   std::stod(rows[k][col("charge_c")])});
  return out;
}

double mass(const std::vector<Landing>& all, const std::string& material,
            const std::string& product = "") {
  double m = 0.0;
  for (const Landing& l : all)
    if (l.material == material && (product.empty() || l.product == product)) m += l.mass;
  return m;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

std::vector<double> positions(const std::vector<Landing>& all, const std::string& material) {
  std::vector<double> x;
  for (const Landing& l : all)
    if (l.material == material) x.push_back(l.along);
  return x;
}

// 0.1 s of the reference scene's feed (about 170 flakes), run as the
// scene runs, until every particle fed is collected or lost. Thresholds
// (the test prints what it measures; the whole 1 s feed in
// docs/validation.md):
//  - every particle accounted for: the run completes, none active;
//  - copper: at least 90 % of it in the conductor product, whose
//    copper grade is at least 85 % (FR-4 flakes too thick for their image
//    pull to hold them fly beyond splitter 2's edge); none in the
//    non-conductor product;
//  - FR-4: at least 60 % of it in the non-conductor product, at most 10 %
//    in the conductor product; at least half of what reaches the
//    non-conductor product brushed off the drum (charge 0): the rest
//    leaves the drum under its front, charged.
TEST(SeparatorScene, ShortFeedSeparatesCopperFromFr4) {
  const Simulation sim = load(kScenes + "ces_pcb.yaml", {{"feeds.nozzle.duration", "0.1 s"}});
  const fs::path dir = run_scene(sim, "short_feed");
  const auto summary = nlohmann::json::parse(read_text(dir / "summary.json"));
  EXPECT_TRUE(summary["balance"]["exact"].get<bool>());
  const int fed = summary["balance"]["fed"]["count"];
  EXPECT_GT(fed, 120);
  EXPECT_EQ(summary["balance"]["active"]["count"].get<int>(), 0);
  const std::vector<Landing> all = landings(dir);
  const double copper = mass(all, "copper"), fr4 = mass(all, "fr4");
  const double cu_far = mass(all, "copper", "conductor"), fr4_far = mass(all, "fr4", "conductor");
  const double fr4_near = mass(all, "fr4", "nonconductor");
  double brushed = 0.0;
  for (const Landing& l : all)
    if (l.material == "fr4" && l.product == "nonconductor" && l.charge == 0.0) brushed += l.mass;
  std::printf("[ short feed ] %d fed; copper %.1f %% far, grade %.1f %%; FR-4 %.1f %% near, "
              "%.1f %% far, %.1f %% of the near brushed\n",
              fed, 100 * cu_far / copper, 100 * cu_far / (cu_far + fr4_far), 100 * fr4_near / fr4,
              100 * fr4_far / fr4, 100 * brushed / fr4_near);
  EXPECT_GE(cu_far / copper, 0.9);
  EXPECT_GE(cu_far / (cu_far + fr4_far), 0.85);
  EXPECT_EQ(mass(all, "copper", "nonconductor"), 0.0);
  EXPECT_GE(fr4_near / fr4, 0.6);
  EXPECT_LE(fr4_far / fr4, 0.1);
  EXPECT_GE(brushed / fr4_near, 0.5);
}

// ------------------------------------------------------------------ published trends in short

// docs/validation.md's sweeps (tools/validation_sweeps.py) in short: a few
// points of each, on shorter feeds, asserting the trends the model
// reproduces. Where it does not (fines separate at least as well as
// 0.6-1.2 mm; the copper recovery does not grow with the voltage; the copper
// landing does not widen with the feed rate at 70 rpm), docs/validation.md
// says why and nothing is asserted.

// A run of scenes/validation/ces_pcb_sweep.yaml fed for 0.1 s (about 160
// flakes, 13 of them copper) to a fixed end, as the sweeps measure it: in %
// of the mass fed of each material, particles still on the drum included.
struct Split {
  double efficiency = 0.0;  // copper into the conductor product + FR-4 into the non-conductor - 100
  double copper_to_middling = 0.0, fr4_to_conductor = 0.0, middling = 0.0;
};

using Overrides = std::vector<std::pair<std::string, std::string>>;

Split split(Overrides overrides, const std::string& end, const std::string& name) {
  overrides.insert(overrides.begin(), {{"feeds.nozzle.duration", "0.1 s"}, {"time.end", end}});
  const fs::path dir = run_scene(load(kScenes + "validation/ces_pcb_sweep.yaml", overrides), name);
  const auto fed = nlohmann::json::parse(read_text(dir / "summary.json"))["balance"]["materials"];
  const double cu = fed["copper"]["fed"]["mass_kg"], fr4 = fed["fr4"]["fed"]["mass_kg"];
  const std::vector<Landing> all = landings(dir);
  Split s;
  s.efficiency = 100 * (mass(all, "copper", "conductor") / cu +
                        mass(all, "fr4", "nonconductor") / fr4 - 1);
  s.copper_to_middling = 100 * mass(all, "copper", "middling") / cu;
  s.fr4_to_conductor = 100 * mass(all, "fr4", "conductor") / fr4;
  s.middling = 100 * (mass(all, "copper", "middling") + mass(all, "fr4", "middling")) / (cu + fr4);
  std::printf("[ trends ] %s: E %.1f %%, copper to the middling %.1f %%, FR-4 to the conductor "
              "%.1f %%, middling %.1f %% of the feed\n",
              name.c_str(), s.efficiency, s.copper_to_middling, s.fr4_to_conductor, s.middling);
  return s;
}

// The drum, the brush and the belt (at the drum's surface speed) together.
Overrides drum_speed(const std::string& rpm, const std::string& belt) {
  return {{"bodies.drum.motion.rotation.speed", rpm},
          {"bodies.brush.motion.rotation.speed", rpm},
          {"feeds.nozzle.velocity.0", belt}};
}

// Three published trends at once, sharing the scene as written (70 rpm,
// 35 kV, the measured flakes) as the reference point:
//  - drum speed: separation good near 70 rpm and failing on both sides
//    (Li et al., critical rotational speed model): at 30 rpm the copper is
//    not thrown clear and lands in the middling; at 130 rpm the FR-4 leaves
//    the roll before its image pull holds it and lands in the conductor
//    product;
//  - voltage: less middling and better separation at 35 kV than at 20 kV
//    (Wu, Li & Xu 2008);
//  - size: the 0.6-1.2 mm sieve class separates better than the coarser
//    measured flakes, 1.7-4.8 mm (docs/validation.md: 96.8 against 77.5 %).
//    Li, Xu & Zhou (2007) find 0.6-1.2 mm the most separable class of all;
//    the model does not (1.2-2.4 mm separates as well, validation.md's
//    "disagrees"), and that is not asserted.
// The test prints each case's E. Tolerances, wide enough for another
// seed's feed and narrow enough that a case without the trend's mechanism
// fails them: E at least 60 % at the reference point, each failure side at
// least 40 points below it with at least 80 % of the misplaced material
// where the mechanism puts it, 20 kV at least 20 points below and with at
// least 10 points more middling, 0.6-1.2 mm at least 5 points above. The
// ends leave every particle time to be collected (30 rpm: three quarters
// of a turn to the brush); one cycling under the brush's nip counts as
// misplaced.
TEST(SeparatorScene, SeparationFollowsDrumSpeedVoltageAndSize) {
  const Split reference = split({}, "1.6 s", "reference");
  const Split slow = split(drum_speed("30 rpm", "0.5 m/s"), "2.5 s", "30 rpm");
  const Split fast = split(drum_speed("130 rpm", "2.18 m/s"), "1.0 s", "130 rpm");
  const Split low_voltage = split({{"electrostatics.electrodes.electrode.voltage", "-20 kV"},
                                   {"electrostatics.electrodes.wire.voltage", "-20 kV"}},
                                  "1.6 s", "20 kV");
  // tools/validation_sweeps.py's 0.6-1.2 mm class: widths uniform over it,
  // thicknesses the measured laws scaled by its mid width (0.85 mm) over the
  // measured median widths, 1500 flakes a second.
  const Split sieved = split(
      {{"feeds.nozzle.rate", "1500 /s"},
       {"feeds.nozzle.mix.0.width", "{uniform: {min: 0.6 mm, max: 1.2 mm}}"},
       {"feeds.nozzle.mix.0.thickness",
        "{lognormal: {median: 0.168 mm, sigma: 0.61, min: 0.0439 mm, max: 0.349 mm}}"},
       {"feeds.nozzle.mix.1.width", "{uniform: {min: 0.6 mm, max: 1.2 mm}}"},
       {"feeds.nozzle.mix.1.thickness",
        "{lognormal: {median: 0.131 mm, sigma: 0.67, min: 0.0226 mm, max: 0.329 mm}}"}},
      "1.6 s", "0.6-1.2 mm");

  EXPECT_GE(reference.efficiency, 60.0);
  EXPECT_LE(slow.efficiency, reference.efficiency - 40.0);
  EXPECT_GE(slow.copper_to_middling, 80.0);
  EXPECT_LE(fast.efficiency, reference.efficiency - 40.0);
  EXPECT_GE(fast.fr4_to_conductor, 80.0);
  EXPECT_LE(low_voltage.efficiency, reference.efficiency - 20.0);
  EXPECT_GE(low_voltage.middling, reference.middling + 10.0);
  EXPECT_GE(sieved.efficiency, reference.efficiency + 5.0);
}

// The plant-scale scene (scenes/ces_industrial.yaml) in short: the
// reference machine at 1 m and 0.5 t/h. The feed runs 10 ms at its full
// rate (2,700 particles), then the run goes on to 0.1 s, by which time
// they have fallen the 24 mm from the outlet onto the drum. The feeder places particles until the
// fed mass reaches rate x time, so it is within one particle of it: at most 6.1 mg, a copper
// disc 1.2 mm wide and 0.6 mm thick. On the drum, the particles' positions along its axis are those
// of a feed uniform over its 0.98 m: each tenth of the drum holds its share within four binomial
// standard errors, and the ends are reached within a centimetre.
TEST(SeparatorScene, IndustrialMachineIsFedHalfATonneAnHourAcrossItsMetre) {
  const Simulation sim = load(kScenes + "ces_industrial.yaml",
                              {{"feeds.feeder.duration", "10 ms"},
                               {"time.end", "0.1 s"},
                               {"output.trajectories", "{every: 0.1 s, format: csv}"}});
  ASSERT_TRUE(sim.electrostatics);
  EXPECT_EQ(sim.model->contact.manifold, Manifold::Four);
  EXPECT_TRUE(sim.model->contact.flat_faces);
  EXPECT_TRUE(sim.model->sleep.enabled);
  EXPECT_EQ(sim.electrostatics->drum.half_width, 0.5);
  for (const RigidBody& b : sim.model->bodies) {
    const geo::Aabb box = geo::local_bounds(b.shape);
    EXPECT_DOUBLE_EQ(box.max.z() - box.min.z(), 1.0) << b.name;
  }
  ASSERT_EQ(sim.feeds.size(), 1u);
  const Feed& feed = sim.feeds[0];
  EXPECT_NEAR(feed.mass_rate * 3600.0, 500.0, 1e-9);  // kg/h
  EXPECT_DOUBLE_EQ(feed.region.max.z() - feed.region.min.z(), 0.98);
  const fs::path dir = run_scene(sim, "industrial");
  const auto summary = nlohmann::json::parse(read_text(dir / "summary.json"));
  EXPECT_EQ(summary["contact"]["manifold"], "four");
  EXPECT_EQ(summary["contact"]["flake_faces"], "flat");
  EXPECT_EQ(summary["contact"]["sleep"]["speed_mps"], 5e-3);
  const auto& balance = summary["balance"];
  EXPECT_TRUE(balance["exact"].get<bool>());
  const double fed = balance["fed"]["mass_kg"];
  const double copper = balance["materials"]["copper"]["fed"]["mass_kg"];
  constexpr double kHeaviest = 8960.0 * std::numbers::pi / 4 * 1.2e-3 * 1.2e-3 * 0.6e-3;
  EXPECT_NEAR(fed, feed.mass_rate * 0.01, kHeaviest);
  EXPECT_NEAR(copper, 0.28 * fed, kHeaviest);
  const auto rows = read_csv(dir / "trajectories.csv");
  const auto& h = rows.at(0);
  const auto col = [&](const char* name) {
    return std::size_t(std::find(h.begin(), h.end(), name) - h.begin());
  };
  std::vector<double> along;  // z of the particles on the drum at 0.1 s
  for (std::size_t k = 1; k < rows.size(); ++k) {
    const auto& r = rows[k];
    if (std::stod(r[col("time_s")]) < 0.1) continue;
    const double x = std::stod(r[col("x_m")]), y = std::stod(r[col("y_m")]);
    if (std::hypot(x, y) < 0.16 + 0.8e-3) along.push_back(std::stod(r[col("z_m")]));
  }
  const double n = double(along.size());
  EXPECT_GT(n, 0.9 * balance["fed"]["count"].get<double>());
  EXPECT_LT(*std::min_element(along.begin(), along.end()), -0.48);
  EXPECT_GT(*std::max_element(along.begin(), along.end()), 0.48);
  for (int tenth = 0; tenth < 10; ++tenth) {
    const double lo = -0.5 + 0.1 * tenth, hi = lo + 0.1;
    const double share = (std::min(hi, 0.49) - std::max(lo, -0.49)) / 0.98;
    const double count = double(std::count_if(along.begin(), along.end(),
                                              [&](double z) { return z >= lo && z < hi; }));
    EXPECT_NEAR(count, share * n, 4.0 * std::sqrt(n * share * (1.0 - share))) << "tenth " << tenth;
  }
}

// Quantile p of x, linear between order statistics (numpy's default).
double quantile(std::vector<double> x, double p) {
  std::sort(x.begin(), x.end());
  const double h = (double(x.size()) - 1.0) * p;
  const std::size_t i = std::size_t(h);
  if (i + 1 >= x.size()) return x.back();
  return x[i] + (h - double(i)) * (x[i + 1] - x[i]);
}

// The spread of a landing distribution: the range holding its middle 90 %.
double range_5_95(const std::vector<double>& x) {
  return quantile(x, 0.95) - quantile(x, 0.05);
}

// The share of x landing more than `gap` short of the median of x, with its
// binomial standard error; the share in the error is (k + 1) / (n + 2), so
// that a share of none still has one.
struct Share {
  double value = 0.0, error = 0.0;
};

Share short_share(const std::vector<double>& x, double gap) {
  const double cut = quantile(x, 0.5) - gap;
  const double n = double(x.size());
  const double k = double(std::count_if(x.begin(), x.end(), [&](double v) { return v < cut; }));
  const double p = (k + 1.0) / (n + 2.0);
  return {k / n, std::sqrt(p * (1.0 - p) / n)};
}

// The seed's Figure 10: the copper landing spreads wider as the feed rate
// grows, on scenes/validation/ces_feedrate.yaml at the seed's roll speed,
// 44.8 rpm, that of its figure (at 70 rpm the copper leaves the roll before
// it is up to speed and lands wide at every rate: docs/validation.md). The
// mix drops at rest from a feeder's lip at the top of the drum, which must
// accelerate it by friction; particles lying on others (friction 0.2
// instead of the drum's 0.5) leave the drum slower and land short, so the
// copper landing grows a low tail as the layer thickens. Two of the
// sweep's points as tools/validation_sweeps.py runs them (docs/validation.md):
// 5 g/s through the seed's outlet (a sparse layer) fed for 3 s, and 160 g/s
// (an overfed roll) fed for 0.13 s, each until 0.65 s after its feed ends.
//
// Measure: the share of the copper landing more than 20 mm short of the
// copper median (the feed rate acts on the tail, and a count in the tail is
// the least noisy measure of it on 70-130 copper particles), with a
// binomial standard error, and the 5-95 % range. Asserted: the short share
// rises by more than two standard errors and the range by more than 20 mm;
// nearly all the copper lands (at least 90 %), beyond the FR-4.
TEST(SeparatorScene, CopperLandingWidensWithFeedRate) {
  constexpr double kGap = 0.020;
  struct Rate {
    const char* loading;
    const char *rate, *duration, *end;
  };
  std::vector<Share> share;
  std::vector<double> spread;
  for (const Rate& r :
       {Rate{"5", "1.25 g/s", "3 s", "3.65 s"}, Rate{"160", "40 g/s", "0.13 s", "0.78 s"}}) {
    SCOPED_TRACE(std::string(r.loading) + " g/s");
    const Simulation sim = load(kScenes + "validation/ces_feedrate.yaml",
                                {{"feeds.nozzle.rate", r.rate},
                                 {"feeds.nozzle.duration", r.duration},
                                 {"time.end", r.end},
                                 {"bodies.drum.motion.rotation.speed", "44.8 rpm"},
                                 {"bodies.brush.motion.rotation.speed", "44.8 rpm"}});
    const fs::path dir = run_scene(sim, std::string("feed_") + r.loading);
    const auto summary = nlohmann::json::parse(read_text(dir / "summary.json"));
    EXPECT_TRUE(summary["balance"]["exact"].get<bool>());
    const std::vector<Landing> all = landings(dir);
    const std::vector<double> cu = positions(all, "copper"), fr4 = positions(all, "fr4");
    ASSERT_GE(cu.size(), 60u);
    EXPECT_GT(median(cu) - median(fr4), 0.05);
    const int cu_fed = summary["balance"]["materials"]["copper"]["fed"]["count"];
    EXPECT_GE(double(cu.size()), 0.9 * cu_fed) << "copper still on the drum";
    share.push_back(short_share(cu, kGap));
    spread.push_back(range_5_95(cu));
    std::printf("[ feed rate ] %s g/s: %zu copper landed, short by > 20 mm %.1f +- %.1f %%, "
                "5-95 %% range %.1f mm\n",
                r.loading, cu.size(), 100 * share.back().value, 100 * share.back().error,
                1e3 * spread.back());
  }
  ASSERT_EQ(share.size(), 2u);
  EXPECT_GT(share[1].value - share[0].value, 2.0 * std::hypot(share[0].error, share[1].error));
  EXPECT_GT(spread[1] - spread[0], 0.020);
}

}  // namespace
}  // namespace ces
