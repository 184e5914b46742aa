// The instruction sets the APGD kernel is built for (kernel.inl, compiled
// once for each, kernel_*.cpp) and the choice among them. One binary runs on
// any x86-64 and uses the widest the CPU has. The three give the same bits:
// the same IEEE operations in the same order, no fused multiply-add.
#pragma once
#include <string>

namespace ces {

// The values are kernel_*.cpp's CES_KERNEL_ISA.
enum class Isa { Baseline = 0, Avx2 = 1, Avx512 = 2 };

const char* isa_name(Isa isa);  // "baseline", "avx2", "avx512"
bool cpu_has(Isa isa);
// The kernel a run uses, chosen at its first call: the widest the CPU has,
// or the one the environment variable CES_KERNEL names (baseline, avx2,
// avx512; for comparing them). Throws std::invalid_argument if CES_KERNEL
// names none of them or one this CPU lacks.
Isa kernel_isa();
// "avx512 (this CPU: baseline, avx2, avx512)": for --version.
std::string kernel_description();

}  // namespace ces
