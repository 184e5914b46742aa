// Runs that survive: a run killed with SIGKILL at a random moment and
// resumed from its checkpoint writes the bytes the uninterrupted run writes,
// and so does one whose particles sleep on a plate;
// a run that does not finish never touches an earlier complete run; a run
// that completes removes only the files the earlier run wrote; a file that
// cannot be written is named in summary.json.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <csignal>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>
#include <vector>

#include "support.hpp"

namespace ces {
namespace {

using test::ces_sim;
using test::fresh_dir;
using test::Outcome;
using test::read_text;
namespace fs = std::filesystem;

const std::string kBinary = CES_SIM_BINARY;
const std::string kTiny = std::string(CES_TEST_DIR) + "/scenes/tiny.yaml";

// tiny.yaml fed for 2 s and run to 2.5 s (a few seconds of wall time), with
// a checkpoint every 0.1 s and frames every 50 ms as VTK and CSV; its copper
// as flakes and a wheel turning clear of the flow beside its ramp, so that
// the frames hold every kind of file: particles, spheres, the static and the
// moving machine.
// With `plate`, the ramp lies flat and the particles that come to rest on
// it fall asleep (solver.sleep; a few hundred of them), carried by it.
std::vector<std::string> longer_run(bool plate = false) {
  const std::string tilt = plate ? "" : "pose: {rotation: {axis: [0, 0, 1], angle: -30 deg}}, ";
  std::vector<std::string> args = {
      "--set", "time.end=2.5 s", "--set", "feeds.hopper.duration=2 s", "--set",
      "output.checkpoint.every=0.1 s", "--set", "feeds.hopper.mix.0.shape=flake", "--set",
      "bodies=[{name: ramp, geometry: {box: {size: [0.1, 0.01, 0.04]}}, " + tilt +
          "material: steel}, "
          "{name: wheel, geometry: {cylinder: {radius: 0.02, length: 0.04}}, "
          "pose: {position: [0.25, 0.15, 0]}, material: steel, "
          "motion: {rotation: {axis: [0, 0, 1], center: [0.25, 0.15, 0], speed: 60 rpm}}}]",
      "--quiet"};
  if (plate) args.insert(args.end(), {"--set", "solver.sleep={speed: 5 mm/s, time: 20 ms}"});
  return args;
}

pid_t start_run(const fs::path& dir, const std::vector<std::string>& run = longer_run()) {
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  std::vector<std::string> args = {kBinary, kTiny, "-o", dir.string()};
  args.insert(args.end(), run.begin(), run.end());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  ::execv(kBinary.c_str(), argv.data());
  ::_exit(127);
}

void wait_for(const fs::path& file) {
  for (int i = 0; i < 6000 && !fs::exists(file); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_TRUE(fs::exists(file)) << file;
}

// Kills the run `delay` after its first checkpoint; false if it ended first.
bool kill_after_first_checkpoint(const fs::path& dir, std::chrono::milliseconds delay,
                                 const std::vector<std::string>& run = longer_run()) {
  const pid_t pid = start_run(dir, run);
  wait_for(dir / "partial" / "checkpoint.bin");
  std::this_thread::sleep_for(delay);
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
}

std::string run_args(const fs::path& dir, const std::vector<std::string>& run) {
  std::string args = kTiny + " -o " + dir.string();
  for (const std::string& a : run)
    args += " " + (a.find(' ') != std::string::npos ? "'" + a + "'" : a);
  return args;
}

// The files a run's results consist of (not steps.csv's wall times or the
// summary's).
const char* const kResults[] = {"bins.csv",         "products.csv",     "crossings.csv",
                                "lost.csv",         "trajectories.csv", "trajectories.pvd",
                                "scene.resolved.yaml"};

// A resumed run's wall time counts the killed process's up to its last
// checkpoint, as the stages' do: the total holds all of them.
void expect_wall_of_every_process(const nlohmann::json& killed, const nlohmann::json& resumed) {
  const nlohmann::json& wall = resumed["wall_time_s"];
  double stages = 0.0;
  for (const auto& [stage, seconds] : wall["stages"].items()) stages += seconds.get<double>();
  EXPECT_GE(wall["total"].get<double>(), stages);
  EXPECT_GT(wall["total"].get<double>(), killed["wall_time_s"]["total"].get<double>());
  EXPECT_GE(wall["stages"]["output"].get<double>(),
            killed["wall_time_s"]["stages"]["output"].get<double>());
  // And its peak memory is the largest of its processes'.
  EXPECT_GE(resumed["peak_memory_mib"].get<double>(), killed["peak_memory_mib"].get<double>());
  EXPECT_GT(killed["peak_memory_mib"].get<double>(), 0.0);
}

// The run, whole in `whole`, and in `killed` killed at a random moment
// after its first checkpoint then resumed.
void expect_resumed_bytes(const fs::path& whole, const fs::path& killed,
                          const std::vector<std::string>& run) {
  const Outcome ref = ces_sim(run_args(whole, run));
  ASSERT_EQ(ref.code, 0) << ref.err;
  std::random_device entropy;
  const unsigned seed = entropy();
  std::mt19937 rng(seed);
  const auto delay = std::chrono::milliseconds(std::uniform_int_distribution<int>(0, 600)(rng));
  SCOPED_TRACE("kill " + std::to_string(delay.count()) + " ms after the first checkpoint (seed " +
               std::to_string(seed) + ")");
  ASSERT_TRUE(kill_after_first_checkpoint(killed, delay, run)) << "the run ended before the kill";
  EXPECT_FALSE(fs::exists(killed / "bins.csv")) << "an unfinished run publishes nothing";
  const nlohmann::json partial = nlohmann::json::parse(read_text(killed / "partial" / "summary.json"));
  EXPECT_FALSE(partial["complete"].get<bool>());
  EXPECT_NE(partial["reason"].get<std::string>().find("killed"), std::string::npos);

  const Outcome resumed = ces_sim("resume " + killed.string() + " --quiet");
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  expect_wall_of_every_process(partial, nlohmann::json::parse(read_text(killed / "summary.json")));
  for (const char* name : kResults)
    EXPECT_EQ(read_text(whole / name), read_text(killed / name)) << name;
  std::size_t frames = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(whole / "trajectories")) {
    ++frames;
    const fs::path name = e.path().filename();
    EXPECT_EQ(read_text(e.path()), read_text(killed / "trajectories" / name)) << name;
  }
  EXPECT_GE(frames, 40u);
  for (const char* name : {"machine_static.vtp", "frame_000010_spheres.vtp",
                           "frame_000010_machine.vtp"})
    EXPECT_TRUE(fs::exists(whole / "trajectories" / name)) << name;
  EXPECT_EQ(test::report_data(whole / "report.html")["frames"],
            test::report_data(killed / "report.html")["frames"]);
  EXPECT_FALSE(fs::exists(killed / "partial"));
}

TEST(Restart, KilledAtARandomMomentResumesToTheSameBytes) {
  expect_resumed_bytes(fresh_dir("whole"), fresh_dir("killed"), longer_run());
}

// Sleepers carry state a checkpoint must keep: their carrier and how long
// they have been at rest.
TEST(Restart, ARunWithSleepersResumesToTheSameBytes) {
  const fs::path whole = fresh_dir("plate_whole");
  expect_resumed_bytes(whole, fresh_dir("plate_killed"), longer_run(true));
  const nlohmann::json summary = nlohmann::json::parse(read_text(whole / "summary.json"));
  EXPECT_GT(summary["solver"]["asleep_max"].get<int>(), 100);
}

TEST(Restart, AnUnfinishedRunLeavesTheEarlierCompleteRunIntact) {
  const fs::path dir = fresh_dir("earlier");
  ASSERT_EQ(ces_sim(kTiny + " -o " + dir.string() + " --quiet").code, 0);
  const std::string bins = read_text(dir / "bins.csv"), summary = read_text(dir / "summary.json");
  fs::create_directories(dir / "trajectories");
  std::ofstream(dir / "trajectories" / "frame_custom.vtp") << "mine";
  ASSERT_TRUE(kill_after_first_checkpoint(dir, std::chrono::milliseconds(50)));
  EXPECT_EQ(read_text(dir / "bins.csv"), bins);
  EXPECT_EQ(read_text(dir / "summary.json"), summary);
  EXPECT_EQ(read_text(dir / "trajectories" / "frame_custom.vtp"), "mine");
  EXPECT_TRUE(fs::exists(dir / "trajectories" / "frame_000000.vtp"));
}

// While a run holds its folder (here the test holds it, as a run does),
// another run into it is refused before it clears the first one's
// partial/.
TEST(Restart, ARunIntoAFolderInUseIsRefused) {
  const fs::path dir = fresh_dir("in_use");
  fs::create_directories(dir / "partial");
  std::ofstream(dir / "partial" / "steps.csv") << "the other run's";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
  const Outcome second = ces_sim(kTiny + " -o " + dir.string() + " --quiet");
  EXPECT_EQ(second.code, 3);
  EXPECT_NE(second.err.find("another ces-sim run is writing in"), std::string::npos) << second.err;
  EXPECT_EQ(read_text(dir / "partial" / "steps.csv"), "the other run's");
  ::close(fd);
  EXPECT_EQ(ces_sim(kTiny + " -o " + dir.string() + " --quiet").code, 0);
}

// The earlier run wrote frames; the new one writes none: its frames go, a
// user's file beside them stays, and so does a file the earlier run never
// listed.
TEST(Restart, ACompleteRunRemovesOnlyTheEarlierRunsFiles) {
  const fs::path dir = fresh_dir("replaced");
  ASSERT_EQ(ces_sim(kTiny + " -o " + dir.string() + " --quiet").code, 0);
  ASSERT_TRUE(fs::exists(dir / "trajectories" / "frame_000001.vtp"));
  std::ofstream(dir / "trajectories" / "frame_custom.vtp") << "mine";
  std::ofstream(dir / "notes.txt") << "mine";
  std::string plain = read_text(kTiny);
  const std::string frames = "trajectories: {every: 50 ms, format: both}";
  ASSERT_NE(plain.find(frames), std::string::npos);
  plain.replace(plain.find(frames), frames.size(), "steps: true");
  const fs::path scene = fresh_dir("plain") / "tiny_plain.yaml";
  std::ofstream(scene) << plain;
  const Outcome o = ces_sim(scene.string() + " -o " + dir.string() + " --quiet");
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_FALSE(fs::exists(dir / "trajectories" / "frame_000001.vtp"));
  EXPECT_FALSE(fs::exists(dir / "trajectories.pvd"));
  EXPECT_FALSE(fs::exists(dir / "trajectories.csv"));
  EXPECT_EQ(read_text(dir / "trajectories" / "frame_custom.vtp"), "mine");
  EXPECT_EQ(read_text(dir / "notes.txt"), "mine");
  EXPECT_TRUE(fs::exists(dir / "bins.csv"));
  EXPECT_FALSE(fs::exists(dir / "partial"));
}

// summary.json is text anyone may edit: an earlier one that lists folders
// ('.', 'sub/', 'trajectories', 'partial'), a path out of the folder, or a
// file through a folder that links elsewhere has none of them removed, and
// the new run completes in its place.
TEST(Restart, AnEarlierSummaryListingFoldersRemovesNoneOfThem) {
  const fs::path dir = fresh_dir("listed_folders");
  ASSERT_EQ(ces_sim(kTiny + " -o " + dir.string() + " --quiet").code, 0);
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "sub" / "mine.txt") << "mine";
  const fs::path outside = fresh_dir("listed_outside");
  std::ofstream(outside / "victim.txt") << "theirs";
  fs::create_directory_symlink(outside, dir / "link");
  nlohmann::json summary = nlohmann::json::parse(read_text(dir / "summary.json"));
  for (const char* name : {".", "./", "sub/", "sub", "trajectories", "partial", "../x", "/tmp",
                           "link/victim.txt"})
    summary["files"].push_back(name);
  std::ofstream(dir / "summary.json") << summary.dump();
  const Outcome o = ces_sim(kTiny + " -o " + dir.string() + " --quiet");
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_TRUE(nlohmann::json::parse(read_text(dir / "summary.json"))["complete"].get<bool>());
  EXPECT_EQ(read_text(dir / "sub" / "mine.txt"), "mine");
  EXPECT_EQ(read_text(outside / "victim.txt"), "theirs");
  EXPECT_TRUE(fs::exists(dir / "trajectories" / "frame_000001.vtp"));
  EXPECT_FALSE(fs::exists(dir / "partial"));
}

// A partial/trajectories that links elsewhere is a link to clear, not a
// folder of this run's frames: the frames it points at stay.
TEST(Restart, AWorkFolderLinkingElsewhereHasNoneOfItsTargetsFramesRemoved) {
  const fs::path dir = fresh_dir("linked_frames");
  const fs::path outside = fresh_dir("linked_frames_outside");
  std::ofstream(outside / "frame_000000.vtp") << "theirs";
  fs::create_directories(dir / "partial");
  fs::create_directory_symlink(outside, dir / "partial" / "trajectories");
  const Outcome o = ces_sim(kTiny + " -o " + dir.string() + " --quiet");
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(read_text(outside / "frame_000000.vtp"), "theirs");
  EXPECT_TRUE(fs::exists(dir / "trajectories" / "frame_000001.vtp"));
}

// Each output that cannot be written is named in the reason, in the order
// they failed: a frame mid-run (its temporary's place taken by a folder),
// then bins.csv among the outputs written at the end. A later failure adds
// to the reason, so the first is never hidden.
TEST(Restart, AFileThatCannotBeWrittenIsNamedInTheSummary) {
  const fs::path dir = fresh_dir("unwritable"), partial = dir / "partial";
  fs::create_directories(partial / "trajectories" / "frame_000002.vtp.tmp" / "x");
  fs::create_directories(partial / "bins.csv" / "x");
  const Outcome o = ces_sim(kTiny + " -o " + dir.string() + " --quiet");
  EXPECT_EQ(o.code, 3) << o.err;
  const nlohmann::json s = nlohmann::json::parse(read_text(partial / "summary.json"));
  EXPECT_FALSE(s["complete"].get<bool>());
  const std::string reason = s["reason"];
  EXPECT_EQ(reason.rfind("error after ", 0), 0u) << reason;
  const std::size_t frame = reason.find("trajectories/frame_000002.vtp");
  ASSERT_NE(frame, std::string::npos) << reason;
  EXPECT_NE(reason.find("bins.csv", frame), std::string::npos) << reason;
  EXPECT_NE(o.err.find(reason), std::string::npos) << o.err;
  EXPECT_FALSE(fs::exists(dir / "summary.json"));
}

// A complete run whose file cannot take its place in the output folder (a
// folder of that name is there) moves nothing: the earlier run stays whole,
// and the summary in partial/ says why, naming the file, as stderr does.
TEST(Restart, AResultThatCannotBePublishedLeavesTheEarlierRunAndSaysWhy) {
  const fs::path dir = fresh_dir("unpublished");
  const std::string run = kTiny + " -o " + dir.string() + " --quiet";
  ASSERT_EQ(ces_sim(run + " --set output.steps=false").code, 0);
  const std::string report = read_text(dir / "report.html"), summary = read_text(dir / "summary.json");
  fs::create_directories(dir / "steps.csv" / "mine");
  const Outcome o = ces_sim(run);
  EXPECT_EQ(o.code, 3) << o.err;
  EXPECT_EQ(read_text(dir / "report.html"), report);
  EXPECT_EQ(read_text(dir / "summary.json"), summary);
  const nlohmann::json s = nlohmann::json::parse(read_text(dir / "partial" / "summary.json"));
  EXPECT_FALSE(s["complete"].get<bool>());
  const std::string reason = s["reason"];
  EXPECT_NE(reason.find((dir / "steps.csv").string()), std::string::npos) << reason;
  EXPECT_NE(o.err.find(reason), std::string::npos) << o.err;
}

TEST(Restart, ResumeRefusesAMissingOrDamagedCheckpoint) {
  const fs::path none = fresh_dir("none");
  const Outcome missing = ces_sim("resume " + none.string());
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("no checkpoint"), std::string::npos) << missing.err;

  // A folder or a pipe in its place is not opened (a pipe would be waited
  // on for ever).
  const fs::path odd = none / "partial" / "checkpoint.bin";
  fs::create_directories(odd);
  const Outcome folder = ces_sim("resume " + none.string());
  EXPECT_EQ(folder.code, 2);
  EXPECT_NE(folder.err.find("not a regular file"), std::string::npos) << folder.err;
  fs::remove(odd);
  ASSERT_EQ(::mkfifo(odd.c_str(), 0600), 0);
  const Outcome pipe = ces_sim("resume " + none.string());
  EXPECT_EQ(pipe.code, 2);
  EXPECT_NE(pipe.err.find("not a regular file"), std::string::npos) << pipe.err;

  const fs::path dir = fresh_dir("damaged");
  ASSERT_TRUE(kill_after_first_checkpoint(dir, std::chrono::milliseconds(0)));
  const fs::path file = dir / "partial" / "checkpoint.bin";
  const std::string whole = read_text(file);
  fs::resize_file(file, fs::file_size(file) / 2);
  const Outcome damaged = ces_sim("resume " + dir.string());
  EXPECT_EQ(damaged.code, 2);
  EXPECT_NE(damaged.err.find("cannot resume"), std::string::npos) << damaged.err;

  // One bit flipped anywhere past the head: in the scene's text, in the
  // state, in the checksum itself.
  for (const double at : {0.01, 0.3, 0.6, 0.95, 0.99999}) {
    std::string flipped = whole;
    flipped[std::size_t(at * double(flipped.size() - 1))] ^= 0x10;
    std::ofstream(file, std::ios::binary) << flipped;
    const Outcome bit = ces_sim("resume " + dir.string());
    EXPECT_EQ(bit.code, 2) << at;
    EXPECT_NE(bit.err.find("checksum does not match"), std::string::npos) << at << bit.err;
  }
}

}  // namespace
}  // namespace ces
