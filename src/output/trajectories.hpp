// Particle trajectories, one frame every `every` seconds of simulated time:
//  - VTK XML PolyData, one trajectories/frame_NNNNNN.vtp per frame (points:
//    particle centres; point data: id, diameter, material, charge, velocity;
//    one vertex cell per point so ParaView draws them), indexed by
//    trajectories.pvd, which is rewritten after every frame so it always
//    lists every frame on disk;
//  - trajectories.csv, one row per particle per frame.
// Particles appear in id order, so equal runs give equal files.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "common/serial.hpp"
#include "model/state.hpp"
#include "output/files.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

class TrajectoryWriter {
 public:
  TrajectoryWriter(const std::filesystem::path& dir, const Simulation& sim,
                   std::vector<double> shape_size, Start start = Start::Fresh);

  // Writes a frame if one is due at state.time.
  void observe(const State& state);
  // trajectories.csv complete on the disk (the run's end).
  void close();
  std::size_t frames() const { return frame_times_.size(); }
  // The files written so far, relative to the output folder.
  std::vector<std::string> files() const;

  // The frames so far and trajectories.csv's length, for checkpoints; load()
  // removes the frames written after the checkpoint and cuts the csv back.
  void save(ByteWriter& out);
  void load(ByteReader& in);

 private:
  void sort_by_id(const Particles& p);
  void write_vtp(const State& state);
  void write_pvd();
  void append_csv(const State& state);

  std::filesystem::path dir_;
  const Simulation* sim_;
  std::vector<double> shape_size_;
  double every_ = 0.0;
  std::uint64_t next_frame_ = 0;
  std::vector<double> frame_times_;
  AppendFile csv_;
  std::vector<std::size_t> order_;  // particle indices by id
  std::string text_;                // reused frame buffer
};

}  // namespace ces::output
