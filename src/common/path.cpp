#include "common/path.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <system_error>

namespace ces {

namespace fs = std::filesystem;

std::optional<fs::path> file_in_the_way(const fs::path& dir) {
  fs::path made = dir;
  std::error_code ec;
  while (!fs::exists(made, ec) && made.has_relative_path()) made = made.parent_path();
  if (made.empty() || fs::is_directory(made, ec)) return std::nullopt;
  return made;
}

bool is_inner_file_name(const std::string& name) {
  const fs::path p(name);
  if (name.empty() || p.is_absolute() || p.filename().empty()) return false;
  return std::none_of(p.begin(), p.end(),
                      [](const fs::path& part) { return part == ".." || part == "."; });
}

void replace_files(const fs::path& from, const fs::path& to, const std::vector<std::string>& files,
                   const std::vector<std::string>& earlier, const std::string& last) {
  const ResolvedFolder folder(to);
  // Checked before anything moves: a 'meshes' the user linked elsewhere
  // would take the files out of `to` and over whatever is there.
  for (const std::string& f : files)
    if (!folder.within(f))
      throw fs::filesystem_error("a link in the path leads out of the folder, not written through",
                                 to / f, std::make_error_code(std::errc::operation_not_permitted));
  for (const std::string& f : files) {
    if (f == last) continue;
    fs::create_directories((to / f).parent_path());
    fs::rename(from / f, to / f);
  }
  for (const std::string& f : earlier)
    if (std::find(files.begin(), files.end(), f) == files.end() && folder.holds(f))
      fs::remove(to / f);
  fs::rename(from / last, to / last);
}

FolderLock::FolderLock(const fs::path& dir, bool wait)
    : fd_(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)) {
  if (fd_ < 0) throw std::system_error(errno, std::generic_category(), dir.string());
  int got = 0;
  do got = ::flock(fd_, LOCK_EX | (wait ? 0 : LOCK_NB));
  while (got != 0 && errno == EINTR);
  held_ = got == 0;
}

FolderLock::~FolderLock() { ::close(fd_); }

ResolvedFolder::ResolvedFolder(const fs::path& path)
    : path_(path), real_(fs::weakly_canonical(path)) {}

bool ResolvedFolder::within(const std::string& name) const {
  const fs::path inside =
      fs::weakly_canonical((path_ / name).parent_path()).lexically_relative(real_);
  return !inside.empty() && *inside.begin() != "..";
}

bool ResolvedFolder::holds(const std::string& name) const {
  const fs::file_status status = fs::symlink_status(path_ / name);
  return (fs::is_regular_file(status) || fs::is_symlink(status)) && within(name);
}

}  // namespace ces
