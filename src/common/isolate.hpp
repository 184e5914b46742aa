// Work on untrusted input that may crash or exhaust the process, done in a
// child process under limits.
#pragma once
#include <functional>
#include <string>

namespace ces {

struct IsolationLimits {
  double bytes = 0.0;        // address space of the child
  double cpu_seconds = 0.0;  // CPU time of the child
};

// The limits for a reader of the file at `path`: 4 GiB and 16 bytes per
// byte of the file, 120 s of CPU, which a reader of the largest file a
// scene or an export may name stays inside.
IsolationLimits reader_limits(const std::string& path);

// Runs `work` in a child process (fork) with `limits` and returns what it
// returned. What ends the child early becomes a std::runtime_error here
// that says what it was: an exception of `work` (its message), memory past
// the limit, CPU time past the limit, or a signal (an assertion in a
// library, a crash). The child shares nothing back but the result.
std::string run_isolated(const std::function<std::string()>& work, const IsolationLimits& limits);

}  // namespace ces
