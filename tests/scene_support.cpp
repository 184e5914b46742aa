#include "scene_support.hpp"

#include <gtest/gtest.h>

#include <fstream>

namespace ces::test {

namespace fs = std::filesystem;

TempDir::TempDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  path_ = fs::temp_directory_path() /
          ("ces_scene_" + std::string(info->test_suite_name()) + "_" + info->name());
  fs::remove_all(path_);
  fs::create_directories(path_);
}

TempDir::~TempDir() { fs::remove_all(path_); }

std::string TempDir::write(const std::string& name, const std::string& text) const {
  const fs::path p = path_ / name;
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
  return p.string();
}

std::vector<scene::Diagnostic> load_errors(const std::string& path,
                                           const scene::LoadOptions& options) {
  try {
    scene::load(path, options);
  } catch (const scene::SceneError& e) {
    return e.diagnostics();
  }
  ADD_FAILURE() << path << " loaded without errors";
  return {};
}

std::string all(const std::vector<scene::Diagnostic>& list) {
  std::string s;
  for (const scene::Diagnostic& d : list) s += d.str() + "\n";
  return s;
}

}  // namespace ces::test
