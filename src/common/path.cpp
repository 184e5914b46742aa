#include "common/path.hpp"

#include <algorithm>

namespace ces {

namespace fs = std::filesystem;

bool is_inner_file_name(const std::string& name) {
  const fs::path p(name);
  if (name.empty() || p.is_absolute() || p.filename().empty()) return false;
  return std::none_of(p.begin(), p.end(),
                      [](const fs::path& part) { return part == ".." || part == "."; });
}

void replace_files(const fs::path& from, const fs::path& to, const std::vector<std::string>& files,
                   const std::vector<std::string>& earlier, const std::string& last) {
  for (const std::string& f : files) {
    if (f == last) continue;
    fs::create_directories((to / f).parent_path());
    fs::rename(from / f, to / f);
  }
  const ResolvedFolder folder(to);
  for (const std::string& f : earlier)
    if (std::find(files.begin(), files.end(), f) == files.end() && folder.holds(f))
      fs::remove(to / f);
  fs::rename(from / last, to / last);
}

ResolvedFolder::ResolvedFolder(const fs::path& path)
    : path_(path), real_(fs::weakly_canonical(path)) {}

bool ResolvedFolder::holds(const std::string& name) const {
  const fs::path file = path_ / name;
  const fs::file_status status = fs::symlink_status(file);
  if (!fs::is_regular_file(status) && !fs::is_symlink(status)) return false;
  const fs::path within = fs::weakly_canonical(file.parent_path()).lexically_relative(real_);
  return !within.empty() && *within.begin() != "..";
}

}  // namespace ces
