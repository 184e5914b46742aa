// Child processes (the memory probe, ces-sim) and /proc readings.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>

#include "bench.hpp"

namespace bench {

std::string self_exe() { return std::filesystem::read_symlink("/proc/self/exe").string(); }

namespace {

[[noreturn]] void exec_child(const std::vector<std::string>& argv, int out_fd) {
  if (out_fd >= 0) dup2(out_fd, STDOUT_FILENO);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  execv(args[0], args.data());
  std::fprintf(stderr, "ces_bench: cannot run %s: %s\n", args[0], std::strerror(errno));
  _exit(127);
}

std::string read_all(int fd) {
  std::string out;
  char buf[4096];
  for (ssize_t k; (k = read(fd, buf, sizeof buf)) > 0;) out.append(buf, std::size_t(k));
  return out;
}

}  // namespace

ProcessResult run_process(const std::vector<std::string>& argv, bool capture) {
  ProcessResult r;
  int fds[2] = {-1, -1};
  if (capture && pipe(fds) != 0) return r;
  std::fflush(nullptr);
  const auto t0 = Clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    if (capture) close(fds[0]);
    exec_child(argv, capture ? fds[1] : -1);
  }
  if (capture) {
    close(fds[1]);
    if (pid > 0) r.out = read_all(fds[0]);
    close(fds[0]);
  }
  if (pid < 0) return r;
  int status = 0;
  waitpid(pid, &status, 0);
  r.wall = since(t0);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace bench
