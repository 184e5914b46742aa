// Paths as the commands that take them from a scene or a study name them.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ces {

// A path made absolute against the working directory ("" is that directory
// itself), with no '.' or '..' left in it. Links stay: a scene's includes
// and name come from the path it is given.
inline std::filesystem::path absolute_path(const std::filesystem::path& p) {
  return std::filesystem::absolute(p.empty() ? std::filesystem::path(".") : p).lexically_normal();
}

// The part of `dir`'s path that exists, when it is not a folder (a file
// where a folder is to be made, or on the way to it); nothing otherwise.
std::optional<std::filesystem::path> file_in_the_way(const std::filesystem::path& dir);

// Whether `name`, a file's path read from a file anyone may edit (a run's
// summary.json, an export's report), names a file inside the folder it is
// relative to: not absolute, a file name at its end, no '.' or '..' part.
bool is_inner_file_name(const std::string& name);

// Moves `files` (paths relative to both folders) from `from` into `to`
// but `last`, removes those of `earlier` (what `to`'s index listed before)
// not written again that lie in `to` itself, then moves `last` (the index
// that lists what `to` holds): nothing else in `to` is touched. Throws
// std::filesystem::filesystem_error, before anything moves when a link in
// a file's path leads out of `to`.
void replace_files(const std::filesystem::path& from, const std::filesystem::path& to,
                   const std::vector<std::string>& files, const std::vector<std::string>& earlier,
                   const std::string& last);

// An exclusive lock on a folder (flock on the folder itself) for the
// object's life; the kernel lets go of it when the process ends, however
// it ends. With `wait` it blocks until another holder lets go; without,
// held() says whether it was taken. Throws std::system_error when the
// folder cannot be opened.
class FolderLock {
 public:
  FolderLock(const std::filesystem::path& dir, bool wait);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;
  bool held() const { return held_; }

 private:
  int fd_ = -1;
  bool held_ = false;
};

// A folder, resolved once for every file checked in it.
class ResolvedFolder {
 public:
  explicit ResolvedFolder(const std::filesystem::path& path);

  // Whether `name` is a file (or a link) that lies in the folder itself: a
  // 'sub/x' whose 'sub' links elsewhere names another folder's file.
  bool holds(const std::string& name) const;
  // Whether `name`'s folder, links resolved, is this folder or lies in it.
  bool within(const std::string& name) const;

 private:
  std::filesystem::path path_, real_;
};

}  // namespace ces
