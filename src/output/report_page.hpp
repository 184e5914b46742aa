// report.html's page: its styles and its script, around the data the run
// gives it (report.hpp).
#pragma once
#include <string>

namespace ces::output {

// data: a JSON object {summary, materials, machine, frames} already safe
// inside <script>; the SVG texts are shown as images (their own ids stay
// theirs); empty ones are left out.
std::string report_page(const std::string& title, const std::string& data,
                        const std::string& distribution_svg, const std::string& field_svg);

// The base64 of bytes, for data: URLs.
std::string base64(const std::string& bytes);

}  // namespace ces::output
