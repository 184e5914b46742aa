#include "support.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace ces::test {
namespace {

std::string temp_prefix() { return "ces_test_" + std::to_string(::getpid()) + "_"; }

class TempCleanup : public ::testing::Environment {
  void TearDown() override {
    for (const auto& e : fs::directory_iterator(fs::temp_directory_path()))
      if (e.path().filename().string().starts_with(temp_prefix())) fs::remove_all(e.path());
  }
};
[[maybe_unused]] const auto* const kCleanup = ::testing::AddGlobalTestEnvironment(new TempCleanup);

}  // namespace

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / (temp_prefix() + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

Outcome ces_sim(const std::string& args) {
  static int calls = 0;
  const fs::path io = fs::temp_directory_path() / (temp_prefix() + "io_" + std::to_string(calls++));
  const std::string command = std::string(CES_SIM_BINARY) + " " + args + " > " + io.string() +
                              ".out 2> " + io.string() + ".err";
  const int status = std::system(command.c_str());
  Outcome o;
  o.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  o.out = read_text(io.string() + ".out");
  o.err = read_text(io.string() + ".err");
  fs::remove(io.string() + ".out");
  fs::remove(io.string() + ".err");
  return o;
}

nlohmann::json report_data(const fs::path& report) {
  const std::string page = read_text(report);
  const std::string open = "<script type=\"application/json\" id=\"data\">";
  const std::size_t begin = page.find(open);
  if (begin == std::string::npos) return nullptr;
  const std::size_t start = begin + open.size();
  return nlohmann::json::parse(page.substr(start, page.find("</script>", start) - start));
}

RigidBody ground_plane(const Vec3& normal, int material) {
  RigidBody b;
  b.name = "ground";
  b.shape = geo::Plane{normal.normalized(), 0.0};
  b.material = material;
  return b;
}

}  // namespace ces::test
