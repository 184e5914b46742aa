// crossings.csv and lost.csv, written as the run goes: each step's records
// are appended when the step ends, so the run's memory does not grow with
// the particles it has collected, and a run that stops for any reason
// keeps the records of every step it took.
#pragma once
#include <filesystem>

#include "common/serial.hpp"
#include "output/files.hpp"
#include "output/records.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

class CollectedLog {
 public:
  // The files in `dir`; a resumed run opens them in load().
  CollectedLog(const Simulation& sim, const std::filesystem::path& dir, Start start);

  // The step's records (Collection::crossings(), losses()).
  void record(const Collection& c);
  // The files complete on the disk (the run's end).
  void close();

  // The files' lengths, for checkpoints; load() cuts them back to those
  // and appends from there.
  void save(ByteWriter& out);
  void load(ByteReader& in);

 private:
  const Simulation& sim_;
  std::filesystem::path crossings_path_, lost_path_;
  AppendFile crossings_, lost_;
};

}  // namespace ces::output
