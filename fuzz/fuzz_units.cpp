// libFuzzer target: units::parse on any text. Besides crashes and
// sanitizer reports it stops on a quantity that is not a finite number
// written as such: out of range must be an error, never inf, NaN or a
// subnormal.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>
#include <variant>

#include "scene/units.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto parsed = ces::scene::units::parse(text);
  if (const auto* q = std::get_if<ces::scene::units::Quantity>(&parsed)) {
    if (!std::isfinite(q->value) || (q->value != 0.0 && !std::isnormal(q->value))) {
      std::fprintf(stderr, "fuzz_units: '%.*s' gave %g\n", int(size), text.data(), q->value);
      std::abort();
    }
    for (const int e : q->dimension.exponent)
      if (e < -16 || e > 16) std::abort();
  }
  return 0;
}
