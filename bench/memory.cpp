// Peak memory of a bed, measured in a fresh process: its peak resident set
// (VmHWM) minus what it held before building the bed (VmRSS), so neither the
// bench's earlier beds nor the allocator's cached memory count.
#include <cstdio>
#include <sstream>

#include "bench.hpp"

namespace bench {

namespace {
constexpr int kProbeSteps = 2;       // the first allocates, the second warm-starts
constexpr int kProbeIterations = 5;  // memory does not depend on it
}  // namespace

int run_memory_probe(std::size_t n, bool packed, int threads) {
  const double base = proc_status_bytes("VmRSS");
  ces::World w(bed_model(kProbeIterations, threads));
  fill_bed(w, n, 0.001, packed ? 1.0 : 1.5);
  std::size_t contacts = 0;
  for (int s = 0; s < kProbeSteps; ++s) contacts = w.step().contacts;
  std::printf("%zu %zu %.0f %.0f\n", n, contacts, base, proc_status_bytes("VmHWM"));
  return 0;
}

MemoryProbe probe_memory(const std::string& exe, std::size_t n, bool packed, int threads) {
  const ProcessResult p = run_process({exe, "--probe-memory", std::to_string(n),
                                       packed ? "packed" : "sparse", std::to_string(threads)},
                                      true);
  MemoryProbe m;
  m.packed = packed;
  std::istringstream in(p.out);
  m.ok = p.exit_code == 0 && bool(in >> m.particles >> m.contacts >> m.base >> m.peak);
  if (!m.ok) std::fprintf(stderr, "ces_bench: memory probe of %zu particles failed\n", n);
  return m;
}

}  // namespace bench
