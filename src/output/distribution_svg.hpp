// distribution.svg: the landing distribution of each material along each
// collector's axis (mass % per bin against position in mm), one stepped line
// per material, product boundaries dashed, like the seed paper's Figures 9
// and 10. Hand-written SVG, no plotting library.
#pragma once
#include <string>
#include <vector>

#include "output/records.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

std::string distribution_svg(const Simulation& sim, const Collection& c,
                             const std::vector<int>& materials);

}  // namespace ces::output
