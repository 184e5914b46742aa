// Output files appear atomically: the bytes go to "name.tmp", are flushed to
// the disk (fsync), then renamed over "name". A reader, or a run killed half
// way, sees the old file or the new one, never a torn one.
#pragma once
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string_view>

namespace ces::output {

// Writing an output failed (disk full, no permission, ...).
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

void write_file_atomic(const std::filesystem::path& path, std::string_view content);

// A file written in pieces over a run (steps.csv, trajectories.csv) and
// published by commit(). Destroyed uncommitted, it removes its .tmp.
class AtomicFile {
 public:
  AtomicFile() = default;
  explicit AtomicFile(std::filesystem::path path);
  AtomicFile(AtomicFile&& other) noexcept;
  AtomicFile& operator=(AtomicFile&& other) noexcept;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  bool is_open() const { return file_ != nullptr; }
  void write(std::string_view bytes);
  void commit();

 private:
  void discard() noexcept;
  std::filesystem::path path_, tmp_;
  std::FILE* file_ = nullptr;
};

}  // namespace ces::output
