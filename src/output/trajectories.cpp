#include "output/trajectories.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "output/format.hpp"

namespace ces::output {
namespace {

std::string frame_name(std::size_t frame) {
  char name[40];
  std::snprintf(name, sizeof name, "frame_%06zu.vtp", frame);
  return name;
}

void append_vec(std::string& out, const Vec3& v) {
  append_number(out, v.x());
  out += ' ';
  append_number(out, v.y());
  out += ' ';
  append_number(out, v.z());
  out += '\n';
}

// One <DataArray> whose values are produced by item(out, i) for i in order.
template <class Item>
void data_array(std::string& out, const char* type, const char* name, int components, std::size_t n,
                Item item) {
  out += "        <DataArray type=\"";
  out += type;
  out += "\" Name=\"";
  out += name;
  out += "\" NumberOfComponents=\"";
  append_number(out, components);
  out += "\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < n; ++i) item(out, i);
  out += "        </DataArray>\n";
}

void line(std::string& out, auto value) {
  append_number(out, value);
  out += '\n';
}

}  // namespace

TrajectoryWriter::TrajectoryWriter(const std::filesystem::path& dir, const Simulation& sim,
                                   std::vector<double> shape_size, Start start)
    : dir_(dir),
      sim_(&sim),
      shape_size_(std::move(shape_size)),
      every_(sim.output.trajectories.every) {
  if (every_ <= 0.0) return;
  if (sim.output.trajectories.vtk) std::filesystem::create_directories(dir_ / "trajectories");
  if (sim.output.trajectories.csv && start == Start::Fresh) {
    csv_ = AppendFile(dir_ / "trajectories.csv");
    csv_.write("time_s,id,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,diameter_m,material\n");
  }
}

void TrajectoryWriter::observe(const State& state) {
  if (every_ <= 0.0) return;
  const double due = state.time + 0.5 * sim_->model->step;
  if (due < double(next_frame_) * every_) return;
  next_frame_ = std::uint64_t(std::floor(due / every_)) + 1;
  sort_by_id(state.particles);
  if (sim_->output.trajectories.vtk) write_vtp(state);
  frame_times_.push_back(state.time);
  if (sim_->output.trajectories.vtk) write_pvd();
  if (csv_.is_open()) append_csv(state);
}

void TrajectoryWriter::close() { csv_.close(); }

std::vector<std::string> TrajectoryWriter::files() const {
  std::vector<std::string> out;
  if (every_ <= 0.0) return out;
  if (sim_->output.trajectories.csv) out.push_back("trajectories.csv");
  if (!sim_->output.trajectories.vtk || frame_times_.empty()) return out;
  out.push_back("trajectories.pvd");
  for (std::size_t k = 0; k < frame_times_.size(); ++k)
    out.push_back("trajectories/" + frame_name(k));
  return out;
}

void TrajectoryWriter::save(ByteWriter& out) {
  out.value(next_frame_);
  out.values(frame_times_);
  out.value(csv_.flush());
}

void TrajectoryWriter::load(ByteReader& in) {
  in.value(next_frame_);
  in.values(frame_times_);
  const auto length = in.value<std::uint64_t>();
  if (every_ <= 0.0) return;
  if (sim_->output.trajectories.csv) csv_ = AppendFile(dir_ / "trajectories.csv", length);
  if (!sim_->output.trajectories.vtk) return;
  // Frames after the checkpoint: written again as the run goes on.
  for (std::size_t k = frame_times_.size();; ++k) {
    const std::filesystem::path frame = dir_ / "trajectories" / frame_name(k);
    if (!std::filesystem::remove(frame)) break;
  }
  if (!frame_times_.empty()) write_pvd();
}

void TrajectoryWriter::sort_by_id(const Particles& p) {
  order_.resize(p.size());
  std::iota(order_.begin(), order_.end(), std::size_t{0});
  std::sort(order_.begin(), order_.end(),
            [&](std::size_t a, std::size_t b) { return p.id[a] < p.id[b]; });
}

void TrajectoryWriter::write_vtp(const State& state) {
  const Particles& p = state.particles;
  const std::size_t n = order_.size();
  text_ =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
      "header_type=\"UInt64\">\n"
      "  <PolyData>\n"
      "    <FieldData>\n"
      "      <DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" "
      "format=\"ascii\">";
  append_number(text_, state.time);
  text_ += "</DataArray>\n    </FieldData>\n    <Piece NumberOfPoints=\"";
  append_number(text_, n);
  text_ += "\" NumberOfVerts=\"";
  append_number(text_, n);
  text_ +=
      "\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n"
      "      <PointData Scalars=\"diameter\" Vectors=\"velocity\">\n";
  data_array(text_, "UInt64", "id", 1, n,
             [&](std::string& o, std::size_t i) { line(o, p.id[order_[i]]); });
  data_array(text_, "Float64", "diameter", 1, n, [&](std::string& o, std::size_t i) {
    line(o, p.scale[order_[i]] * shape_size_[std::size_t(p.shape[order_[i]])]);
  });
  data_array(text_, "Int32", "material", 1, n,
             [&](std::string& o, std::size_t i) { line(o, int(p.material[order_[i]])); });
  data_array(text_, "Float64", "charge", 1, n,
             [&](std::string& o, std::size_t i) { line(o, p.charge[order_[i]]); });
  data_array(text_, "Float64", "velocity", 3, n,
             [&](std::string& o, std::size_t i) { append_vec(o, p.velocity[order_[i]]); });
  text_ += "      </PointData>\n      <Points>\n";
  data_array(text_, "Float64", "position", 3, n,
             [&](std::string& o, std::size_t i) { append_vec(o, p.position[order_[i]]); });
  text_ += "      </Points>\n      <Verts>\n";
  data_array(text_, "Int64", "connectivity", 1, n,
             [](std::string& o, std::size_t i) { line(o, std::int64_t(i)); });
  data_array(text_, "Int64", "offsets", 1, n,
             [](std::string& o, std::size_t i) { line(o, std::int64_t(i + 1)); });
  text_ += "      </Verts>\n    </Piece>\n  </PolyData>\n</VTKFile>\n";
  write_file_atomic(dir_ / "trajectories" / frame_name(frame_times_.size()), text_);
}

void TrajectoryWriter::write_pvd() {
  std::string pvd =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      "  <Collection>\n";
  for (std::size_t k = 0; k < frame_times_.size(); ++k) {
    pvd += "    <DataSet timestep=\"";
    append_number(pvd, frame_times_[k]);
    pvd += "\" group=\"\" part=\"0\" file=\"trajectories/" + frame_name(k) + "\"/>\n";
  }
  pvd += "  </Collection>\n</VTKFile>\n";
  write_file_atomic(dir_ / "trajectories.pvd", pvd);
}

void TrajectoryWriter::append_csv(const State& state) {
  const Particles& p = state.particles;
  const auto& materials = sim_->model->materials.materials();
  text_.clear();
  CsvWriter row(text_);
  for (const std::size_t i : order_) {
    row << state.time << p.id[i] << p.position[i].x() << p.position[i].y() << p.position[i].z()
        << p.velocity[i].x() << p.velocity[i].y() << p.velocity[i].z()
        << p.scale[i] * shape_size_[std::size_t(p.shape[i])]
        << materials[std::size_t(p.material[i])].name;
    row.end_row();
  }
  csv_.write(text_);
}

}  // namespace ces::output
