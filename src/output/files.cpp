#include "output/files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <utility>

namespace ces::output {
namespace {

[[noreturn]] void fail(const std::string& what, const std::filesystem::path& path) {
  throw IoError("cannot " + what + " " + path.string() + ": " + std::strerror(errno));
}

std::filesystem::path tmp_path(const std::filesystem::path& path) {
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  return tmp;
}

// Flush to the disk, close, rename over the target and sync the directory
// entry, so the new name survives a crash as well.
void publish(std::FILE* file, const std::filesystem::path& tmp, const std::filesystem::path& path) {
  const bool flushed = std::fflush(file) == 0 && ::fsync(::fileno(file)) == 0;
  const int flush_errno = errno;
  const bool closed = std::fclose(file) == 0;
  if (!flushed || !closed) {
    if (!flushed) errno = flush_errno;
    const int saved = errno;
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    errno = saved;
    fail("write", tmp);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) fail("rename into", path);
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  if (const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY); fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

void write_file_atomic(const std::filesystem::path& path, std::string_view content) {
  AtomicFile file(path);
  file.write(content);
  file.commit();
}

AtomicFile::AtomicFile(std::filesystem::path path) : path_(std::move(path)), tmp_(tmp_path(path_)) {
  file_ = std::fopen(tmp_.c_str(), "wb");
  if (!file_) fail("create", tmp_);
}

AtomicFile::AtomicFile(AtomicFile&& other) noexcept
    : path_(std::move(other.path_)),
      tmp_(std::move(other.tmp_)),
      file_(std::exchange(other.file_, nullptr)) {}

AtomicFile& AtomicFile::operator=(AtomicFile&& other) noexcept {
  if (this != &other) {
    discard();
    path_ = std::move(other.path_);
    tmp_ = std::move(other.tmp_);
    file_ = std::exchange(other.file_, nullptr);
  }
  return *this;
}

AtomicFile::~AtomicFile() { discard(); }

void AtomicFile::write(std::string_view bytes) {
  if (!file_) throw IoError("write to a closed file " + path_.string());
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) fail("write", tmp_);
}

void AtomicFile::commit() {
  if (!file_) throw IoError("commit of a closed file " + path_.string());
  publish(std::exchange(file_, nullptr), tmp_, path_);
}

void AtomicFile::discard() noexcept {
  if (!file_) return;
  std::fclose(std::exchange(file_, nullptr));
  std::error_code ignored;
  std::filesystem::remove(tmp_, ignored);
}

AppendFile::AppendFile(const std::filesystem::path& path) : path_(path) {
  file_ = std::fopen(path_.c_str(), "wb");
  if (!file_) fail("create", path_);
}

AppendFile::AppendFile(const std::filesystem::path& path, std::uint64_t resume_at) : path_(path) {
  std::error_code error;
  if (std::filesystem::file_size(path_, error) < resume_at || error)
    throw IoError("cannot resume " + path_.string() + ": it is shorter than the checkpoint says");
  std::filesystem::resize_file(path_, resume_at, error);
  if (error) throw IoError("cannot cut " + path_.string() + ": " + error.message());
  file_ = std::fopen(path_.c_str(), "ab");
  if (!file_) fail("open", path_);
}

AppendFile::AppendFile(AppendFile&& other) noexcept
    : path_(std::move(other.path_)), file_(std::exchange(other.file_, nullptr)) {}

AppendFile& AppendFile::operator=(AppendFile&& other) noexcept {
  if (this != &other) {
    if (file_) std::fclose(file_);
    path_ = std::move(other.path_);
    file_ = std::exchange(other.file_, nullptr);
  }
  return *this;
}

AppendFile::~AppendFile() {
  if (file_) std::fclose(file_);
}

void AppendFile::write(std::string_view bytes) {
  if (!file_) throw IoError("write to a closed file " + path_.string());
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) fail("write", path_);
}

std::uint64_t AppendFile::flush() {
  if (!file_) return 0;
  if (std::fflush(file_) != 0 || ::fsync(::fileno(file_)) != 0) fail("write", path_);
  const long at = std::ftell(file_);
  if (at < 0) fail("measure", path_);
  return std::uint64_t(at);
}

void AppendFile::close() {
  if (!file_) return;
  flush();
  if (std::fclose(std::exchange(file_, nullptr)) != 0) fail("close", path_);
}

}  // namespace ces::output
