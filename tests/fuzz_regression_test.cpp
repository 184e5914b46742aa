// The fuzzers' past findings (fuzz/regressions/), replayed in the normal
// build: every input that once crashed, hung or was wrongly accepted must
// now end in a clean error. Scene inputs are loaded as the fuzz targets load
// them (from tests/bad_scenes/, so includes resolve the same way) and must
// throw SceneError with one-line diagnostics; unit inputs must be refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <variant>
#include <vector>

#include "scene/scene.hpp"
#include "scene/units.hpp"
#include "support.hpp"

namespace ces::scene {
namespace {

namespace fs = std::filesystem;

const fs::path kRegressions = fs::path(CES_SOURCE_DIR) / "fuzz" / "regressions";

std::vector<fs::path> findings(const std::string& target) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(kRegressions / target))
    if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

void expect_clean_error(const fs::path& input, const std::string& load_as) {
  SCOPED_TRACE(input.string());
  try {
    load_text(test::read_text(input), load_as);
    ADD_FAILURE() << "loaded without errors";
  } catch (const SceneError& e) {
    ASSERT_FALSE(e.diagnostics().empty());
    for (const Diagnostic& d : e.diagnostics())
      EXPECT_EQ(d.str().find('\n'), std::string::npos) << d.str();
  }
}

const std::string kBadScenes = std::string(CES_SOURCE_DIR) + "/tests/bad_scenes/";

TEST(FuzzRegressions, SceneYamlFindingsEndInACleanError) {
  for (const fs::path& f : findings("scene_yaml")) expect_clean_error(f, kBadScenes + "fuzz.yaml");
}

TEST(FuzzRegressions, SceneJsonFindingsEndInACleanError) {
  for (const fs::path& f : findings("scene_json")) expect_clean_error(f, kBadScenes + "fuzz.json");
}

TEST(FuzzRegressions, UnitFindingsAreRefused) {
  for (const fs::path& f : findings("units")) {
    const auto parsed = units::parse(test::read_text(f));
    EXPECT_TRUE(std::holds_alternative<std::string>(parsed)) << f;
  }
}

// Every target has findings to replay: an empty folder would pass silently.
TEST(FuzzRegressions, EveryTargetHasItsCorpus) {
  for (const char* target : {"scene_yaml", "scene_json", "units"})
    EXPECT_FALSE(findings(target).empty()) << target;
}

}  // namespace
}  // namespace ces::scene
