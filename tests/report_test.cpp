// report.html (output/report.hpp): the data it draws from is the run's own,
// and the page needs nothing from outside itself. Headless Chromium renders
// it in Report.RendersInChromium (tests/report_in_browser.sh).
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "output/report.hpp"
#include "output/report_page.hpp"
#include "support.hpp"

namespace ces {
namespace {

TEST(Report, Base64OfTheStandardsVectors) {  // RFC 4648, section 10
  EXPECT_EQ(output::base64(""), "");
  EXPECT_EQ(output::base64("f"), "Zg==");
  EXPECT_EQ(output::base64("fo"), "Zm8=");
  EXPECT_EQ(output::base64("foo"), "Zm9v");
  EXPECT_EQ(output::base64("foob"), "Zm9vYg==");
  EXPECT_EQ(output::base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(output::base64("foobar"), "Zm9vYmFy");
}

// A run of `steps` steps of h observed by a cross section, the frames'
// times then those of its end (finish).
std::vector<double> frame_times(output::CrossSection& section, int steps, double h) {
  State state;
  for (int k = 0; k <= steps; ++k) {
    state.time = k * h;
    section.observe(state);
  }
  section.finish(state);
  std::vector<double> times;
  for (const output::CrossSection::Frame& f : section.frames()) times.push_back(f.time);
  return times;
}

// However long the run turns out (a run until collected ends before its
// time.end), its frames are evenly spaced from t = 0 to its last step, 100
// to 199 of them, and the last step is one more where it is not one of them.
TEST(Report, FramesSpanTheRunEvenly) {
  const double h = 0.25e-3;
  for (const int steps : {150, 1200, 7764, 40000}) {
    output::CrossSection section(h);
    const std::vector<double> t = frame_times(section, steps, h);
    ASSERT_GE(t.size(), 100u) << steps;
    EXPECT_LE(t.size(), 200u) << steps;
    EXPECT_EQ(t.front(), 0.0);
    EXPECT_NEAR(t.back(), steps * h, 1e-9) << steps;
    const double every = t[1] - t[0];
    for (std::size_t k = 1; k + 1 < t.size(); ++k) EXPECT_NEAR(t[k], k * every, 1e-9) << steps;
    EXPECT_LE(t.back() - t[t.size() - 2], every + 1e-9) << steps;
  }
}

// A cross section saved mid-run and loaded goes on to the same frames.
TEST(Report, FramesResumeFromACheckpoint) {
  const double h = 1e-3;
  output::CrossSection whole(h), first(h);
  const std::vector<double> expected = frame_times(whole, 3000, h);
  State state;
  for (int k = 0; k <= 1234; ++k) {
    state.time = k * h;
    first.observe(state);
  }
  ByteWriter out;
  first.save(out);
  output::CrossSection resumed(h);
  ByteReader in(out.bytes());
  resumed.load(in);
  std::vector<double> times;
  for (int k = 1235; k <= 3000; ++k) {
    state.time = k * h;
    resumed.observe(state);
  }
  resumed.finish(state);
  for (const output::CrossSection::Frame& f : resumed.frames()) times.push_back(f.time);
  EXPECT_EQ(times, expected);
}

// A mixed particle (a PCB fragment with metal in it) on the drum carries
// two charges, its metal part's and its insulating part's: every output
// gives their sum. The last frame of the report and of trajectories.csv,
// both at the run's end, hold the same charges (sorted: the report's
// frames carry no ids).
TEST(Report, AMixedParticlesChargeIsTheSameInEveryOutput) {
  const test::fs::path dir = test::fresh_dir("mixed_charge");
  std::ofstream(dir / "mixed.yaml")
      << "ces_sim: 1\n"
         "include: " CES_SOURCE_DIR
         "/scenes/machines/ces_machine.yaml\n"
         "time: {step: 0.5 ms, end: 0.12 s, until: end}\n"
         "gravity: [0, -9.81 m/s^2, 0]\n"
         "materials:\n"
         "  pcb: {density: 2500, metal_fraction: 0.3,\n"
         "        relative_permittivity: 4.4, charge_decay_time: 20 s}\n"
         "feeds:\n"
         "  - name: f\n"
         "    region: {box: {min: [-0.01, 0.165, -0.01],\n"
         "                   max: [0.01, 0.17, 0.01]}}\n"
         "    rate: 500 /s\n"
         "    duration: 0.02 s\n"
         "    mix: [{material: pcb, size: {constant: 1 mm}}]\n"
         "output: {trajectories: {every: 0.12 s, format: csv}}\n";
  const test::Outcome r =
      test::ces_sim((dir / "mixed.yaml").string() + " -q -o " + (dir / "out").string() +
                    " --include-path " CES_SOURCE_DIR "/scenes");
  ASSERT_EQ(r.code, 0) << r.err;
  std::vector<double> report, csv;
  const nlohmann::json frames = test::report_data(dir / "out" / "report.html")["frames"];
  ASSERT_NEAR(frames.back()["t"].get<double>(), 0.12, 1e-9);
  for (const auto& q : frames.back()["q"]) report.push_back(q.get<double>());
  std::istringstream lines(test::read_text(dir / "out" / "trajectories.csv"));
  std::string line;
  std::getline(lines, line);  // the header: charge_c is the 12th column
  while (std::getline(lines, line)) {
    std::vector<std::string> cells;
    std::istringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    if (std::stod(cells[0]) > 0.12 - 1e-9) csv.push_back(std::stod(cells[11]));
  }
  ASSERT_FALSE(csv.empty());
  ASSERT_EQ(report.size(), csv.size());
  std::sort(report.begin(), report.end());
  std::sort(csv.begin(), csv.end());
  for (std::size_t k = 0; k < csv.size(); ++k)
    EXPECT_NEAR(report[k], csv[k], 1e-6 * std::abs(csv[k])) << k;
}

// A name with markup in it stays text: the page's data holds no '<' (a
// "<!--" there would keep the browser from finding the data's end) and
// reads back as the name.
TEST(Report, MarkupInANameStaysInTheData) {
  const test::fs::path dir = test::fresh_dir("markup");
  std::string scene = test::read_text(std::string(CES_SOURCE_DIR) + "/scenes/default.yaml");
  const std::string name = "<!--<script></script>";
  scene.replace(scene.find("name: default"), 13, "name: '" + name + "'");
  std::ofstream(dir / "markup.yaml") << scene;
  const test::Outcome r = test::ces_sim((dir / "markup.yaml").string() +
                                        " --set time.end=0.01s -q -o " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string page = test::read_text(dir / "out" / "report.html");
  const std::string open = "<script type=\"application/json\" id=\"data\">";
  const std::size_t start = page.find(open) + open.size();
  const std::size_t end = page.find("</script>", start);
  ASSERT_NE(end, std::string::npos);
  EXPECT_EQ(page.substr(start, end - start).find('<'), std::string::npos);
  EXPECT_EQ(test::report_data(dir / "out" / "report.html")["summary"]["scene"]["name"], name);
}

// The reference scene for 0.3 s: the page carries summary.json's figures,
// the machine (drum, brush, wire, electrode, splitters, the collector's plane),
// 100 to 199 frames from t = 0 to the end whose last one holds every particle
// still in the machine, and no address outside the page.
TEST(Report, CarriesTheRunsFiguresFramesAndMachine) {
  const test::fs::path dir = test::fresh_dir("report");
  const test::Outcome r = test::ces_sim(std::string(CES_SOURCE_DIR) +
                                        "/scenes/ces_pcb.yaml --set time.end=0.3s --set time.until=end -q -o " +
                                        dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json data = test::report_data(dir / "report.html");
  ASSERT_TRUE(data.is_object());
  const nlohmann::json summary = nlohmann::json::parse(test::read_text(dir / "summary.json"));
  EXPECT_EQ(data["summary"]["collectors"], summary["collectors"]);
  EXPECT_EQ(data["summary"]["balance"], summary["balance"]);
  EXPECT_EQ(data["materials"], (nlohmann::json{"steel", "brush", "copper", "fr4", "plate"}));

  const nlohmann::json& machine = data["machine"];
  ASSERT_EQ(machine["circles"].size(), 4u);  // drum, brush, the corona wire, the electrode
  EXPECT_EQ(machine["circles"][0]["r"], 1600);  // 0.16 m in 0.1 mm
  EXPECT_EQ(machine["polygons"].size(), 2u);    // the splitters
  EXPECT_EQ(machine["collectors"].size(), 1u);

  const nlohmann::json& frames = data["frames"];
  ASSERT_GE(frames.size(), 100u);
  EXPECT_LT(frames.size(), 200u);
  EXPECT_EQ(frames.front()["t"], 0.0);
  EXPECT_NEAR(frames.back()["t"].get<double>(), 0.3, 1e-9);
  const std::size_t active = summary["balance"]["active"]["count"];
  ASSERT_GT(active, 0u) << "the run's end leaves particles to draw";
  const std::size_t drawn = frames.back()["x"].size(), stride = (active + 1499) / 1500;
  EXPECT_LE(drawn, 1500u);
  EXPECT_GE(drawn, active / stride - 1);  // every stride-th id of those in the machine
  EXPECT_EQ(frames.back()["q"].size(), drawn);

  const std::string page = test::read_text(dir / "report.html");
  EXPECT_EQ(page.find("http"), std::string::npos);  // no network: everything is in the page
  EXPECT_EQ(page.find("src=\"/"), std::string::npos);
}

}  // namespace
}  // namespace ces
