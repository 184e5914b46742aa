#include "export_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "export.hpp"
#include "support.hpp"

namespace ces::export_test {

using ces::test::read_text;

void write_stl(const fs::path& path, const std::vector<Triangle>& triangles) {
  std::ofstream out(path, std::ios::binary);
  const char header[80] = {};
  out.write(header, 80);
  const auto count = std::uint32_t(triangles.size());
  out.write(reinterpret_cast<const char*>(&count), 4);
  for (const Triangle& t : triangles) {
    float record[12] = {};
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) record[3 + 3 * c + k] = float(t[c][k]);
    out.write(reinterpret_cast<const char*>(record), sizeof record);
    out.write("\0\0", 2);
  }
}

std::vector<Triangle> cylinder(double radius, double length, int segments, const Vec3& c) {
  std::vector<Triangle> t;
  const Vec3 lo = c - 0.5 * length * Vec3::UnitZ(), hi = c + 0.5 * length * Vec3::UnitZ();
  for (int i = 0; i < segments; ++i) {
    const double a0 = 2 * kPi * i / segments, a1 = 2 * kPi * (i + 1) / segments;
    const Vec3 r0(radius * std::cos(a0), radius * std::sin(a0), 0),
        r1(radius * std::cos(a1), radius * std::sin(a1), 0);
    t.push_back({lo + r0, lo + r1, hi + r1});
    t.push_back({lo + r0, hi + r1, hi + r0});
    t.push_back({hi, hi + r0, hi + r1});
    t.push_back({lo, lo + r1, lo + r0});
  }
  return t;
}

std::vector<Triangle> box(const Vec3& lo, const Vec3& hi) {
  const Vec3 v[8] = {{lo.x(), lo.y(), lo.z()}, {hi.x(), lo.y(), lo.z()}, {hi.x(), hi.y(), lo.z()},
                     {lo.x(), hi.y(), lo.z()}, {lo.x(), lo.y(), hi.z()}, {hi.x(), lo.y(), hi.z()},
                     {hi.x(), hi.y(), hi.z()}, {lo.x(), hi.y(), hi.z()}};
  const int f[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                        {2, 3, 7}, {2, 7, 6}, {1, 2, 6}, {1, 6, 5}, {0, 4, 7}, {0, 7, 3}};
  std::vector<Triangle> t;
  for (const auto& k : f) t.push_back({v[k[0]], v[k[1]], v[k[2]]});
  return t;
}

std::vector<Triangle> centred_box(const Vec3& size) { return box(-0.5 * size, 0.5 * size); }

void write_stl_machine(const fs::path& dir, double mm, int drum_segments) {
  fs::create_directories(dir);
  auto scaled = [&](std::vector<Triangle> t) {
    for (Triangle& tri : t)
      for (Vec3& v : tri) v *= mm;
    return t;
  };
  write_stl(dir / "drum.stl", scaled(cylinder(160, 300, drum_segments)));
  write_stl(dir / "hopper.stl", scaled(box({-50, 170, -50}, {-10, 200, 50})));
  write_stl(dir / "splitter.stl", scaled(box({150, -160, -150}, {152, -60, 150})));
}

const char* const kSceneKeys = R"(
time: {step: 1 ms, end: 0.1 s}
gravity: [0, -9.81, 0]
materials:
  steel: {friction: 0.3}
)";

std::string machine_annotations(const std::string& drum_axis, const std::string& extra) {
  return "parts:\n"
         "  drum: {role: drum, material: steel, speed: 44.8 rpm, rotation_axis: " +
         drum_axis +
         "}\n"
         "  hopper: {role: hopper, material: steel}\n"
         "  \"split*\": {role: splitter, material: steel}\n" +
         extra + kSceneKeys;
}

Exported run(const fs::path& input, const std::string& annotations, const fs::path& work,
             const std::vector<std::string>& include_paths) {
  const fs::path file = work / "annotations.yaml";
  std::ofstream(file) << annotations;
  Exported e;
  e.folder = work / "out";
  std::ostringstream out, err;
  e.code = exporter::run_export(
      {input.string(), file.string(), e.folder.string(), false, include_paths}, out, err);
  e.out = out.str();
  e.err = err.str();
  if (e.code == 0) {
    e.scene = YAML::LoadFile((e.folder / "scene.yaml").string());
    e.report = nlohmann::json::parse(read_text(e.folder / "export_report.json"));
  }
  return e;
}

YAML::Node body(const Exported& e, const std::string& name) {
  for (const auto& b : e.scene["bodies"])
    if (b["name"].as<std::string>() == name) return b;
  ADD_FAILURE() << "no body " << name;
  return {};
}

Vec3 vec(const YAML::Node& n) { return {n[0].as<double>(), n[1].as<double>(), n[2].as<double>()}; }

Mat3 pose_rotation(const YAML::Node& body) {
  const YAML::Node r = body["pose"]["rotation"];
  if (!r) return Mat3::Identity();
  const std::string angle = r["angle"].as<std::string>();
  EXPECT_TRUE(angle.ends_with(" deg")) << angle;
  return Eigen::AngleAxisd(std::stod(angle) * kPi / 180, vec(r["axis"]).normalized())
      .toRotationMatrix();
}

const nlohmann::json& report_part(const Exported& e, const std::string& name) {
  for (const auto& p : e.report["parts"])
    if (p["name"] == name) return p;
  throw std::runtime_error("no part " + name + " in the report");
}

Vec3 json_vec(const nlohmann::json& j) {
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

std::pair<Vec3, Vec3> stl_bounds(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  in.seekg(80);
  std::uint32_t n = 0;
  in.read(reinterpret_cast<char*>(&n), 4);
  Vec3 lo = Vec3::Constant(1e300), hi = -lo;
  for (std::uint32_t t = 0; t < n; ++t) {
    float r[12];
    in.read(reinterpret_cast<char*>(r), sizeof r);
    in.ignore(2);
    for (int c = 1; c < 4; ++c) {
      const Vec3 v(r[3 * c], r[3 * c + 1], r[3 * c + 2]);
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  return {lo, hi};
}

void expect_validates(const Exported& e, const std::string& extra) {
  const auto v = ces::test::ces_sim("validate " + (e.folder / "scene.yaml").string() + extra);
  EXPECT_EQ(v.code, 0) << v.out << v.err;
}

void expect_nothing_written(const Exported& e) {
  EXPECT_FALSE(fs::exists(e.folder));
  for (const auto& entry : fs::directory_iterator(e.folder.parent_path()))
    EXPECT_FALSE(entry.path().filename().string().starts_with(".out.")) << entry.path();
}

void expect_hopper(const Exported& e) {
  const YAML::Node hopper = body(e, "hopper");
  ASSERT_TRUE(hopper["geometry"]["mesh"]) << hopper;
  const fs::path mesh = e.folder / hopper["geometry"]["mesh"]["file"].as<std::string>();
  const auto [lo, hi] = stl_bounds(mesh);
  EXPECT_LT((lo - Vec3(-0.05, 0.17, -0.05)).norm(), 1e-7);  // float coordinates
  EXPECT_LT((hi - Vec3(-0.01, 0.20, 0.05)).norm(), 1e-7);
  const auto& box = report_part(e, "hopper")["mesh"]["bounding_box"];
  EXPECT_LT((json_vec(box["min"]) - Vec3(-0.05, 0.17, -0.05)).norm(), 1e-9);
  EXPECT_LT((json_vec(box["max"]) - Vec3(-0.01, 0.20, 0.05)).norm(), 1e-9);
  EXPECT_EQ(report_part(e, "hopper")["mesh"]["open_edges"], 0);
}

void expect_splitter_box(const Exported& e) {
  const YAML::Node s = body(e, "splitter");
  ASSERT_TRUE(s["geometry"]["box"]) << s;
  EXPECT_LT((vec(s["geometry"]["box"]["size"]) - Vec3(0.002, 0.1, 0.3)).norm(), 1e-6);
  EXPECT_LT((vec(s["pose"]["position"]) - Vec3(0.151, -0.11, 0)).norm(), 1e-6);
}

}  // namespace ces::export_test
