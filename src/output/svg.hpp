// The pieces every SVG picture of ces-sim is drawn with (landing
// distributions, the field picture): numbers in the fixed format of
// svg_number, text escaped.
#pragma once
#include <string>
#include <string_view>

namespace ces::output::svg {

// A <text> at (x, y), anchored "start", "middle" or "end"; `extra` holds
// further attributes, each with its leading space.
void text(std::string& s, double x, double y, const std::string& body, const char* anchor,
          std::string_view extra = "");
// A <line>; `style` holds its attributes (stroke, dash).
void line(std::string& s, double x1, double y1, double x2, double y2, std::string_view style);
// Round tick spacing (1, 2 or 5 times a power of ten) for about five ticks
// over `range` > 0.
double tick_step(double range);

}  // namespace ces::output::svg
