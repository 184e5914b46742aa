#include "output/collected_log.hpp"

#include <string>

#include "output/tables.hpp"

namespace ces::output {

CollectedLog::CollectedLog(const Simulation& sim, const std::filesystem::path& dir, Start start)
    : sim_(sim), crossings_path_(dir / "crossings.csv"), lost_path_(dir / "lost.csv") {
  if (start == Start::Resume) return;
  crossings_ = AppendFile(crossings_path_);
  crossings_.write(std::string(kCrossingsHeader) + '\n');
  lost_ = AppendFile(lost_path_);
  lost_.write(std::string(kLostHeader) + '\n');
}

void CollectedLog::record(const Collection& c) {
  if (!c.crossings().empty()) crossings_.write(crossing_rows(sim_, c));
  if (!c.losses().empty()) lost_.write(lost_rows(sim_, c));
}

void CollectedLog::close() {
  crossings_.close();
  lost_.close();
}

void CollectedLog::save(ByteWriter& out) {
  out.value(crossings_.flush());
  out.value(lost_.flush());
}

void CollectedLog::load(ByteReader& in) {
  const auto crossings = in.value<std::uint64_t>();
  const auto lost = in.value<std::uint64_t>();
  crossings_ = AppendFile(crossings_path_, crossings);
  lost_ = AppendFile(lost_path_, lost);
}

}  // namespace ces::output
