// The separator from a scene file, end to end (issue 4): the scene keys
// compile to the field model, charging zones, electrical materials, drag
// and particle shapes; the runner installs only what a scene asks for; the
// field picture is the field model's; a short feed of the reference machine
// separates copper from FR-4 with an exact balance; and the copper landing
// widens with the feed rate (the seed's Figure 10).
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
#include <random>
#include <sstream>

#include "feed/shapes.hpp"
#include "fields/charge.hpp"
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

// Loads a scene with overrides, on one thread.
Simulation load(const std::string& scene,
                const std::vector<std::pair<std::string, std::string>>& overrides = {}) {
  scene::LoadOptions options;
  options.overrides = overrides;
  options.threads = 1;
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
  EXPECT_TRUE(std::holds_alternative<fields::BipolarField>(es.field));
  EXPECT_EQ(es.drum.radius, 0.16);
  EXPECT_EQ(es.drum.half_width, 0.15);
  EXPECT_EQ(sim.model->bodies[std::size_t(es.drum_body)].name, "drum");
  ASSERT_TRUE(es.brush_body);
  EXPECT_EQ(sim.model->bodies[std::size_t(*es.brush_body)].name, "brush");
  ASSERT_EQ(sim.electrodes.size(), 1u);
  const fields::Electrode& e = sim.electrodes[0].electrode;
  EXPECT_NEAR(e.centre.x(), 0.267 * std::cos(30 * kDeg), 1e-15);
  EXPECT_NEAR(e.centre.y(), 0.267 * std::sin(30 * kDeg), 1e-15);
  EXPECT_EQ(e.radius, 0.019);
  EXPECT_EQ(e.potential, -35000.0);
  ASSERT_EQ(es.corona.size(), 1u);
  const fields::CoronaZone& z = es.corona[0];
  EXPECT_DOUBLE_EQ(z.angle_begin, 30 * kDeg);
  EXPECT_DOUBLE_EQ(z.angle_end, 75 * kDeg);
  EXPECT_EQ(z.depth, 0.005);
  EXPECT_EQ(z.mode, fields::CoronaCharging::Saturation);
  EXPECT_DOUBLE_EQ(*z.field, 4.13e5);
  EXPECT_EQ(z.ion_sign, -1.0);
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
    // From the resistivity: eps0 epsr rho = 39 s (PHYSICS.md §3).
    EXPECT_NEAR(e.decay_time, fields::relaxation_time(4.4, 1e12), 1e-12);
    EXPECT_NEAR(e.decay_time, 38.96, 0.01);
  }
}

// A scene without air and electrodes builds neither (DESIGN.md §1).
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
                                       "    - {name: wire, position: [0.1 m, 0.2 m],\n"
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
  EXPECT_EQ(lines->electrodes().size(), 2u);  // the machine's electrode and the wire
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
  EXPECT_NEAR(2.0 * shape(0).bounding_radius / d, 1.87, 0.01);
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
      load(kScenes + "ces_pcb.yaml", {{"feeds.nozzle.start", "1 s"}, {"time.end", "1 ms"}});
  const fs::path dir = run_scene(sim, "field");
  const auto rows = read_csv(dir / "field.csv");
  ASSERT_GT(rows.size(), 1000u);
  EXPECT_EQ(rows[0],
            (std::vector<std::string>{"x_m", "y_m", "ex_vpm", "ey_vpm", "e_vpm", "phi_v"}));
  const auto& model = std::get<fields::BipolarField>(sim.electrostatics->field);
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
  EXPECT_NEAR(phi_min, -35000.0, 1e-3);
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

// 0.1 s of the reference scene's feed (about 570 particles), run until
// nearly all of it has landed, the FR-4 flakes after riding 3/4 of a turn
// to the brush (1.6 s). Thresholds (measured at seed 1 in brackets):
//  - copper: at least 90 % of it in the conductor product (100 %), whose
//    copper grade is at least 90 % (100 %); at most 5 % of the FR-4 there
//    (0 %);
//  - FR-4 into the near (nonconductor) product: at least 40 % of it (51 %)
//    and no copper, at least 85 % of that brushed off the drum (charge 0:
//    91 %). Half the FR-4 mass is flakes, pinned by the face law
//    (stages.hpp) and brushed off: 98 % of them reach the near product. The other half
//    is grains, whose sphere-law image force (at most 1.06 m g at 0.5 mm)
//    cannot hold them under the drum, where 1.36 m g pulls them off: they
//    slide off the lower front into the middling (README).
TEST(SeparatorScene, ShortFeedSeparatesCopperFromFr4) {
  const Simulation sim =
      load(kScenes + "ces_pcb.yaml", {{"feeds.nozzle.duration", "0.1 s"}, {"time.end", "1.6 s"}});
  const fs::path dir = run_scene(sim, "short_feed");
  const auto summary = nlohmann::json::parse(read_text(dir / "summary.json"));
  EXPECT_TRUE(summary["balance"]["exact"].get<bool>());
  const int fed = summary["balance"]["fed"]["count"];
  EXPECT_GT(fed, 400);
  EXPECT_LE(summary["balance"]["active"]["count"].get<int>(), fed / 50) << "still in flight";
  const std::vector<Landing> all = landings(dir);
  const double copper = mass(all, "copper"), fr4 = mass(all, "fr4");
  const double cu_far = mass(all, "copper", "conductor"), fr4_far = mass(all, "fr4", "conductor");
  EXPECT_GE(cu_far / copper, 0.9);
  EXPECT_GE(cu_far / (cu_far + fr4_far), 0.9);
  EXPECT_LE(fr4_far / fr4, 0.05);
  const double fr4_near = mass(all, "fr4", "nonconductor");
  EXPECT_GE(fr4_near / fr4, 0.4);
  EXPECT_EQ(mass(all, "copper", "nonconductor"), 0.0);
  double brushed = 0.0;
  for (const Landing& l : all)
    if (l.material == "fr4" && l.product == "nonconductor" && l.charge == 0.0) brushed += l.mass;
  EXPECT_GE(brushed / fr4_near, 0.85);
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

// Bootstrap standard error of range_5_95 (1000 resamples, fixed stream).
double range_5_95_se(const std::vector<double>& x) {
  std::mt19937_64 rng(20261201);
  std::vector<double> values, sample(x.size());
  for (int b = 0; b < 1000; ++b) {
    for (double& s : sample) s = x[rng() % x.size()];
    values.push_back(range_5_95(sample));
  }
  double mean = 0.0, var = 0.0;
  for (double v : values) mean += v / double(values.size());
  for (double v : values) var += (v - mean) * (v - mean) / double(values.size() - 1);
  return std::sqrt(var);
}

// The seed's Figure 10 on small feeds: the copper landing widens with the
// feed rate. The feed-rate scenes drop the mix at rest from a feeder's lip
// at the top of the drum, which must accelerate it by friction; in a dense
// layer, particles lying on others (friction 0.2 instead of the drum's 0.5)
// leave the drum slower and land short, so the copper landing grows a low
// tail (copper thrown into the middling) as the rate grows.
//
// Measure: the 5-95 % range of the copper landing x (the standard deviation
// reacts to one stray particle, the interquartile range misses the tail,
// which is where the feed rate acts), with a bootstrap standard error (1000
// resamples). Asserted: from 5 to 40 g/s it widens by more than 10 mm and by
// more than one combined standard error. Measured on these feeds over seeds
// 1-8 (README): 5 g/s 21.8-28.7 mm (62-85 copper particles), 40 g/s
// 40.4-69.8 mm (101-123), the step 13.8-45.7 mm and 1.1-7.0 standard errors
// (7.0 at seed 1, which the test runs, before the sliding release on walls;
// 1.3 after it, and 2.8 and 0.6 at seeds 2 and 3; 2 or more at 6 seeds of 8, so 2 is
// not asserted: with about 110 copper particles at 40 g/s the standard
// error is 4-14 mm, and more would cost CI minutes). Nearly all the copper
// must have landed (at least 90 %; measured 91.5-100 %): the slow particles
// are the tail.
//
// Not asserted: the step from 5 to 20 g/s. Full runs (0.5 s of feed, about
// 230 copper particles at 20 g/s) widen monotonically at every seed tried,
// by 1.5-2.9 standard errors from 5 to 20 g/s (README); on a feed short
// enough for CI the layer under the lip is barely formed, the step is within
// one standard error at 3 seeds of 5, and the order reverses at one. The
// 20 g/s scene runs here on a tiny feed for its balance and separation.
TEST(SeparatorScene, CopperLandingWidensWithFeedRate) {
  struct Feed {
    const char* rate;
    const char* duration;
    const char* end;
  };
  std::vector<double> spread, error;
  for (const Feed& feed : {Feed{"5", "0.6 s", "1.2 s"}, Feed{"20", "0.05 s", "0.65 s"},
                           Feed{"40", "0.12 s", "0.75 s"}}) {
    SCOPED_TRACE(std::string(feed.rate) + " g/s");
    const Simulation sim =
        load(kScenes + "ces_feedrate/feed_" + feed.rate + "gps.yaml",
             {{"feeds.nozzle.duration", feed.duration}, {"time.end", feed.end}});
    const fs::path dir = run_scene(sim, std::string("feed_") + feed.rate);
    const auto summary = nlohmann::json::parse(read_text(dir / "summary.json"));
    EXPECT_TRUE(summary["balance"]["exact"].get<bool>());
    const std::vector<Landing> all = landings(dir);
    const std::vector<double> cu = positions(all, "copper"), fr4 = positions(all, "fr4");
    ASSERT_GE(cu.size(), 5u);
    EXPECT_GT(median(cu) - median(fr4), 0.05);
    if (std::string(feed.rate) == "20") continue;
    const int cu_fed = summary["balance"]["materials"]["copper"]["fed"]["count"];
    ASSERT_GE(cu.size(), 50u);
    EXPECT_GE(double(cu.size()), 0.9 * cu_fed) << "copper still on the drum";
    spread.push_back(range_5_95(cu));
    error.push_back(range_5_95_se(cu));
    std::printf("[ feed rate ] %s g/s: %zu copper, 5-95 %% range %.1f +- %.1f mm\n", feed.rate,
                cu.size(), 1e3 * spread.back(), 1e3 * error.back());
  }
  ASSERT_EQ(spread.size(), 2u);
  EXPECT_GT(spread[1] - spread[0], 0.010);
  EXPECT_GT(spread[1] - spread[0], std::hypot(error[0], error[1]));
}

}  // namespace
}  // namespace ces
