// libFuzzer target: scene text in, a Simulation or a SceneError out.
// Compiled twice, as YAML (fuzz_scene_yaml) and as JSON (fuzz_scene_json):
// CES_FUZZ_SCENE names the file the text is loaded as, in tests/bad_scenes/
// so that includes, meshes and CSV files of the bad-scene suite resolve.
//
// Besides crashes, sanitizer reports, hangs and memory (libFuzzer's own
// limits), it stops on what the scene layer promises: no exception but
// SceneError, every diagnostic on one line, and a loaded scene that loads
// again from its resolved text to the same hash.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "scene/scene.hpp"

namespace {

[[noreturn]] void fail(const char* what, const std::string& detail) {
  std::fprintf(stderr, "fuzz_scene: %s\n%s\n", what, detail.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const std::string path = CES_FUZZ_SCENE;
  try {
    const ces::Simulation sim = ces::scene::load_text(text, path);
    const ces::Simulation again = ces::scene::load_text(sim.resolved_yaml, path + ".resolved.yaml");
    if (again.scene_hash != sim.scene_hash)
      fail("the resolved scene loads to another hash",
           sim.resolved_yaml + "\n---\n" + again.resolved_yaml);
  } catch (const ces::scene::SceneError& e) {
    for (const ces::scene::Diagnostic& d : e.diagnostics())
      if (d.str().find('\n') != std::string::npos) fail("a diagnostic spans lines", d.str());
  }
  return 0;
}
