// Helpers shared by the exporter's tests: CAD written as CAD programs write
// it (binary STL, float coordinates), ces-export run on it, and the scene and
// report it wrote read back. Built into ces_tests and into
// ces_export_stl_tests (the STL-only exporter), so nothing here needs
// OpenCASCADE.
#pragma once
#include <yaml-cpp/yaml.h>

#include <array>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "common/math.hpp"

namespace ces::export_test {

namespace fs = std::filesystem;

// --- CAD written by the tests

using Triangle = std::array<Vec3, 3>;

// Binary STL, as CAD programs write it (float coordinates).
void write_stl(const fs::path& path, const std::vector<Triangle>& triangles);

// A closed cylinder of `segments` sides along z, centred on `c`.
std::vector<Triangle> cylinder(double radius, double length, int segments,
                               const Vec3& c = Vec3::Zero());

std::vector<Triangle> box(const Vec3& lo, const Vec3& hi);
std::vector<Triangle> centred_box(const Vec3& size);

// The test machine in mm: a drum along z (R 160, 300 long), a box hopper
// above it and a plate splitter beside it.
void write_stl_machine(const fs::path& dir, double mm = 1.0, int drum_segments = 256);

// The scene keys the test machine's annotations end with (time, gravity and
// the materials mapping, open for more entries).
extern const char* const kSceneKeys;

// Annotations for the test machine: the drum turning about `drum_axis`, the
// hopper and the splitters, `extra` part rules, then kSceneKeys.
std::string machine_annotations(const std::string& drum_axis, const std::string& extra = "");

// --- running ces-export and reading what it wrote

struct Exported {
  int code = -1;
  std::string out, err;
  fs::path folder;
  YAML::Node scene;
  nlohmann::json report;
};

// Exports `input` with `annotations` (written to work/annotations.yaml)
// into work/out, includes allowed from `include_paths` too.
Exported run(const fs::path& input, const std::string& annotations, const fs::path& work,
             const std::vector<std::string>& include_paths = {});

YAML::Node body(const Exported& e, const std::string& name);
Vec3 vec(const YAML::Node& n);

// The rotation a body's pose gives (identity without one).
Mat3 pose_rotation(const YAML::Node& body);

const nlohmann::json& report_part(const Exported& e, const std::string& name);
Vec3 json_vec(const nlohmann::json& j);

// The bounding box of a binary STL's vertices.
std::pair<Vec3, Vec3> stl_bounds(const fs::path& path);

// ces-sim validates the exported scene (with `extra` arguments).
void expect_validates(const Exported& e, const std::string& extra = "");

// Failed exports leave neither the folder nor the one being built.
void expect_nothing_written(const Exported& e);

// The test machine's hopper (a mesh) and splitter (a box), where drawn.
void expect_hopper(const Exported& e);
void expect_splitter_box(const Exported& e);

}  // namespace ces::export_test
