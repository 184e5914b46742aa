#include "sim/output_folder.hpp"

#include <algorithm>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>

#include "common/path.hpp"

namespace ces {
namespace {

namespace fs = std::filesystem;

// A listed name a run may have written: a file inside the folder and not
// in its partial/ (a summary.json is text anyone may edit).
bool safe_relative(const std::string& name) {
  return is_inner_file_name(name) && *fs::path(name).begin() != "partial";
}

// The files a run's summary.json lists (relative paths), or none.
std::vector<std::string> listed_files(const fs::path& summary_json) {
  std::error_code not_a_file;  // a folder in its place lists nothing
  if (!fs::is_regular_file(summary_json, not_a_file)) return {};
  std::ifstream in(summary_json);
  if (!in) return {};
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  std::vector<std::string> files;
  if (j.is_discarded() || !j.contains("files") || !j["files"].is_array()) return files;
  for (const nlohmann::json& f : j["files"])
    if (f.is_string() && safe_relative(f.get<std::string>())) files.push_back(f.get<std::string>());
  return files;
}

// What an unfinished run may have left in its work folder: the files its
// summary lists, the checkpoint, and the names every run writes as it goes.
void clear_work(const fs::path& work) {
  std::vector<std::string> names = listed_files(work / "summary.json");
  for (const char* name : {"summary.json", "checkpoint.bin", "checkpoint.bin.tmp",
                           "scene.resolved.yaml", "steps.csv", "trajectories.csv",
                           "trajectories.pvd", "trajectories/machine_static.vtp", "field.csv",
                           "field.svg"})
    names.emplace_back(name);
  const ResolvedFolder folder(work);
  for (const std::string& name : names) {
    if (!safe_relative(name)) continue;
    if (folder.holds(name)) fs::remove(work / name);
    if (folder.holds(name + ".tmp")) fs::remove(work / (name + ".tmp"));
  }
  // The folder itself, not a link: a link's target holds someone else's frames.
  if (fs::is_directory(fs::symlink_status(work / "trajectories")))
    for (const fs::directory_entry& e : fs::directory_iterator(work / "trajectories"))
      if (e.path().extension() == ".vtp" && e.path().stem().string().starts_with("frame_"))
        fs::remove(e.path());
  std::error_code not_empty;  // a folder with someone else's files stays
  fs::remove(work / "trajectories", not_empty);
  fs::remove(work, not_empty);
}

// Names the file that failed as well as the folder: the folder alone does
// not say which of a run's files to look at.
void io(const std::string& what, const fs::path& path, const fs::filesystem_error& e) {
  std::string files;
  if (!e.path1().empty()) files = " (" + e.path1().string();
  if (!e.path2().empty()) files += " to " + e.path2().string();
  if (!files.empty()) files += ")";
  throw output::IoError("cannot " + what + " " + path.string() + files + ": " +
                        e.code().message());
}

// DIR itself, locked: no file of ours is left in it.
std::unique_ptr<FolderLock> lock_folder(const fs::path& dir) {
  std::unique_ptr<FolderLock> lock;
  try {
    lock = std::make_unique<FolderLock>(dir, false);
  } catch (const std::system_error&) {
    throw output::IoError("cannot open the output folder " + dir.string());
  }
  if (!lock->held())
    throw output::IoError("another ces-sim run is writing in " + dir.string() +
                          ": wait for it to end, or give this run another folder (-o)");
  return lock;
}

}  // namespace

OutputFolder::OutputFolder(fs::path dir, output::Start start)
    : dir_(std::move(dir)), work_(dir_ / "partial") {
  try {
    fs::create_directories(dir_);
  } catch (const fs::filesystem_error& e) {
    io("prepare the output folder", dir_, e);
  }
  lock_ = lock_folder(dir_);
  try {
    if (start == output::Start::Fresh && fs::exists(work_)) clear_work(work_);
    fs::create_directories(work_);
  } catch (const fs::filesystem_error& e) {
    io("prepare the output folder", dir_, e);
  }
}

OutputFolder::~OutputFolder() = default;

void OutputFolder::publish(const std::vector<std::string>& files) const {
  // A folder where a file goes cannot be replaced: found before any move,
  // it leaves dir() as it was.
  for (const std::string& f : files)
    if (fs::is_directory(dir_ / f))
      throw output::IoError("cannot move the results into " + dir_.string() + ": " +
                            (dir_ / f).string() + " is a folder");
  const std::vector<std::string> earlier = listed_files(dir_ / "summary.json");
  try {
    replace_files(work_, dir_, files, earlier, "summary.json");
    clear_work(work_);
  } catch (const fs::filesystem_error& e) {
    io("move the results into", dir_, e);
  }
}

}  // namespace ces
