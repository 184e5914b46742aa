#include "sim/checkpoint.hpp"

#include <cstring>
#include <fstream>
#include <iterator>

#include "common/hash.hpp"
#include "common/serial.hpp"
#include "output/files.hpp"

namespace ces {
namespace {

// The head's first bytes, with the format's version: a checkpoint from
// another version of the format is refused, never misread.
constexpr std::string_view kMagic = "ces-sim checkpoint 7\n";

// The last 8 bytes: FNV-1a of all before them. A change confined to one
// byte always changes it (each step of the hash is a bijection of its
// state), so a flipped bit in the state is refused, not resumed from.
std::uint64_t checksum(std::string_view bytes) { return fnv1a(bytes); }

}  // namespace

std::filesystem::path checkpoint_file(const std::filesystem::path& dir) {
  return dir / "partial" / "checkpoint.bin";
}

void write_checkpoint(const std::filesystem::path& file, const Checkpoint& c) {
  ByteWriter out;
  out.text(kMagic);
  out.text(c.scene_path);
  out.text(c.scene_hash);
  out.text(c.resolved_yaml);
  out.text(c.body);
  out.value(checksum(out.bytes()));
  output::write_file_atomic(file, out.bytes());
}

Checkpoint read_checkpoint(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw output::IoError("no checkpoint at " + file.string());
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  ByteReader r(bytes);
  Checkpoint c;
  try {
    if (r.text() != kMagic) throw CorruptData("not a checkpoint of this version of ces-sim");
    const std::size_t sum_at = bytes.size() - sizeof(std::uint64_t);
    std::uint64_t sum = 0;
    std::memcpy(&sum, bytes.data() + sum_at, sizeof sum);
    if (sum != checksum(std::string_view(bytes).substr(0, sum_at)))
      throw CorruptData("damaged: its checksum does not match its bytes");
    c.scene_path = r.text();
    c.scene_hash = r.text();
    c.resolved_yaml = r.text();
    c.body = r.text();
    r.value(sum);
    if (!r.at_end()) throw CorruptData("bytes after its end");
  } catch (const CorruptData& e) {
    throw CorruptData(file.string() + ": " + e.what());
  }
  return c;
}

}  // namespace ces
