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
#include <sstream>
#include <thread>

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

std::size_t count_numbers(const std::string& text) {
  std::istringstream in(text);
  std::size_t n = 0;
  for (double v; in >> v;) ++n;
  return n;
}

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
  EXPECT_EQ(ces_sim("compare /nonexistent/a /nonexistent/b").code, 2);
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

  const std::string bins = read_text(dir / "bins.csv");
  EXPECT_EQ(bins.substr(0, bins.find('\n')),
            "collector,bin,from_m,to_m,copper_count,copper_kg,fr4_count,fr4_kg");
  EXPECT_EQ(std::count(bins.begin(), bins.end(), '\n'), 21);
  const std::string products = read_text(dir / "products.csv");
  EXPECT_EQ(products.substr(0, products.find('\n')),
            "collector,product,from_m,to_m,copper_kg,fr4_kg,total_kg,main_material,grade,recovery");
  EXPECT_EQ(std::count(products.begin(), products.end(), '\n'), 3);
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

TEST(Cli, VtkFramesParseBackAndThePvdListsEveryFrame) {
  const fs::path& dir = tiny_run("formats");
  const Element pvd = XmlReader(read_text(dir / "trajectories.pvd")).document();
  ASSERT_EQ(pvd.attributes.at("type"), "Collection");
  const Element* collection = pvd.child("Collection");
  ASSERT_NE(collection, nullptr);
  // 0, 50, ..., 400 ms.
  ASSERT_EQ(collection->children.size(), 9u);
  std::size_t frames_on_disk = 0;
  for (const auto& e : fs::directory_iterator(dir / "trajectories"))
    frames_on_disk += e.path().extension() == ".vtp";
  EXPECT_EQ(frames_on_disk, collection->children.size());

  std::size_t most_points = 0;
  for (const Element& dataset : collection->children) {
    const Element vtp = XmlReader(read_text(dir / dataset.attributes.at("file"))).document();
    ASSERT_EQ(vtp.attributes.at("type"), "PolyData");
    const Element* piece = vtp.child("PolyData")->child("Piece");
    ASSERT_NE(piece, nullptr);
    const std::size_t n = std::stoul(piece->attributes.at("NumberOfPoints"));
    most_points = std::max(most_points, n);
    const Element* points = piece->child("Points")->child("DataArray");
    EXPECT_EQ(count_numbers(points->text), 3 * n);
    std::map<std::string, std::size_t> arrays;
    for (const Element& a : piece->child("PointData")->children)
      arrays[a.attributes.at("Name")] = count_numbers(a.text);
    const std::map<std::string, std::size_t> expected = {
        {"id", n}, {"diameter", n}, {"material", n}, {"charge", n}, {"velocity", 3 * n}};
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
  EXPECT_TRUE(o.err.empty()) << "stderr is not a terminal: no progress line, got " << o.err;
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
