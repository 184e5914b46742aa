// `ces-sim study` on tests/scenes/study_drop.yaml: free flight to a
// collector, so the landing position is known in closed form.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <vector>

#include "output/compare.hpp"
#include "study/study.hpp"
#include "support.hpp"

namespace ces {
namespace {

using test::fs::path;

const std::string kScene = std::string(CES_TEST_DIR) + "/scenes/study_drop.yaml";
const std::string kSteps = " --vary time.step=2ms,1ms,0.5ms";

// study.csv as rows of fields; the header is row 0.
std::vector<std::vector<std::string>> read_csv(const path& file) {
  const output::Table t = output::read_table(file);
  std::vector<std::vector<std::string>> rows{t.header};
  rows.insert(rows.end(), t.rows.begin(), t.rows.end());
  return rows;
}

TEST(Study, CasesAreTheGridLastAxisFastest) {
  const auto cases = study::make_cases(
      {study::parse_axis("time.step=2ms,1ms"), study::parse_axis("solver.method=apgd,spg,psor")});
  ASSERT_EQ(cases.size(), 6u);
  EXPECT_EQ(cases[4].index, 4u);
  EXPECT_EQ(cases[4].sets, (study::Sets{{"time.step", "1ms"}, {"solver.method", "spg"}}));
  EXPECT_THROW(study::parse_axis("time.step"), std::invalid_argument);
  EXPECT_THROW(study::parse_axis("time.step=1ms,,2ms"), std::invalid_argument);
  EXPECT_THROW(study::parse_axis("time.step=1ms,1ms"), std::invalid_argument);
  EXPECT_THROW(study::parse_axes({"time.step=1ms,0.5ms", "seed:time.step=1:2ms"}),
               std::invalid_argument);
  EXPECT_EQ(study::parse_axes({"time.step=1ms", "seed=1,2"}).size(), 2u);
}

// Each case runs the scene as the study does, with the same --include-path:
// a scene that includes from beside its folder works in every case.
TEST(Study, CasesPassOnTheIncludePaths) {
  study::Options o;
  o.scene = kScene;
  o.include_paths = {"/a/machines", "/b"};
  const auto cases = study::make_cases({study::parse_axis("seed=1,2")});
  const std::vector<std::string> args = study::case_arguments(o, cases[1]);
  const std::vector<std::string> tail(args.end() - 4, args.end());
  EXPECT_EQ(tail, (std::vector<std::string>{"--include-path", "/a/machines", "--include-path", "/b"}));
}

// The user's own --unset reaches every case, before any --set.
TEST(Study, CasesPassOnTheRemovals) {
  study::Options o;
  o.scene = kScene;
  o.base_unsets = {"solver.sleep"};
  o.base_sets = {{"time.end", "0.1s"}};
  const auto cases = study::make_cases({study::parse_axis("seed=1,2")});
  const std::vector<std::string> args = study::case_arguments(o, cases[1]);
  const std::vector<std::string> middle(args.begin() + 4, args.begin() + 10);
  EXPECT_EQ(middle, (std::vector<std::string>{"--unset", "solver.sleep", "--set", "time.end=0.1s",
                                              "--set", "seed=2"}));
}

// Keys joined by ':' vary together: DVI and DEM each at their own steps.
TEST(Study, ZippedKeysVaryTogether) {
  const auto cases = study::make_cases({study::parse_axis("contact.model:time.step=dvi:1ms,dem:5us"),
                                        study::parse_axis("seed=1,2")});
  ASSERT_EQ(cases.size(), 4u);
  EXPECT_EQ(cases[3].sets,
            (study::Sets{{"contact.model", "dem"}, {"time.step", "5us"}, {"seed", "2"}}));
  EXPECT_THROW(study::parse_axis("contact.model:time.step=dvi:1ms,dem"), std::invalid_argument);
  EXPECT_THROW(study::parse_axis("contact.model:time.step=dvi:,dem:1ms"), std::invalid_argument);
}

// DVI and DEM on one plot: the reference is the finest DVI case even though
// the DEM case has the smaller step; DEM draws its own line.
TEST(Study, DviAndDemShareThePlotWithDviAsReference) {
  const path dir = test::fresh_dir("study_dem");
  const test::Outcome r = test::ces_sim(
      "study " + kScene + " --vary contact.model:time.step=dvi:2ms,dvi:1ms,dem:0.5ms --jobs 2 -o " +
      dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("reference: " + (dir / "case_1").string()), std::string::npos) << r.out;
  const auto rows = read_csv(dir / "study.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0][1], "contact.model");
  EXPECT_EQ(rows[0][2], "time.step");
  EXPECT_EQ(rows[3].back(), "dem");
  EXPECT_NE(test::read_text(dir / "study.svg").find(">dem</text>"), std::string::npos);
}

// The reference is the finest case (0.5 ms) and its error against itself is
// exactly 0; the landing error against the reference and against the closed
// form (mean landing position, x = vx sqrt(2 H / g)) shrinks strictly with
// the step. Tolerance: exact for the self-comparison.
TEST(Study, ErrorsShrinkWithTheStepAndTheReferenceIsExact) {
  const path dir = test::fresh_dir("study_grid");
  const test::Outcome r =
      test::ces_sim("study " + kScene + kSteps + " --jobs 2 -o " + dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("reference: " + (dir / "case_2").string()), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("the feed's sampling at the reference (its products' largest standard "
                       "errors): grade "),
            std::string::npos)
      << r.out;
  const auto rows = read_csv(dir / "study.csv");
  ASSERT_EQ(rows.size(), 4u);
  const auto col = [&](const std::string& name) {
    return std::size_t(std::find(rows[0].begin(), rows[0].end(), name) - rows[0].begin());
  };
  const std::size_t w1 = col("w1_max_mm");
  ASSERT_LT(w1, rows[0].size());
  EXPECT_EQ(rows[3][w1], "0");
  EXPECT_GT(std::stod(rows[1][w1]), std::stod(rows[2][w1]));
  EXPECT_GT(std::stod(rows[2][w1]), 0.0);
  for (std::size_t i = 1; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i][col("balance_exact")], "true");
    EXPECT_EQ(std::stod(rows[i][col("grade_error")]), 0.0);
  }

  const study::Errors self = study::measure(dir / "case_2", dir / "case_2");
  EXPECT_EQ(self.w1_max_mm, 0.0);
  EXPECT_EQ(self.grade, 0.0);
  EXPECT_EQ(self.recovery, 0.0);
  EXPECT_EQ(self.w1_mm.size(), 2u);

  const double exact = 1.0 * std::sqrt(2 * 0.1 / 9.81);  // the fast grains
  double previous = 1e9;
  std::vector<double> means;
  for (int k = 0; k < 3; ++k) {
    const auto landings = output::read_landings(dir / ("case_" + std::to_string(k)) / "crossings.csv");
    const auto& fast = landings.at("fast at floor");
    double mean = 0;
    for (const auto& [x, m] : fast) mean += x / double(fast.size());
    const double error = std::abs(mean - exact);
    EXPECT_LT(error, previous) << "case " << k;
    previous = error;
    means.push_back(mean);
  }
  // Semi-implicit Euler falls as y0 - g t^2/2 - g h t/2, so a grain lands
  // h/2 early: vx h/2 short. The same grains at each step: from 2 to 1 ms
  // they land 0.5 mm farther, from 1 to 0.5 ms 0.25 mm (0.01 mm: the
  // O(h^2) terms, vx h^2 / (8 t), are a few microns). Against the closed form, 0.25 mm short at
  // 0.5 ms, to 0.2 mm: three standard errors of the ten grains' mean over
  // launch heights spread by +-0.5 mm.
  EXPECT_NEAR(means[1] - means[0], 0.5e-3, 0.01e-3);
  EXPECT_NEAR(means[2] - means[1], 0.25e-3, 0.01e-3);
  EXPECT_NEAR(exact - means[2], 0.25e-3, 0.2e-3);
  const std::string svg = test::read_text(dir / "study.svg");
  EXPECT_NE(svg.find("<polyline"), std::string::npos);
  EXPECT_NE(svg.find(">2ms</text>"), std::string::npos) << "each point labelled with its step";
  const std::string report = test::read_text(dir / "report.html");
  EXPECT_NE(report.find("<a href=\"case_2/report.html\">"), std::string::npos);
  EXPECT_TRUE(test::fs::exists(dir / "case_2" / "report.html"));

  // A reference whose products.csv has no standard errors (an older run):
  // the sampling is not known, and the study says so.
  const path old = test::fresh_dir("study_old_reference");
  for (const char* name : {"crossings.csv", "summary.json"})
    test::fs::copy_file(dir / "case_2" / name, old / name);
  std::istringstream products(test::read_text(dir / "case_2" / "products.csv"));
  std::ofstream stripped(old / "products.csv");
  for (std::string line; std::getline(products, line);)
    stripped << line.substr(0, line.rfind(',', line.rfind(',') - 1)) << '\n';
  stripped.close();
  const test::Outcome again = test::ces_sim("study " + kScene + kSteps + " --jobs 2 -o " +
                                            dir.string() + " --reference " + old.string());
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_NE(again.out.find("the feed's sampling at the reference: not known"), std::string::npos)
      << again.out;

  // A reference that is not a run's folder is refused before any case runs.
  const path none = test::fresh_dir("study_no_reference");
  const test::Outcome refused = test::ces_sim("study " + kScene + kSteps + " -o " + none.string() +
                                              " --reference " + (none / "missing").string());
  EXPECT_EQ(refused.code, 2);
  EXPECT_NE(refused.err.find("no crossings.csv"), std::string::npos) << refused.err;
  EXPECT_FALSE(test::fs::exists(none / "case_0"));
}

// A study of tolerances at one step: the reference is the tightest case,
// whatever order the axis lists them in.
// A product can be mostly copper in one run and mostly FR-4 in the other:
// its grade and recovery errors are the case's against the reference's on
// the reference's main material, not one material's figures against the
// other's.
TEST(Study, GradeErrorsAreOnTheReferencesMainMaterial) {
  const path ref = test::fresh_dir("study_main_ref"), run = test::fresh_dir("study_main_case");
  ASSERT_EQ(test::ces_sim(kScene + " -q -o " + ref.string()).code, 0);
  for (const char* f : {"crossings.csv", "summary.json"})
    std::filesystem::copy_file(ref / f, run / f);
  const std::string header =
      "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery\n";
  std::ofstream(ref / "products.csv") << header << "tray,near,0,1,copper,3,0.003,0.6,0.5\n"
                                      << "tray,near,0,1,fr4,2,0.002,0.4,0.2\n";
  std::ofstream(run / "products.csv") << header << "tray,near,0,1,copper,3,0.003,0.45,0.45\n"
                                      << "tray,near,0,1,fr4,4,0.0037,0.55,0.3\n";
  const study::Errors e = study::measure(run, ref);
  EXPECT_NEAR(e.grade, 0.15, 1e-12);  // copper: 0.45 against 0.6
  EXPECT_NEAR(e.recovery, 0.05, 1e-12);
}

TEST(Study, TheTightestToleranceIsTheReference) {
  const path dir = test::fresh_dir("study_tolerance");
  const test::Outcome r = test::ces_sim(
      "study " + kScene + " --vary solver.tolerance=10mm/s,0.1mm/s,1mm/s --jobs 2 -o " +
      dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("reference: " + (dir / "case_1").string()), std::string::npos) << r.out;
}

// Cases that end before any particle reaches a collector: the errors read
// 0, and the study says that is for want of anything to compare.
TEST(Study, ANothingCollectedReferenceIsNamed) {
  const path dir = test::fresh_dir("study_nothing");
  const test::Outcome r = test::ces_sim(
      "study " + kScene + " --set time.end=1ms --vary time.step=1ms,0.5ms -o " + dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("warning: the reference collected no particle"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("warning: the reference collected no particle"), std::string::npos) << r.out;
}

// A study run again reuses its complete cases, unless the scene changed
// since: the edited scene's cases run again (they kept the old numbers).
TEST(Study, AnEditedSceneRunsItsCasesAgain) {
  const path dir = test::fresh_dir("study_edited");
  const path scene = dir / "drop.yaml";
  std::filesystem::copy_file(kScene, scene);
  const std::string study =
      "study " + scene.string() + " --vary time.step=1ms,2ms -o " + (dir / "out").string();
  ASSERT_EQ(test::ces_sim(study).code, 0);
  const auto fed = [&] {
    const std::string summary = test::read_text(dir / "out" / "case_0" / "summary.json");
    return nlohmann::json::parse(summary)["balance"]["fed"]["count"].get<int>();
  };
  const int before = fed();
  ASSERT_EQ(test::ces_sim(study).code, 0);
  EXPECT_EQ(fed(), before);  // nothing changed: reused
  std::string text = test::read_text(scene);
  text.replace(text.find("rate: 100 /s"), 12, "rate: 200 /s");
  std::ofstream(scene) << text;
  ASSERT_EQ(test::ces_sim(study).code, 0);
  EXPECT_GT(fed(), before);
}

// A case that failed has no figures: its row of study.csv is empty past
// "complete" (it read zeros, perfect agreement). A failed reference is
// named, as is a --reference that did not complete.
TEST(Study, FailedCasesAndReferencesAreNamedNotZero) {
  const path dir = test::fresh_dir("study_failed");
  const std::string base = "study " + kScene + " --set time.until=collected -o ";
  const test::Outcome one = test::ces_sim(base + (dir / "one").string() +
                                          " --vary time.step:time.end=1ms:0.05s,0.5ms:0.3s");
  EXPECT_EQ(one.code, 3) << one.err;
  const auto rows = read_csv(dir / "one" / "study.csv");
  ASSERT_EQ(rows.size(), 3u);
  const std::size_t complete =
      std::size_t(std::find(rows[0].begin(), rows[0].end(), "complete") - rows[0].begin());
  ASSERT_LT(complete, rows[1].size());
  EXPECT_EQ(rows[1][complete], "false");
  for (std::size_t i = complete + 1; i < rows[1].size(); ++i)
    EXPECT_EQ(rows[1][i], "") << rows[0][i];
  EXPECT_EQ(rows[2][complete], "true");

  const test::Outcome finest = test::ces_sim(base + (dir / "two").string() +
                                             " --vary time.step:time.end=1ms:0.3s,0.5ms:0.05s");
  EXPECT_EQ(finest.code, 3);
  EXPECT_NE(finest.err.find("the reference, the finest case, " + (dir / "two" / "case_1").string() +
                            ", did not complete"),
            std::string::npos)
      << finest.err;

  const path failed = dir / "one" / "case_0" / "partial";
  const test::Outcome given =
      test::ces_sim("study " + kScene + " --vary time.step=1ms,2ms --reference " + failed.string() +
                    " -o " + (dir / "three").string());
  EXPECT_EQ(given.code, 2);
  EXPECT_NE(given.err.find("does not say the run completed"), std::string::npos) << given.err;
}

// --list-cases: one line per case, K then its --set list; --case K runs that
// case only; the full study then reuses it rather than running it again.
TEST(Study, ListAndSelectCases) {
  const path dir = test::fresh_dir("study_cases");
  const std::string base = "study " + kScene + kSteps + " -o " + dir.string();
  const test::Outcome list = test::ces_sim(base + " --vary solver.max_iterations=25,50 --list-cases");
  ASSERT_EQ(list.code, 0) << list.err;
  EXPECT_EQ(std::count(list.out.begin(), list.out.end(), '\n'), 6);
  EXPECT_NE(list.out.find("3  --set time.step=1ms --set solver.max_iterations=50\n"),
            std::string::npos)
      << list.out;

  ASSERT_EQ(test::ces_sim(base + " --case 1").code, 0);
  EXPECT_TRUE(test::fs::exists(dir / "case_1" / "summary.json"));
  EXPECT_FALSE(test::fs::exists(dir / "case_0"));
  EXPECT_FALSE(test::fs::exists(dir / "study.csv"));
  const auto stamp = test::fs::last_write_time(dir / "case_1" / "summary.json");

  ASSERT_EQ(test::ces_sim(base).code, 0);
  EXPECT_TRUE(test::fs::exists(dir / "study.csv"));
  EXPECT_EQ(test::fs::last_write_time(dir / "case_1" / "summary.json"), stamp);
  EXPECT_EQ(test::ces_sim(base + " --case 3").code, 2);  // out of range
}

// A scheduler's --case commands name the scene and the folders absolute; the
// measuring command may name them relative to where it runs, and still
// finds the cases they ran, and runs none of them again.
TEST(Study, ARelativeCommandFindsTheCasesTheSchedulerRan) {
  const path dir = test::fresh_dir("study_relative");
  const std::string absolute = "study " + kScene + kSteps + " -o " + dir.string();
  for (int k = 0; k < 3; ++k)
    ASSERT_EQ(test::ces_sim(absolute + " --case " + std::to_string(k)).code, 0);
  const auto stamp = test::fs::last_write_time(dir / "case_0" / "summary.json");
  const std::string relative = "study " + test::fs::relative(kScene).string() + kSteps + " -o " +
                               test::fs::relative(dir).string();
  ASSERT_EQ(test::ces_sim(relative).code, 0);
  EXPECT_EQ(test::fs::last_write_time(dir / "case_0" / "summary.json"), stamp);
  EXPECT_TRUE(test::fs::exists(dir / "study.csv"));
}

// The commands a scheduler runs carry the study's --include-path.
TEST(Study, SchedulersPassOnTheIncludePaths) {
  const path dir = test::fresh_dir("study_scheduled");
  const std::string folder = std::string(CES_TEST_DIR) + "/scenes";
  const test::Outcome r = test::ces_sim("study " + kScene + kSteps + " --include-path " + folder +
                                        " --scheduler slurm -o " + dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string commands = test::read_text(dir / "cases.sh");
  EXPECT_NE(commands.find("'--include-path' '" + test::fs::absolute(folder).lexically_normal().string() + "'"),
            std::string::npos)
      << commands;
  EXPECT_NE(r.out.find("--include-path"), std::string::npos) << r.out;
}

// study.csv without its wall_time_s column: everything a study measures
// but the time it took, which no two runs share.
std::string without_wall_time(const path& file) {
  auto rows = read_csv(file);
  const auto at = std::find(rows[0].begin(), rows[0].end(), "wall_time_s") - rows[0].begin();
  std::string text;
  for (auto& row : rows) {
    row.erase(row.begin() + at);
    for (const std::string& cell : row) text += cell + ",";
    text += "\n";
  }
  return text;
}

// The serial study and another study of the same grid agree: study.csv
// byte for byte but the wall times, each case's bins and products byte for
// byte.
void expect_same_study(const path& serial, const path& other, std::size_t cases) {
  EXPECT_EQ(without_wall_time(serial / "study.csv"), without_wall_time(other / "study.csv"));
  for (std::size_t k = 0; k < cases; ++k) {
    const path a = serial / ("case_" + std::to_string(k)), b = other / ("case_" + std::to_string(k));
    EXPECT_EQ(test::read_text(a / "bins.csv"), test::read_text(b / "bins.csv")) << k;
    EXPECT_EQ(test::read_text(a / "products.csv"), test::read_text(b / "products.csv")) << k;
  }
}

path serial_study(const std::string& name) {
  const path dir = test::fresh_dir(name);
  const test::Outcome r = test::ces_sim("study " + kScene + kSteps + " --jobs 1 -o " + dir.string());
  EXPECT_EQ(r.code, 0) << r.err;
  return dir;
}

// GNU parallel on 2 processes runs the same cases as the serial study.
TEST(Study, GnuParallelGivesTheSerialStudy) {
  const path serial = serial_study("study_serial_p");
  const path dir = test::fresh_dir("study_parallel");
  const test::Outcome r = test::ces_sim("study " + kScene + kSteps +
                                        " --scheduler parallel --jobs 2 -o " + dir.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string commands = test::read_text(dir / "cases.sh");
  EXPECT_EQ(std::count(commands.begin(), commands.end(), '\n'), 3);
  // Each case's share of the cores, 2 jobs at a time.
  const int share = std::max(1, int(std::thread::hardware_concurrency()) / 2);
  EXPECT_NE(commands.find("'--threads' '" + std::to_string(share) + "'"), std::string::npos)
      << commands;
  expect_same_study(serial, dir, 3);
}

// The Slurm script, run here as the array would run it (one task per
// SLURM_ARRAY_TASK_ID), then the measuring command: the serial study.
TEST(Study, SlurmArrayGivesTheSerialStudy) {
  const path serial = serial_study("study_serial_s");
  const path dir = test::fresh_dir("study_slurm");
  const std::string base = "study " + kScene + kSteps + " -o " + dir.string();
  const test::Outcome r = test::ces_sim(base + " --scheduler slurm");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("sbatch --parsable"), std::string::npos) << r.out;
  const std::string script = test::read_text(dir / "study.sbatch");
  EXPECT_NE(script.find("#SBATCH --array=0-2\n"), std::string::npos) << script;
  EXPECT_FALSE(test::fs::exists(dir / "case_0"));
  for (int task = 0; task < 3; ++task) {
    const std::string command = "SLURM_ARRAY_TASK_ID=" + std::to_string(task) + " bash " +
                                (dir / "study.sbatch").string() + " > /dev/null 2>&1";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
  }
  ASSERT_EQ(test::ces_sim(base).code, 0);
  expect_same_study(serial, dir, 3);
}

}  // namespace
}  // namespace ces
