// Particle trajectories, one frame every `every` seconds of simulated time:
//  - VTK, indexed by trajectories.pvd (rewritten after every frame, so it
//    always lists every frame on disk), each frame a multiblock of:
//      particles  trajectories/frame_NNNNNN.vtp: a point and a vertex per
//                 particle, with its id, size, material, shape,
//                 orientation, velocity, spin, charge and birth time;
//      spheres    trajectories/frame_NNNNNN_spheres.vtp (scenes with sphere
//                 clusters): a point per sphere of every particle, with its
//                 diameter, to draw clusters as their spheres;
//      machine    trajectories/machine_static.vtp, written once: the bodies
//                 that do not move and the electrodes; and
//                 trajectories/frame_NNNNNN_machine.vtp: those that move,
//                 at the frame's pose;
//    binary, zlib-compressed (output/vtk_xml.hpp);
//  - trajectories.csv, one row per particle per frame.
// Particles appear in id order, so equal runs give equal files.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "common/serial.hpp"
#include "model/state.hpp"
#include "output/files.hpp"
#include "output/surfaces.hpp"
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
  void write_vtk(const State& state);
  std::string particles_vtp(const State& state) const;
  std::string spheres_vtp(const State& state) const;
  std::string machine_vtp(const State& state, const std::vector<int>& bodies,
                          bool electrodes) const;
  void write_pvd();
  // The .vtp files of a frame, relative to trajectories/.
  std::vector<std::string> frame_files(std::size_t frame) const;
  void append_csv(const State& state);
  bool has_static_machine() const { return !static_bodies_.empty() || !sim_->electrodes.empty(); }

  std::filesystem::path dir_;
  const Simulation* sim_;
  std::vector<double> shape_size_;
  double every_ = 0.0;
  std::uint64_t next_frame_ = 0;
  std::vector<double> frame_times_;
  AppendFile csv_;
  std::vector<std::size_t> order_;  // particle indices by id
  std::string text_;                // reused frame buffer
  std::vector<std::string> material_names_, shape_names_, part_names_;
  std::vector<int> static_bodies_, moving_bodies_;  // Model::bodies indices
  bool clusters_ = false;         // some shape has more than one sphere
  PlaneExtent plane_;
};

}  // namespace ces::output
