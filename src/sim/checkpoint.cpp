#include "sim/checkpoint.hpp"

#include <cstring>
#include <fstream>

#include "common/hash.hpp"
#include "common/serial.hpp"
#include "output/files.hpp"

namespace ces {
namespace {

// The head's first bytes, with the format's version: a checkpoint from
// another version of the format is refused, never misread.
constexpr std::string_view kMagic = "ces-sim checkpoint 9\n";

// The last 8 bytes: FNV-1a of all before them. A change confined to one
// byte always changes it (each step of the hash is a bijection of its
// state), so a flipped bit in the state is refused, not resumed from.
std::uint64_t checksum(std::string_view bytes) { return fnv1a(bytes); }

}  // namespace

std::filesystem::path checkpoint_file(const std::filesystem::path& dir) {
  return dir / "partial" / "checkpoint.bin";
}

void write_checkpoint(const std::filesystem::path& file, const Checkpoint& c) {
  // The body, most of the bytes, goes to the file from where it is: a copy
  // of the whole would double the run's memory while it writes.
  ByteWriter head;
  head.text(kMagic);
  head.text(c.scene_path);
  head.text(c.scene_hash);
  head.text(c.resolved_yaml);
  head.value(std::uint64_t(c.body.size()));
  ByteWriter tail;
  tail.value(fnv1a(c.body, checksum(head.bytes())));
  output::AtomicFile out(file);
  for (const std::string_view part :
       {std::string_view(head.bytes()), std::string_view(c.body), std::string_view(tail.bytes())})
    out.write(part);
  out.commit();
}

namespace {

std::string read_all(const std::filesystem::path& file) {
  // A pipe would be waited on for ever, a folder's size is read as an
  // exabyte: neither is opened.
  std::error_code error;
  if (std::filesystem::exists(file, error) && !std::filesystem::is_regular_file(file, error))
    throw output::IoError("the checkpoint " + file.string() + " is not a regular file");
  std::ifstream in(file, std::ios::binary | std::ios::ate);
  if (!in) throw output::IoError("no checkpoint at " + file.string());
  std::string bytes(std::size_t(in.tellg()), '\0');
  in.seekg(0);
  if (!in.read(bytes.data(), std::streamsize(bytes.size())))
    throw output::IoError("cannot read the checkpoint " + file.string());
  return bytes;
}

}  // namespace

Checkpoint read_checkpoint(const std::filesystem::path& file) {
  std::string bytes = read_all(file);
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
    const auto length = r.value<std::uint64_t>();
    if (r.position() > sum_at || length != sum_at - r.position())
      throw CorruptData("its state is not the length it says");
    // The state moves out of the bytes read, not copied: it is most of them.
    const std::size_t start = r.position();
    bytes.resize(sum_at);
    bytes.erase(0, start);
    c.body = std::move(bytes);
  } catch (const CorruptData& e) {
    throw CorruptData(file.string() + ": " + e.what());
  }
  return c;
}

}  // namespace ces
