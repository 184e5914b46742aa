// The solver kernel's builds (dynamics/isa.hpp): every one this CPU has
// gives the same bytes, and CES_KERNEL chooses among them or is refused.
#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <vector>

#include "dynamics/isa.hpp"
#include "output/compare.hpp"
#include "support.hpp"

namespace ces {
namespace {

const std::string kScene = std::string(CES_SOURCE_DIR) + "/scenes/hopper.yaml";

// Runs `args` with CES_KERNEL set to `kernel`.
test::Outcome with_kernel(const std::string& kernel, const std::string& args) {
  ::setenv("CES_KERNEL", kernel.c_str(), 1);
  test::Outcome r = test::ces_sim(args);
  ::unsetenv("CES_KERNEL");
  return r;
}

// Runs `args` (a scene and its options) on every build the CPU has and
// expects their bins, products, crossings and the steps' solver figures
// (iterations, residual, overlap: steps.csv but its timing columns) to the
// byte.
// A CPU with the baseline build alone has nothing to compare: skipped.
void expect_same_bytes(const std::string& name, const std::string& args) {
  std::vector<Isa> builds;
  for (const Isa isa : {Isa::Baseline, Isa::Avx2, Isa::Avx512})
    if (cpu_has(isa)) builds.push_back(isa);
  if (builds.size() < 2)
    GTEST_SKIP() << "this CPU runs one build of the kernel: nothing to compare";
  std::map<std::string, std::string> first;
  for (const Isa isa : builds) {
    const test::fs::path dir = test::fresh_dir(name + "_" + isa_name(isa));
    const test::Outcome r = with_kernel(isa_name(isa), args + " -q -o " + dir.string());
    ASSERT_EQ(r.code, 0) << r.err;
    std::map<std::string, std::string> files;
    for (const char* f : {"bins.csv", "products.csv", "crossings.csv"})
      files[f] = test::read_text(dir / f);
    const output::Table steps = output::read_table(dir / "steps.csv");
    for (const char* column : {"iterations", "residual_mps", "max_penetration_m"}) {
      const std::size_t c = steps.column(column, dir / "steps.csv");
      for (const auto& row : steps.rows) files[column] += row[c] + "\n";
    }
    if (first.empty()) first = files;
    for (const auto& [file, text] : files)
      EXPECT_EQ(text, first[file]) << isa_name(isa) << " " << file;
  }
}

// A hopper draining: APGD on up to about 2 000 contacts.
TEST(Kernel, EveryBuildTheCpuHasGivesTheSameBytes) { expect_same_bytes("kernel", kScene); }

// A pile on a yielding ramp: blocks of contacts with springs (their rows
// N + E, CcpProblem::softness) among rigid ones.
TEST(Kernel, EveryBuildGivesTheSameBytesWithYieldingContacts) {
  expect_same_bytes("kernel_yield",
                    std::string(CES_SOURCE_DIR) +
                        "/tests/scenes/pile.yaml --set 'materials.steel.stiffness=50 N/m'");
}

TEST(Kernel, VersionNamesTheKernelInUse) {
  const test::Outcome r = with_kernel("baseline", "--version");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("solver kernel: baseline (this CPU: baseline"), std::string::npos) << r.out;
}

TEST(Kernel, UnknownOrMissingKernelIsRefused) {
  const test::Outcome unknown = with_kernel("sse9", "validate " + kScene);
  EXPECT_EQ(unknown.code, 2);
  EXPECT_NE(unknown.err.find("CES_KERNEL=sse9: expected baseline, avx2 or avx512"),
            std::string::npos)
      << unknown.err;
  for (const Isa isa : {Isa::Avx2, Isa::Avx512}) {
    if (cpu_has(isa)) continue;
    const test::Outcome missing = with_kernel(isa_name(isa), "validate " + kScene);
    EXPECT_EQ(missing.code, 2);
    EXPECT_NE(missing.err.find("this CPU does not have it"), std::string::npos) << missing.err;
  }
}

}  // namespace
}  // namespace ces
