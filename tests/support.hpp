// Helpers shared by the tests: files, the ces-sim binary, model parts.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "model/model.hpp"

namespace ces::test {

namespace fs = std::filesystem;

std::string read_text(const fs::path& p);

// An empty folder in the temp directory, private to this test process
// (ctest runs tests in parallel processes) and removed when it exits.
fs::path fresh_dir(const std::string& name);

struct Outcome {
  int code = -1;
  std::string out, err;
};

// Runs the ces-sim binary with `args` (no quoting: keep paths free of
// spaces); stdout and stderr are captured.
Outcome ces_sim(const std::string& args);

// The data report.html draws from (its <script id="data">): summary,
// materials, machine, frames.
nlohmann::json report_data(const fs::path& report);

// A static plane through the origin named "ground".
RigidBody ground_plane(const Vec3& normal = Vec3::UnitY(), int material = 0);

}  // namespace ces::test
