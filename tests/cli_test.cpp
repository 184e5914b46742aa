// End to end: the ces-sim binary on the tiny scenes of tests/scenes/. File
// formats, exit codes, the VTK round trip, compare, and determinism across
// runs, thread counts and YAML/JSON.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "output/compare.hpp"
#include "output/tables.hpp"
#include "support.hpp"

namespace {

namespace fs = std::filesystem;

const std::string kBinary = CES_SIM_BINARY;
const fs::path kScenes = fs::path(CES_TEST_DIR) / "scenes";

using ces::test::ces_sim;
using ces::test::fresh_dir;
using ces::test::Outcome;
using ces::test::read_text;

std::string scene(const char* name) { return (kScenes / name).string(); }

// A run of tiny.yaml into a folder of its own, once per name and process.
const fs::path& tiny_run(const std::string& name, const std::string& extra = "") {
  static std::map<std::string, fs::path> done;
  if (auto it = done.find(name); it != done.end()) return it->second;
  const fs::path dir = fresh_dir(name);
  const Outcome o = ces_sim(scene("tiny.yaml") + " -o " + dir.string() + " --quiet " + extra);
  EXPECT_EQ(o.code, 0) << o.err;
  return done[name] = dir;
}

// --- A small XML reader: enough for VTK's XML files. ---------------------

struct Element {
  std::string name;
  std::map<std::string, std::string> attributes;
  std::string text;
  std::vector<Element> children;

  const Element* child(const std::string& n) const {
    for (const Element& c : children)
      if (c.name == n) return &c;
    return nullptr;
  }
};

class XmlReader {
 public:
  explicit XmlReader(std::string text) : s_(std::move(text)) {}

  Element document() {
    skip_prolog();
    return element();
  }

 private:
  void skip_space() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  void skip_prolog() {
    skip_space();
    while (s_.compare(i_, 2, "<?") == 0 || s_.compare(i_, 4, "<!--") == 0) {
      i_ = s_.find('>', i_) + 1;
      skip_space();
    }
  }
  void expect(char c) {
    if (i_ >= s_.size() || s_[i_] != c)
      throw std::runtime_error(std::string("XML: expected '") + c + "' at " + std::to_string(i_));
    ++i_;
  }
  std::string name() {
    const std::size_t start = i_;
    while (i_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[i_])) || s_[i_] == '_' ||
                              s_[i_] == ':' || s_[i_] == '-'))
      ++i_;
    if (i_ == start) throw std::runtime_error("XML: expected a name at " + std::to_string(i_));
    return s_.substr(start, i_ - start);
  }
  Element element() {
    Element e;
    expect('<');
    e.name = name();
    for (skip_space(); s_[i_] != '>' && s_[i_] != '/'; skip_space()) {
      const std::string key = name();
      skip_space();
      expect('=');
      skip_space();
      expect('"');
      const std::size_t end = s_.find('"', i_);
      e.attributes[key] = s_.substr(i_, end - i_);
      i_ = end + 1;
    }
    if (s_[i_] == '/') {
      expect('/');
      expect('>');
      return e;
    }
    expect('>');
    for (;;) {
      const std::size_t lt = s_.find('<', i_);
      e.text += s_.substr(i_, lt - i_);
      i_ = lt;
      if (s_.compare(i_, 2, "</") == 0) break;
      e.children.push_back(element());
    }
    i_ += 2;
    if (name() != e.name) throw std::runtime_error("XML: mismatched </" + e.name + ">");
    expect('>');
    return e;
  }

  std::string s_;
  std::size_t i_ = 0;
};

// --- Tests ----------------------------------------------------------------

TEST(Cli, VersionSchemaAndHelp) {
  const Outcome v = ces_sim("--version");
  EXPECT_EQ(v.code, 0);
  EXPECT_NE(v.out.find("ces-sim " CES_VERSION), std::string::npos) << v.out;

  const Outcome s = ces_sim("schema");
  EXPECT_EQ(s.code, 0);
  const nlohmann::json schema = nlohmann::json::parse(s.out);
  EXPECT_TRUE(schema.contains("properties"));

  const Outcome h = ces_sim("--help");
  EXPECT_EQ(h.code, 0);
  EXPECT_NE(h.out.find("Exit codes"), std::string::npos);
}

TEST(Cli, ValidateSaysOkOrListsEveryProblemWithItsLine) {
  const Outcome ok = ces_sim("validate " + scene("tiny.yaml"));
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_NE(ok.out.find("OK"), std::string::npos);

  for (const char* command : {"validate ", ""}) {
    const Outcome bad = ces_sim(command + scene("bad.yaml"));
    EXPECT_EQ(bad.code, 2);
    // Every line: file:line:col: key.path: message.
    const std::regex diagnostic(R"(^.*bad\.yaml:(\d+):(\d+): ([^ ]+): .+$)");
    std::istringstream lines(bad.err);
    std::set<std::string> flagged;
    int n = 0;
    for (std::string line; std::getline(lines, line); ++n) {
      std::smatch m;
      ASSERT_TRUE(std::regex_match(line, m, diagnostic)) << line;
      flagged.insert(m[1].str() + " " + m[3].str());
    }
    EXPECT_GE(n, 2);
    EXPECT_TRUE(flagged.count("6 materials.copper.density")) << bad.err;
    EXPECT_TRUE(flagged.count("9 feeds.0.rte") || flagged.count("9 feeds[0].rte")) << bad.err;
  }
}

TEST(Cli, BadArgumentsExitTwo) {
  EXPECT_EQ(ces_sim("").code, 2);
  EXPECT_EQ(ces_sim("--no-such-option " + scene("tiny.yaml")).code, 2);
  EXPECT_EQ(ces_sim(scene("tiny.yaml") + " --set nonsense").code, 2);
  EXPECT_EQ(ces_sim(scene("tiny.yaml") + " --unset no.such.key").code, 2);
  EXPECT_EQ(ces_sim(scene("tiny.yaml") + " --threads 100000").code, 2);
  EXPECT_EQ(ces_sim("compare /nonexistent/a /nonexistent/b").code, 2);
  // An output folder's path through a file is the user's to change, not a
  // failed run.
  const fs::path file = fresh_dir("out_is_a_file") / "file";
  std::ofstream(file) << "mine\n";
  for (const std::string& command : {std::string(), std::string("study --vary seed=1,2 ")})
    for (const fs::path& out : {file, file / "run"}) {
      const Outcome o = ces_sim(command + scene("tiny.yaml") + " -o " + out.string());
      EXPECT_EQ(o.code, 2) << command << o.err;
      EXPECT_NE(o.err.find(file.string() + " is not a folder"), std::string::npos) << o.err;
    }
  EXPECT_EQ(read_text(file), "mine\n");
}

// A mistyped command is named as such, not taken for a scene followed by
// an unexpected argument; an empty output folder is not the scene's own.
TEST(Cli, MistakesAreNamedForWhatTheyAre) {
  // Options before the word (flags, and options with their values) are
  // passed over; a file of that name would be a scene.
  for (const std::string before :
       {"", "--threads 2 ", "--threads=2 -q ", "-o out/x --seed 3 ", "-qo out/x "}) {
    const Outcome typo = ces_sim(before + "valdate " + scene("tiny.yaml"));
    EXPECT_EQ(typo.code, 2) << before;
    EXPECT_NE(typo.err.find("'valdate' is neither a command (validate, schema, compare, resume, "
                            "study) nor a scene file"),
              std::string::npos)
        << before << "\n"
        << typo.err;
  }
  // Option values before a command are not taken for the command.
  for (const std::string before : {"-qo out/x ", "--set time.end=1s --set seed=3 "}) {
    const Outcome ok = ces_sim(before + "validate " + scene("tiny.yaml"));
    EXPECT_EQ(ok.code, 0) << before << "\n" << ok.err;
  }
  // A repeatable option takes one value: the scene after it is the scene.
  const Outcome set_first = ces_sim("--set time.end=0.01s " + scene("tiny.yaml") + " -q -o " +
                                    fresh_dir("set_first").string());
  EXPECT_EQ(set_first.code, 0) << set_first.err;
  for (const std::string& args :
       {scene("tiny.yaml") + " -o ''", "study " + scene("tiny.yaml") + " --vary seed=1,2 -o ''"}) {
    const Outcome empty = ces_sim(args);
    EXPECT_EQ(empty.code, 2) << args;
    EXPECT_NE(empty.err.find("--out: got '', expected a folder"), std::string::npos) << args << "\n"
                                                                                     << empty.err;
  }
}

// Numbers on the command line are checked as written: a negative count is
// not wrapped into a huge tolerance, NaN is no tolerance, and the message
// names the option, the text and the range.
TEST(Cli, NumbersOutOfRangeAreRefusedAsWritten) {
  const std::pair<std::string, std::string> cases[] = {
      {"compare a b --tol-count -1", "--tol-count: got '-1', expected a whole number >= 0"},
      {"compare a b --tol-count 2.5", "--tol-count: got '2.5', expected a whole number >= 0"},
      {"compare a b --tol-mass nan", "--tol-mass: got 'nan', expected a number >= 0"},
      {"compare a b --tol-w1 -1", "--tol-w1: got '-1', expected a number >= 0"},
      {"study " + scene("tiny.yaml") + " --vary seed=1,2 --jobs 0",
       "--jobs: got '0', expected a whole number from 1 to 2147483647"},
      {"study " + scene("tiny.yaml") + " --vary seed=1,2 --jobs 4294967297",
       "--jobs: got '4294967297', expected a whole number from 1 to 2147483647"},
      {"study " + scene("tiny.yaml") + " --vary seed=1,2 --case -1",
       "--case: got '-1', expected a whole number >= 0"},
      {scene("tiny.yaml") + " --threads 010",
       "--threads: got '010', expected a whole number from 1 "
       "to 1024"},
      {scene("tiny.yaml") + " --threads 0x10",
       "--threads: got '0x10', expected a whole number "
       "from 1 to 1024"},
      {scene("tiny.yaml") + " --seed -1",
       "--seed: got '-1', expected a whole number from 0 to 9223372036854775807"},
      {scene("tiny.yaml") + " --seed 010",
       "--seed: got '010', expected a whole number from 0 to 9223372036854775807"},
      {scene("tiny.yaml") + " --seed 9223372036854775808",
       "--seed: got '9223372036854775808', expected a whole number from 0 to "
       "9223372036854775807"},
      {"compare a b --tol-count 1e3", "--tol-count: got '1e3', expected a whole number >= 0"},
  };
  for (const auto& [args, message] : cases) {
    const Outcome o = ces_sim(args);
    EXPECT_EQ(o.code, 2) << args;
    EXPECT_NE(o.err.find(message), std::string::npos) << args << "\n" << o.err;
  }
}

// Scenes past a bound are refused before anything runs: by validate and
// by a run alike, exit 2, one line per problem, no output folder made.
TEST(Cli, HostileScenesAreRefusedByValidateAndByRun) {
  const fs::path bad = fs::path(CES_TEST_DIR) / "bad_scenes";
  const std::pair<const char*, const char*> cases[] = {
      {"too_many_steps.yaml", "too_many_steps.yaml:3:9: time.step: a step of 1e-06 s makes"},
      {"feed_rate_too_high.yaml", "feed_rate_too_high.yaml:9:11: feeds[0].rate: feed 'feeder'"},
      {"alias_bomb.yaml", "alias_bomb.yaml:4:"},
      {"include_outside.yaml", "include_outside.yaml:4:5: include: '/etc/passwd' is outside"},
      {"integer_wraps.yaml", "integer_wraps.yaml:3:26: solver.max_iterations: 2147483648"},
      {"two_documents.yaml", "two_documents.yaml:4:1: a second YAML document"},
  };
  for (const auto& [file, message] : cases) {
    SCOPED_TRACE(file);
    const fs::path out = fresh_dir(std::string("hostile_") + file) / "out";
    for (const std::string& command :
         {"validate " + (bad / file).string(), (bad / file).string() + " -o " + out.string()}) {
      const Outcome o = ces_sim(command);
      EXPECT_EQ(o.code, 2) << o.err;
      EXPECT_NE(o.err.find(message), std::string::npos) << o.err;
      EXPECT_EQ(o.err.find("root:"), std::string::npos) << o.err;
    }
    EXPECT_FALSE(fs::exists(out));
  }
}

// Includes come from the scene's folder, or one named by --include-path.
TEST(Cli, IncludePathNamesAnotherFolderForIncludes) {
  const fs::path scenes = fs::path(CES_TEST_DIR).parent_path() / "scenes";
  const std::string scene = (scenes / "validation" / "ces_feedrate.yaml").string();
  const Outcome refused = ces_sim("validate " + scene);
  EXPECT_EQ(refused.code, 2);
  EXPECT_NE(refused.err.find("include: '../machines/ces_machine.yaml' is outside the folder of "
                             "ces_feedrate.yaml"),
            std::string::npos)
      << refused.err;
  const Outcome ok = ces_sim("validate " + scene + " --include-path " + scenes.string());
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(ces_sim("validate " + scene + " --include-path /nonexistent/folder").code, 2);
}

// Warnings go to stderr, one per line; the scene still validates and runs.
TEST(Cli, WarningsDoNotStopAScene) {
  const fs::path dir = fresh_dir("warning_scene");
  std::ofstream(dir / "s.yaml") << "ces_sim: 1\ntime: {step: 1 ms, end: 2 ms}\n"
                                   "materials: {copper: {density: 8960 kg/m^3}}\n"
                                   "feeds:\n"
                                   "  - name: f\n"
                                   "    region: {box: {min: [0, 0, 0], max: [0.01, 0.01, 0.01]}}\n"
                                   "    rate: 1000 /s\n"
                                   "    mix: [{material: copper, size: {constant: 1 mm}}]\n";
  const std::string warning =
      "s.yaml:4:1: warning: feeds: particles are fed but the scene gives "
      "no gravity";
  const Outcome v = ces_sim("validate " + (dir / "s.yaml").string());
  EXPECT_EQ(v.code, 0) << v.err;
  EXPECT_NE(v.out.find("OK"), std::string::npos);
  EXPECT_NE(v.err.find(warning), std::string::npos) << v.err;
  const Outcome r = ces_sim((dir / "s.yaml").string() + " -o " + (dir / "out").string() + " -q");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find(warning), std::string::npos) << r.err;
}

TEST(Cli, RunWritesTheOutputFilesInTheirFormats) {
  const fs::path& dir = tiny_run("formats");
  const nlohmann::json s = nlohmann::json::parse(read_text(dir / "summary.json"));
  EXPECT_TRUE(s["complete"].get<bool>());
  EXPECT_EQ(s["version"], CES_VERSION);
  EXPECT_EQ(s["seed"], 11);
  EXPECT_EQ(s["steps"], 400);
  EXPECT_TRUE(s["balance"]["exact"].get<bool>());
  EXPECT_GT(s["balance"]["collected"]["count"].get<int>(), 50);
  for (const char* key : {"wall_time_s", "solver", "feeds", "spawn", "collectors",
                          "active_components", "warnings", "scene", "threads"})
    EXPECT_TRUE(s.contains(key)) << key;

  // Tidy: a row per bin (20) or product (2) and material (2).
  const std::string bins = read_text(dir / "bins.csv");
  EXPECT_EQ(bins.substr(0, bins.find('\n')), "collector,bin,from_m,to_m,material,count,mass_kg");
  EXPECT_EQ(std::count(bins.begin(), bins.end(), '\n'), 41);
  const std::string products = read_text(dir / "products.csv");
  EXPECT_EQ(products.substr(0, products.find('\n')),
            "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery,grade_se,"
            "recovery_se");
  EXPECT_EQ(std::count(products.begin(), products.end(), '\n'), 5);
  const std::string crossings = read_text(dir / "crossings.csv");
  EXPECT_EQ(crossings.substr(0, crossings.find('\n')),
            "id,time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,along_m,diameter_m,mass_kg,material,"
            "charge_c,collector,bin,product");
  EXPECT_EQ(std::count(crossings.begin(), crossings.end(), '\n'),
            s["balance"]["collected"]["count"].get<int>() + 1);
  const std::string steps = read_text(dir / "steps.csv");
  EXPECT_EQ(std::count(steps.begin(), steps.end(), '\n'), 401);
  EXPECT_FALSE(read_text(dir / "scene.resolved.yaml").empty());
  EXPECT_TRUE(fs::exists(dir / "trajectories.csv"));

  const Element svg = XmlReader(read_text(dir / "distribution.svg")).document();
  EXPECT_EQ(svg.name, "svg");
  int paths = 0;
  for (const Element& e : svg.children) paths += e.name == "path";
  EXPECT_EQ(paths, 2);  // one line per material
}

// The tidy tables hold what the summary reports: every collected particle
// in a bin or outside them, and each product's main material (its largest
// mass) with the summary's grade and recovery.
TEST(Cli, TidyTablesAgreeWithTheSummary) {
  const fs::path& dir = tiny_run("formats");
  const nlohmann::json s = nlohmann::json::parse(read_text(dir / "summary.json"));
  const nlohmann::json& tray = s["collectors"][0];
  const ces::output::Table bins = ces::output::read_table(dir / "bins.csv");
  std::uint64_t binned = 0;
  for (const auto& row : bins.rows) binned += std::stoull(row[5]);
  EXPECT_EQ(binned + tray["outside_bins"]["count"].get<std::uint64_t>(),
            tray["collected"]["count"].get<std::uint64_t>());

  const ces::output::Table products = ces::output::read_table(dir / "products.csv");
  ASSERT_EQ(products.rows.size(), 4u);
  for (std::size_t p = 0; p < 2; ++p) {
    const auto& copper = products.rows[2 * p];
    const auto& fr4 = products.rows[2 * p + 1];
    const auto& main = std::stod(copper[6]) >= std::stod(fr4[6]) ? copper : fr4;
    const nlohmann::json& summary = tray["products"][p];
    EXPECT_EQ(main[1], summary["name"]);
    EXPECT_EQ(main[4], summary["main_material"]);
    EXPECT_NEAR(std::stod(main[7]), summary["grade"].get<double>(), 1e-9);
    EXPECT_NEAR(std::stod(main[8]), summary["recovery"].get<double>(), 1e-9);
    EXPECT_NEAR(std::stod(main[9]), summary["grade_se"].get<double>(), 1e-9);
    EXPECT_NEAR(std::stod(main[10]), summary["recovery_se"].get<double>(), 1e-9);
    EXPECT_NEAR(std::stod(copper[7]) + std::stod(fr4[7]), 1.0, 1e-8);  // grades add up to 1
    EXPECT_NEAR(std::stod(copper[6]) + std::stod(fr4[6]), summary["mass_kg"].get<double>(),
                1e-9 * summary["mass_kg"].get<double>());
  }
}

// Each product's standard errors follow from the particles of
// crossings.csv and lost.csv: their masses' sums and sums of squares per
// product and material, per product, and per material (collected anywhere
// or lost), into ratio_standard_error. 1e-7 relative, plus 1e-12: the
// files' masses have 9 significant digits.
TEST(Cli, ProductStandardErrorsFollowFromTheParticles) {
  const fs::path& dir = tiny_run("formats");
  struct Sums {
    double kg = 0.0, squares = 0.0;
    std::uint64_t n = 0;
    void add(double m) {
      kg += m;
      squares += m * m;
      ++n;
    }
  };
  std::map<std::string, Sums> cell, product, material;  // keyed "product/material", ...
  const ces::output::Table crossings = ces::output::read_table(dir / "crossings.csv");
  const ces::output::Table lost = ces::output::read_table(dir / "lost.csv");
  for (const ces::output::Table* t : {&crossings, &lost}) {
    const std::size_t mass = t->column("mass_kg", dir), mat = t->column("material", dir);
    const bool collected = t == &crossings;
    const std::size_t prod = collected ? t->column("product", dir) : 0;
    for (const auto& row : t->rows) {
      const double m = std::stod(row[mass]);
      material[row[mat]].add(m);
      if (!collected || row[prod].empty()) continue;
      cell[row[prod] + "/" + row[mat]].add(m);
      product[row[prod]].add(m);
    }
  }
  const ces::output::Table products = ces::output::read_table(dir / "products.csv");
  ASSERT_EQ(products.rows.size(), 4u);
  int spread = 0;
  for (const auto& row : products.rows) {
    const Sums c = cell[row[1] + "/" + row[4]], p = product[row[1]], m = material[row[4]];
    const double grade_se =
        ces::output::ratio_standard_error(c.kg, p.kg, c.squares, p.squares, p.n);
    const double recovery_se =
        ces::output::ratio_standard_error(c.kg, m.kg, c.squares, m.squares, m.n);
    EXPECT_NEAR(std::stod(row[9]), grade_se, 1e-7 * grade_se + 1e-12) << row[1] << " " << row[4];
    EXPECT_NEAR(std::stod(row[10]), recovery_se, 1e-7 * recovery_se + 1e-12)
        << row[1] << " " << row[4];
    spread += grade_se > 0.0 && recovery_se > 0.0;
  }
  EXPECT_GT(spread, 0);  // the run puts some of a material in each product
}

// The XML part of a binary .vtp: everything before its appended data.
Element vtp_header(const fs::path& file) {
  const std::string text = read_text(file);
  const std::size_t appended = text.find("<AppendedData");
  if (appended == std::string::npos) throw std::runtime_error(file.string() + ": no appended data");
  return XmlReader(text.substr(0, appended) + "</VTKFile>").document();
}

// The files' layout; tests/vtk_readback.py reads them with VTK itself.
TEST(Cli, VtkFramesAreBinaryAndThePvdListsEveryFile) {
  const fs::path& dir = tiny_run("formats");
  const Element pvd = XmlReader(read_text(dir / "trajectories.pvd")).document();
  ASSERT_EQ(pvd.attributes.at("type"), "Collection");
  const Element* collection = pvd.child("Collection");
  ASSERT_NE(collection, nullptr);
  // 0, 50, ..., 400 ms, each the particles and the static ramp.
  ASSERT_EQ(collection->children.size(), 2 * 9u);
  std::set<std::string> listed, on_disk;
  for (const Element& dataset : collection->children)
    listed.insert(dataset.attributes.at("file"));
  for (const auto& e : fs::directory_iterator(dir / "trajectories"))
    on_disk.insert("trajectories/" + e.path().filename().string());
  EXPECT_EQ(listed, on_disk);

  std::size_t most_points = 0;
  for (const Element& dataset : collection->children) {
    if (dataset.attributes.at("name") != "particles") continue;
    const Element vtp = vtp_header(dir / dataset.attributes.at("file"));
    ASSERT_EQ(vtp.attributes.at("type"), "PolyData");
    EXPECT_EQ(vtp.attributes.at("compressor"), "vtkZLibDataCompressor");
    const Element* piece = vtp.child("PolyData")->child("Piece");
    ASSERT_NE(piece, nullptr);
    const std::size_t n = std::stoul(piece->attributes.at("NumberOfPoints"));
    EXPECT_EQ(piece->attributes.at("NumberOfVerts"), std::to_string(n));
    most_points = std::max(most_points, n);
    std::set<std::string> arrays;
    for (const Element& a : piece->child("PointData")->children) {
      arrays.insert(a.attributes.at("Name"));
      EXPECT_EQ(a.attributes.at("format"), "appended");
    }
    const std::set<std::string> expected = {
        "id",         "diameter",    "material", "material_name",    "shape",  "shape_name",
        "orientation", "velocity", "angular_velocity", "charge", "birth"};
    EXPECT_EQ(arrays, expected);
  }
  EXPECT_GT(most_points, 10u);
}

TEST(Cli, CompareAgreesOnEqualRunsAndDiffersAcrossSeeds) {
  const fs::path& a = tiny_run("formats");
  const fs::path& b = tiny_run("again");
  const Outcome same = ces_sim("compare " + a.string() + " " + b.string());
  EXPECT_EQ(same.code, 0) << same.out;
  EXPECT_NE(same.out.find("AGREE"), std::string::npos);

  const fs::path& c = tiny_run("seed12", "--seed 12");
  const Outcome diff = ces_sim("compare " + a.string() + " " + c.string());
  EXPECT_EQ(diff.code, 1) << diff.out;
  EXPECT_NE(diff.out.find("DIFFER"), std::string::npos);
  EXPECT_NE(diff.out.find("bins.csv"), std::string::npos);
  // Loose enough tolerances accept the other seed.
  EXPECT_EQ(ces_sim("compare " + a.string() + " " + c.string() +
                    " --tol-count 1000 --tol-mass 1 --tol-w1 1000")
                .code,
            0);
}

// The tables of a run that stopped, or whose summary.json is gone, are
// compared as they are, and the comparison says what they are.
TEST(Cli, CompareSaysWhichRunsDidNotComplete) {
  const fs::path& a = tiny_run("formats");
  const fs::path stopped = fresh_dir("compare_stopped");
  for (const char* name : {"bins.csv", "products.csv", "crossings.csv"})
    fs::copy_file(a / name, stopped / name);
  const Outcome unknown = ces_sim("compare " + a.string() + " " + stopped.string());
  EXPECT_EQ(unknown.code, 0) << unknown.out;
  EXPECT_NE(unknown.out.find(stopped.string() + ": no summary.json"), std::string::npos)
      << unknown.out;
  EXPECT_EQ(unknown.out.find(a.string() + ": "), std::string::npos) << unknown.out;
  std::ofstream(stopped / "summary.json")
      << R"({"complete": false, "reason": "interrupted by SIGINT"})";
  const Outcome interrupted = ces_sim("compare " + a.string() + " " + stopped.string());
  EXPECT_NE(
      interrupted.out.find(stopped.string() + ": its run did not complete (interrupted by SIGINT)"),
      std::string::npos)
      << interrupted.out;
}

// A folder whose tables are not ces-sim's is refused, naming the file,
// the line and what was expected, never compared as numbers it lacks.
TEST(Cli, CompareRefusesTablesItDoesNotKnow) {
  const fs::path& a = tiny_run("formats");
  const fs::path b = fresh_dir("compare_garbage");
  for (const char* name : {"bins.csv", "products.csv", "crossings.csv"})
    fs::copy_file(a / name, b / name);
  const auto expect_refused = [&](const std::string& message) {
    const Outcome o = ces_sim("compare " + a.string() + " " + b.string());
    EXPECT_EQ(o.code, 2) << o.out;
    EXPECT_NE(o.err.find(message), std::string::npos) << o.err;
  };
  std::ofstream(b / "bins.csv") << "garbage\n1\n";
  expect_refused((b / "bins.csv").string() +
                 ":1: expected the header collector,bin,from_m,to_m,material,count,mass_kg, "
                 "found 'garbage'");
  fs::copy_file(a / "bins.csv", b / "bins.csv", fs::copy_options::overwrite_existing);
  // products.csv has two headers it reads (with and without the standard
  // errors): the message names both.
  std::ofstream(b / "products.csv") << "collector,product\n";
  expect_refused((b / "products.csv").string() +
                 ":1: expected the header "
                 "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery,grade_se,"
                 "recovery_se or collector,product,from_m,to_m,material,count,mass_kg,grade,"
                 "recovery, found 'collector,product'");
  std::string products = read_text(a / "products.csv");
  std::size_t cell = products.find('\n') + 1;  // row 2's grade: its eighth field
  for (int field = 0; field < 7; ++field) cell = products.find(',', cell) + 1;
  products.replace(cell, products.find(',', cell) - cell, "pure");
  std::ofstream(b / "products.csv") << products;
  expect_refused((b / "products.csv").string() + ":2: grade is not a finite number: 'pure'");
  fs::copy_file(a / "products.csv", b / "products.csv", fs::copy_options::overwrite_existing);
  std::string crossings = read_text(a / "crossings.csv");
  const std::size_t row = crossings.find('\n') + 1;
  crossings.insert(row, "1,0.1,0,0,0,0,0,0,far,0.001,1e-06,copper,0,tray,0,near\n");
  std::ofstream(b / "crossings.csv") << crossings;
  expect_refused((b / "crossings.csv").string() + ":2: along_m is not a finite number: 'far'");
  fs::copy_file(a / "crossings.csv", b / "crossings.csv", fs::copy_options::overwrite_existing);
  // A count ces-sim cannot have written, and names or headers whose
  // escape sequences would reach the terminal: refused, never echoed.
  const std::string bins = read_text(a / "bins.csv");
  const auto with_row2 = [&](int field, const std::string& value) {
    std::string text = bins;
    std::size_t at = text.find('\n') + 1;
    for (int f = 0; f < field; ++f) at = text.find(',', at) + 1;
    text.replace(at, text.find_first_of(",\n", at) - at, value);
    std::ofstream(b / "bins.csv") << text;
  };
  with_row2(5, "-5");
  expect_refused((b / "bins.csv").string() + ":2: count is -5, expected a whole count >= 0");
  with_row2(5, "1.5");
  expect_refused((b / "bins.csv").string() + ":2: count is 1.5, expected a whole count >= 0");
  with_row2(4, "cop\x1b[2Jper");
  expect_refused((b / "bins.csv").string() + ":2: material holds a control character");
  std::ofstream(b / "bins.csv") << "coll\x1b[2Jector\n";
  expect_refused("found text with control characters");
  const Outcome o = ces_sim("compare " + a.string() + " " + b.string());
  EXPECT_EQ(o.err.find('\x1b'), std::string::npos);
}

// A products.csv from before the grades' and recoveries' standard errors
// still compares, on the columns both folders have, and says which it
// left out: a baseline kept from then stays usable.
TEST(Cli, CompareReadsProductsFromBeforeTheStandardErrors) {
  const fs::path& a = tiny_run("formats");
  const fs::path b = fresh_dir("compare_older");
  for (const char* name : {"bins.csv", "products.csv", "crossings.csv"})
    fs::copy_file(a / name, b / name);
  std::istringstream rows(read_text(a / "products.csv"));
  std::vector<std::string> older;
  for (std::string line; std::getline(rows, line);)
    older.push_back(line.substr(0, line.rfind(',', line.rfind(',') - 1)));
  const auto write = [&] {
    std::ofstream out(b / "products.csv");
    for (const std::string& line : older) out << line << '\n';
  };
  write();
  ASSERT_EQ(older[0], "collector,product,from_m,to_m,material,count,mass_kg,grade,recovery");
  const std::string left_out = "products.csv: grade_se, recovery_se only in ";
  const Outcome forward = ces_sim("compare " + a.string() + " " + b.string());
  EXPECT_EQ(forward.code, 0) << forward.out << forward.err;
  EXPECT_NE(forward.out.find(left_out + "A (the other written before them): not compared"),
            std::string::npos)
      << forward.out;
  const Outcome backward = ces_sim("compare " + b.string() + " " + a.string());
  EXPECT_EQ(backward.code, 0) << backward.out << backward.err;
  EXPECT_NE(backward.out.find(left_out + "B"), std::string::npos) << backward.out;
  // The shared columns are still compared: row 2's recovery, its last.
  older[1] = older[1].substr(0, older[1].rfind(',') + 1) + "0.123";
  write();
  const Outcome changed = ces_sim("compare " + a.string() + " " + b.string());
  EXPECT_EQ(changed.code, 1) << changed.out;
  EXPECT_NE(changed.out.find("recovery: "), std::string::npos) << changed.out;
  EXPECT_NE(changed.out.find(left_out + "A"), std::string::npos) << changed.out;
}

void expect_same_tables(const fs::path& a, const fs::path& b) {
  for (const char* name : {"bins.csv", "products.csv", "crossings.csv"})
    EXPECT_EQ(read_text(a / name), read_text(b / name)) << name << ": " << a << " vs " << b;
}

TEST(Cli, SameSceneAndSeedGiveIdenticalBytesAcrossRunsAndThreads) {
  expect_same_tables(tiny_run("formats"), tiny_run("again"));
  // pile.yaml has hundreds of particles and thousands of contacts, so the
  // engine's parallel loops run.
  std::vector<fs::path> dirs;
  for (const std::string threads : {"1", "2"}) {
    const fs::path dir = fresh_dir("pile" + threads);
    const Outcome o =
        ces_sim(scene("pile.yaml") + " -o " + dir.string() + " --quiet --threads " + threads);
    ASSERT_EQ(o.code, 0) << o.err;
    const nlohmann::json s = nlohmann::json::parse(read_text(dir / "summary.json"));
    EXPECT_EQ(s["threads"], std::stoi(threads));
    EXPECT_GT(s["solver"]["particles_max"].get<int>(), 256);
    EXPECT_GT(s["solver"]["contacts_max"].get<int>(), 256);
    EXPECT_GT(s["balance"]["collected"]["count"].get<int>(), 20);
    dirs.push_back(dir);
  }
  expect_same_tables(dirs[0], dirs[1]);
}

TEST(Cli, YamlAndJsonScenesGiveIdenticalOutputs) {
  const fs::path dir = fresh_dir("json");
  const Outcome o = ces_sim(scene("tiny.json") + " -o " + dir.string() + " --quiet");
  ASSERT_EQ(o.code, 0) << o.err;
  expect_same_tables(tiny_run("formats"), dir);
}

TEST(Cli, ReportNamesFatesProductsAndTheOutputFolder) {
  const fs::path dir = fresh_dir("report");
  const Outcome o = ces_sim(scene("tiny.yaml") + " -o " + dir.string());
  ASSERT_EQ(o.code, 0) << o.err;
  for (const char* text :
       {"fed", "collected", "lost", "tray/near", "grade", "recovery", "residual", "penetration"})
    EXPECT_NE(o.out.find(text), std::string::npos) << text << " in\n" << o.out;
  EXPECT_NE(o.out.find("output: " + dir.string()), std::string::npos) << o.out;
  // Not a terminal: progress lines come every 10 s, and the run is shorter.
  EXPECT_TRUE(o.err.empty()) << o.err;
}

// Off a terminal (stderr to a file, as in a batch job's log), a progress
// line every CES_PROGRESS_INTERVAL seconds of wall time, never more often;
// none with --quiet.
TEST(Cli, ProgressLinesInALogAtTheInterval) {
  constexpr double kInterval = 0.05;  // s
  ::setenv("CES_PROGRESS_INTERVAL", "0.05", 1);
  const fs::path dir = fresh_dir("progress");
  const std::string run = scene("tiny.yaml") + " --set time.end=2s --threads 1 -o " + dir.string();
  // The process's own wall time bounds the progress clock, which starts
  // before the run loop that summary.json's wall time counts.
  const auto t0 = std::chrono::steady_clock::now();
  const Outcome o = ces_sim(run);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const Outcome quiet = ces_sim(run + " --quiet");
  ::setenv("CES_PROGRESS_INTERVAL", "soon", 1);
  const Outcome bad = ces_sim(run);
  ::unsetenv("CES_PROGRESS_INTERVAL");
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(quiet.err, "");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("CES_PROGRESS_INTERVAL=soon: expected a number of seconds"),
            std::string::npos)
      << bad.err;

  const std::regex line(
      R"(progress: t (\S+) / 2 s  wall (\S+) s  ETA \d+ s  particles \d+  contacts \d+)");
  std::istringstream lines(o.err);
  std::size_t n = 0;
  double last_t = -1.0;
  for (std::string text; std::getline(lines, text); ++n) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(text, m, line)) << text;  // no terminal control codes
    EXPECT_GT(std::stod(m[1].str()), last_t);
    last_t = std::stod(m[1].str());
  }
  EXPECT_GE(n, 1u) << "a run of " << wall << " s";
  EXPECT_LE(double(n), wall / kInterval + 1.0) << o.err;
}

// A progress line counts a step's particles and contacts as its row of
// steps.csv does: before the step's collection takes the particles that
// crossed a collector (tiny.yaml collects in many of its steps).
TEST(Cli, ProgressLinesCountAsStepsCsvDoes) {
  ::setenv("CES_PROGRESS_INTERVAL", "1e-9", 1);  // a line every step
  const fs::path dir = fresh_dir("progress_counts");
  const Outcome o = ces_sim(scene("tiny.yaml") + " --threads 1 -o " + dir.string());
  ::unsetenv("CES_PROGRESS_INTERVAL");
  ASSERT_EQ(o.code, 0) << o.err;
  std::map<std::string, std::string> counts;  // "%.4g" of time_s -> "particles contacts"
  std::istringstream rows(read_text(dir / "steps.csv"));
  std::string row;
  std::getline(rows, row);  // header: step,time_s,particles,contacts,...
  while (std::getline(rows, row)) {
    std::vector<std::string> f;
    std::istringstream cells(row);
    for (std::string c; std::getline(cells, c, ',');) f.push_back(c);
    char t[32];
    std::snprintf(t, sizeof t, "%.4g", std::stod(f.at(1)));
    counts[t] = f.at(2) + " " + f.at(3);
  }
  const std::regex line(R"(progress: t (\S+) / 0.4 s  .*  particles (\d+)  contacts (\d+))");
  std::istringstream lines(o.err);
  std::size_t n = 0;
  for (std::string text; std::getline(lines, text); ++n) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(text, m, line)) << text;
    EXPECT_EQ(counts[m[1].str()], m[2].str() + " " + m[3].str()) << text;
  }
  EXPECT_GE(n, 100u);
}

// A run until collected ends when its particles are, long before time.end:
// its progress lines give time.end as the cap it is, with no estimate
// taken from it.
TEST(Cli, ProgressUntilCollectedGivesTheCapAndNoEstimate) {
  ::setenv("CES_PROGRESS_INTERVAL", "1e-6", 1);  // a line at every step
  const fs::path dir = fresh_dir("progress_collected");
  const Outcome o = ces_sim(scene("tiny.yaml") +
                            " --set time.end=2s --set time.until=collected --threads 1 -o " +
                            dir.string());
  ::unsetenv("CES_PROGRESS_INTERVAL");
  ASSERT_EQ(o.code, 0) << o.err;
  const std::regex line(
      R"(progress: t (\S+) s \(until collected, at most 2 s\)  wall (\S+) s  particles \d+  contacts \d+)");
  std::istringstream lines(o.err);
  std::size_t n = 0;
  for (std::string text; std::getline(lines, text); ++n)
    ASSERT_TRUE(std::regex_match(text, line)) << text;
  EXPECT_GT(n, 10u);
}

TEST(Cli, SigtermStopsTheRunKeepsItsOutputsAsideAndExitsThree) {
  const fs::path dir = fresh_dir("sigterm");
  const std::string out = dir.string();
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string sc = scene("tiny.yaml");
    ::execl(kBinary.c_str(), kBinary.c_str(), sc.c_str(), "-o", out.c_str(), "--quiet", "--set",
            "time.end=1000 s", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  // The first summary.json (complete: false) appears once the handlers are in.
  const fs::path partial = dir / "partial";
  for (int i = 0; i < 2000 && !fs::exists(partial / "summary.json"); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  ::kill(pid, SIGTERM);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 3);
  const nlohmann::json s = nlohmann::json::parse(read_text(partial / "summary.json"));
  EXPECT_FALSE(s["complete"].get<bool>());
  EXPECT_EQ(s["reason"], "interrupted by SIGTERM");
  EXPECT_TRUE(s["balance"]["exact"].get<bool>());
  for (const char* name :
       {"bins.csv", "products.csv", "crossings.csv", "steps.csv", "trajectories.pvd"})
    EXPECT_TRUE(fs::exists(partial / name)) << name;
  EXPECT_FALSE(fs::exists(dir / "summary.json")) << "an unfinished run publishes nothing";
}

// time.until: collected: the tiny chute's feed stops at 0.1 s and the run
// ends at the first step with every particle collected or lost, well
// before its 2 s cap; then fed = collected + lost exactly, none active.
TEST(Cli, UntilCollectedEndsWhenTheFeedIsAccountedFor) {
  const fs::path dir = fresh_dir("until_collected");
  const Outcome o = ces_sim(scene("tiny.yaml") + " -o " + dir.string() +
                            " --quiet --set time.until=collected --set time.end=2s");
  ASSERT_EQ(o.code, 0) << o.err;
  const nlohmann::json s = nlohmann::json::parse(read_text(dir / "summary.json"));
  EXPECT_TRUE(s["complete"].get<bool>());
  const nlohmann::json& b = s["balance"];
  EXPECT_TRUE(b["exact"].get<bool>());
  const auto count = [&](const char* k) { return b[k]["count"].get<std::uint64_t>(); };
  EXPECT_GT(count("fed"), 20u);
  EXPECT_EQ(count("active"), 0u);
  EXPECT_EQ(count("fed"), count("collected") + count("lost"));
  const double end = s["simulated_time_s"].get<double>();
  EXPECT_GT(end, 0.1);
  EXPECT_LT(end, 1.0);
  // The step before the last still had a particle or a feed running: a run
  // of one step less than this one's is cut by its cap.
  const fs::path cut = fresh_dir("until_collected_cut");
  const Outcome c = ces_sim(scene("tiny.yaml") + " -o " + cut.string() +
                            " --quiet --set time.until=collected --set time.end=" +
                            std::to_string(end - 1e-3) + "s");
  EXPECT_EQ(c.code, 3) << c.err;
}

// The cap comes first: exit 3, the outputs kept aside, and a message at
// where time.end was given (here the second --set) naming what is still
// active and what was expected.
TEST(Cli, UntilCollectedCapFailsTheRunNamingWhatIsLeft) {
  const fs::path dir = fresh_dir("until_collected_cap");
  const Outcome o = ces_sim(scene("tiny.yaml") + " -o " + dir.string() +
                            " --quiet --set time.until=collected --set time.end=0.15s");
  ASSERT_EQ(o.code, 3) << o.err;
  const nlohmann::json s = nlohmann::json::parse(read_text(dir / "partial" / "summary.json"));
  EXPECT_FALSE(s["complete"].get<bool>());
  const std::string reason = s["reason"];
  EXPECT_EQ(reason.rfind("--set:2:1: time.end: ", 0), 0u) << reason;
  EXPECT_NE(reason.find("still active"), std::string::npos) << reason;
  EXPECT_NE(reason.find("expected every particle collected or lost"), std::string::npos) << reason;
  const std::uint64_t active = s["balance"]["active"]["count"];
  EXPECT_NE(reason.find(std::to_string(active) + " particles"), std::string::npos) << reason;
  EXPECT_NE(o.err.find("still active"), std::string::npos) << o.err;
  // Given in the scene file: its file, line and column.
  std::string text = read_text(kScenes / "tiny.yaml");
  const std::string time = "time: {step: 1 ms, end: 0.4 s}";
  text.replace(text.find(time), time.size(), "time: {step: 1 ms, end: 0.15 s, until: collected}");
  const fs::path file = dir / "capped.yaml";
  std::ofstream(file) << text;
  const Outcome f = ces_sim(file.string() + " -o " + (dir / "file").string() + " --quiet");
  EXPECT_EQ(f.code, 3);
  EXPECT_NE(f.err.find("capped.yaml:7:25: time.end: the run reached its end of 0.15 s with "),
            std::string::npos)
      << f.err;
}

// A feed without a duration never stops: refused with its line.
TEST(Cli, UntilCollectedNeedsFeedsThatStop) {
  const fs::path dir = fresh_dir("until_collected_endless");
  std::string text = read_text(kScenes / "tiny.yaml");
  text.replace(text.find("    duration: 0.1 s\n"), std::string("    duration: 0.1 s\n").size(), "");
  const fs::path file = dir / "endless.yaml";
  std::ofstream(file) << text;
  const Outcome o = ces_sim(file.string() + " -o " + (dir / "out").string() +
                            " --quiet --set time.until=collected");
  EXPECT_EQ(o.code, 2);
  EXPECT_NE(o.err.find("endless.yaml:"), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("has no duration"), std::string::npos) << o.err;
}

}  // namespace
