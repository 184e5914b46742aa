// Numbers in messages and in the printed report.
#pragma once
#include <string>

#include "common/math.hpp"

namespace ces::exporter {

std::string metres(double v);            // "0.32 m", "0.5 mm"
std::string percent(double v);           // 0.0012 -> "0.12 %"
std::string vector_text(const Vec3& v);  // "[0, 0, 1]"

}  // namespace ces::exporter
