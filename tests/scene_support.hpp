#pragma once
// Helpers shared by the scene tests (scene_*_test.cpp): the scenes/
// folder, a temporary folder to write scene files in, the diagnostics a
// load throws, and the smallest valid scene.
#include <filesystem>
#include <string>
#include <vector>

#include "scene/scene.hpp"

namespace ces::test {

inline const std::string kScenes = std::string(CES_SOURCE_DIR) + "/scenes/";

// A fresh folder per test, removed at the end.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string write(const std::string& name, const std::string& text) const;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// The diagnostics a load throws; fails the test if it does not throw.
std::vector<scene::Diagnostic> load_errors(const std::string& path,
                                           const scene::LoadOptions& options = {});

std::string all(const std::vector<scene::Diagnostic>& list);

inline constexpr const char* kMinimal = "ces_sim: 1\ntime: {step: 1 ms, end: 0.1 s}\n";

}  // namespace ces::test
