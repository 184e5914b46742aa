// Output files appear atomically: the bytes go to "name.tmp", are flushed to
// the disk (fsync), then renamed over "name". A reader, or a run killed half
// way, sees the old file or the new one, never a torn one.
#pragma once
#include <cstdint>
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

// A file written whole, then published by commit(). Destroyed uncommitted,
// it removes its .tmp.
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

// How a run's observers open their files: a new run creates them; a run
// resumed from a checkpoint opens them when it loads the checkpoint.
enum class Start { Fresh, Resume };

// A file written in pieces over a run (steps.csv, trajectories.csv) in the
// run's own folder (the whole folder is published when the run ends).
// flush() puts it on the disk and returns its length, which a checkpoint
// records; a resumed run opens it at that length, cutting what was written
// after the checkpoint, and appends.
class AppendFile {
 public:
  AppendFile() = default;
  // A new, empty file; with `resume_at`, the existing one cut to that length.
  explicit AppendFile(const std::filesystem::path& path);
  AppendFile(const std::filesystem::path& path, std::uint64_t resume_at);
  AppendFile(AppendFile&& other) noexcept;
  AppendFile& operator=(AppendFile&& other) noexcept;
  AppendFile(const AppendFile&) = delete;
  AppendFile& operator=(const AppendFile&) = delete;
  ~AppendFile();

  bool is_open() const { return file_ != nullptr; }
  void write(std::string_view bytes);
  std::uint64_t flush();
  void close();

 private:
  std::filesystem::path path_;
  std::FILE* file_ = nullptr;
};

}  // namespace ces::output
