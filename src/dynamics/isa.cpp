#include "dynamics/isa.hpp"

#include <cstdlib>
#include <stdexcept>

namespace ces {
namespace {

constexpr Isa kAll[] = {Isa::Baseline, Isa::Avx2, Isa::Avx512};

Isa choose(const char* forced) {
  Isa widest = Isa::Baseline;
  for (const Isa isa : kAll)
    if (cpu_has(isa)) widest = isa;
  if (forced == nullptr || *forced == '\0') return widest;
  for (const Isa isa : kAll) {
    if (std::string(forced) != isa_name(isa)) continue;
    if (!cpu_has(isa))
      throw std::invalid_argument(std::string("CES_KERNEL=") + forced +
                                  ": this CPU does not have it (it has up to " +
                                  isa_name(widest) + ")");
    return isa;
  }
  throw std::invalid_argument(std::string("CES_KERNEL=") + forced +
                              ": expected baseline, avx2 or avx512");
}

}  // namespace

const char* isa_name(Isa isa) {
  switch (isa) {
    case Isa::Avx2: return "avx2";
    case Isa::Avx512: return "avx512";
    default: return "baseline";
  }
}

// __builtin_cpu_supports checks that the OS saves the vector registers too.
bool cpu_has(Isa isa) {
  switch (isa) {
    case Isa::Avx2: return __builtin_cpu_supports("avx2");
    case Isa::Avx512:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("avx512f") &&
             __builtin_cpu_supports("avx512vl");
    default: return true;
  }
}

Isa kernel_isa() {
  static const Isa isa = choose(std::getenv("CES_KERNEL"));
  return isa;
}

std::string kernel_description() {
  std::string available;
  for (const Isa isa : kAll)
    if (cpu_has(isa)) available.append(available.empty() ? "" : ", ").append(isa_name(isa));
  try {
    return std::string(isa_name(kernel_isa())) + " (this CPU: " + available + ")";
  } catch (const std::invalid_argument& e) {
    return std::string(e.what()) + " (this CPU: " + available + ")";
  }
}

}  // namespace ces
