// report.html (output/report.hpp): the data it draws from is the run's own,
// and the page needs nothing from outside itself. Headless Chromium renders
// it in Report.RendersInChromium (tests/report_in_browser.sh).
#include <gtest/gtest.h>

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

// The reference scene for 0.3 s: the page carries summary.json's figures,
// the machine (drum, brush, wire, electrode, splitters, the collector's plane),
// 100 frames from t = 0 to the end whose last one holds every particle
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
  ASSERT_EQ(frames.size(), 100u);
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
