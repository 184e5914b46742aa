// A run's checkpoint, DIR/partial/checkpoint.bin: a head that names the
// scene (the resolved scene text and the path it was loaded as, so that
// `ces-sim resume` rebuilds the same Simulation) and a body that holds the
// run's state (the world, the observers' sums, the lengths of the files
// written so far). Written atomically: a kill during the write leaves the
// previous checkpoint.
#pragma once
#include <filesystem>
#include <string>

namespace ces {

struct Checkpoint {
  std::string scene_path;     // as loaded: relative paths in the scene start from its folder
  std::string scene_hash;     // of the resolved text
  std::string resolved_yaml;  // the scene as run
  std::string body;           // the state, as the run wrote it
};

std::filesystem::path checkpoint_file(const std::filesystem::path& dir);

void write_checkpoint(const std::filesystem::path& file, const Checkpoint& c);
// Throws output::IoError when there is none, CorruptData when it is damaged
// or from another build.
Checkpoint read_checkpoint(const std::filesystem::path& file);

}  // namespace ces
