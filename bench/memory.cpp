// Peak memory of a bed, measured in a fresh process: its peak resident set
// (VmHWM) minus what it held before building the bed (VmRSS), so neither the
// bench's earlier beds nor the allocator's cached memory count. And the
// machine's memory bandwidth, by STREAM's triad.
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <vector>

#include "bench.hpp"
#include "common/process.hpp"

namespace bench {

namespace {
constexpr int kProbeSteps = 2;       // the first allocates, the second warm-starts
constexpr int kProbeIterations = 5;  // memory does not depend on it
}  // namespace

int run_memory_probe(std::size_t n, bool packed, int threads) {
  const double base = ces::resident_bytes();
  ces::World w(bed_model(kProbeIterations, threads));
  fill_bed(w, n, 0.001, packed ? 1.0 : 1.5);
  std::size_t contacts = 0;
  for (int s = 0; s < kProbeSteps; ++s) contacts = w.step().contacts;
  std::printf("%zu %zu %.0f %.0f\n", n, contacts, base, ces::peak_resident_bytes());
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

double measure_triad(int threads) {
  constexpr std::size_t kN = std::size_t(1) << 23;  // 64 MiB an array, twice the L3
  constexpr int kRepeats = 5;
  std::vector<double> a(kN), b(kN), c(kN);
  // Each thread first touches the part it streams.
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(kN); ++i) {
    a[std::size_t(i)] = 0.0;
    b[std::size_t(i)] = 1.0;
    c[std::size_t(i)] = 2.0;
  }
  double best = 1e300;
  for (int r = 0; r < kRepeats; ++r) {
    const auto t0 = Clock::now();
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(kN); ++i)
      a[std::size_t(i)] = b[std::size_t(i)] + 3.0 * c[std::size_t(i)];
    best = std::min(best, since(t0));
  }
  if (a[kN / 2] != 7.0) std::fprintf(stderr, "ces_bench: the triad computed %g, not 7\n", a[kN / 2]);
  return 3.0 * sizeof(double) * double(kN) / best;  // STREAM's count: no write-allocate
}

Bandwidth measure_bandwidth(int procs) {
  Bandwidth bw;
  bw.one = measure_triad(1);
  if (procs > 1) bw.two = measure_triad(2);
  return bw;
}

}  // namespace bench
