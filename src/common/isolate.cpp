#include "common/isolate.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <new>
#include <stdexcept>

namespace ces {
namespace {

// A sanitizer's shadow memory is address space far past any limit.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

void write_all(int fd, const std::string& bytes) {
  for (std::size_t at = 0; at < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + at, bytes.size() - at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    at += std::size_t(n);
  }
}

std::string read_all(int fd) {
  std::string bytes;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return bytes;
    bytes.append(buffer, std::size_t(n));
  }
}

void limit(int resource, double value) {
  const rlimit r{rlim_t(value), rlim_t(value)};
  ::setrlimit(resource, &r);
}

// The child: its result behind 'R', or what stopped it behind 'E'.
[[noreturn]] void child(int out, const std::function<std::string()>& work,
                        const IsolationLimits& limits) {
  // A library's own complaint (an assertion's text) is not the user's to
  // read: what stopped the child is said by the parent.
  const int null = ::open("/dev/null", O_WRONLY);
  if (null >= 0) ::dup2(null, STDERR_FILENO);
  if (!kSanitized) limit(RLIMIT_AS, limits.bytes);
  limit(RLIMIT_CPU, limits.cpu_seconds);
  std::string message;
  try {
    write_all(out, "R" + work());
    ::_exit(0);
  } catch (const std::bad_alloc&) {
    message = "it needs more memory than the " + std::to_string(int(limits.bytes / (1 << 30))) +
              " GiB its reader is given";
  } catch (const std::exception& e) {
    message = e.what();
  } catch (...) {
    message = "an unknown error";
  }
  write_all(out, "E" + message);
  ::_exit(0);
}

std::string stopped_by(int signal, const IsolationLimits& limits) {
  if (signal == SIGXCPU)
    return "its reader took more than " + std::to_string(int(limits.cpu_seconds)) + " s";
  return std::string("its reader stopped (") + strsignal(signal) +
         "): the file is damaged or not of a kind it reads";
}

}  // namespace

IsolationLimits reader_limits(const std::string& path) {
  return {4.0 * (1 << 30) + 16.0 * double(std::filesystem::file_size(path)), 120.0};
}

std::string run_isolated(const std::function<std::string()>& work, const IsolationLimits& limits) {
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) throw std::runtime_error("cannot make a pipe");
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(pipe_fds[0]);
    ::close(pipe_fds[1]);
    throw std::runtime_error("cannot start a process");
  }
  if (pid == 0) {
    ::close(pipe_fds[0]);
    child(pipe_fds[1], work, limits);
  }
  ::close(pipe_fds[1]);
  std::string got = read_all(pipe_fds[0]);
  ::close(pipe_fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status)) throw std::runtime_error(stopped_by(WTERMSIG(status), limits));
  if (got.empty()) throw std::runtime_error("its reader ended without a result");
  if (got[0] == 'E') throw std::runtime_error(got.substr(1));
  return got.substr(1);
}

}  // namespace ces
