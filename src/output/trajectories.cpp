#include "output/trajectories.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <variant>

#include "output/format.hpp"
#include "output/vtk_xml.hpp"

namespace ces::output {
namespace {

std::string frame_name(std::size_t frame, const char* suffix = "") {
  char name[48];
  std::snprintf(name, sizeof name, "frame_%06zu%s.vtp", frame, suffix);
  return name;
}

constexpr const char* kStaticMachine = "machine_static.vtp";

bool moves(const RigidBody& b) {
  return b.kind == BodyKind::Dynamic || (b.kind == BodyKind::Kinematic && b.motion.moves());
}

// Planes are drawn across the domain, or else across the other bodies.
PlaneExtent plane_extent(const Simulation& sim) {
  geo::Aabb box = geo::Aabb::empty();
  if (sim.domain) {
    box = *sim.domain;
  } else {
    for (const RigidBody& b : sim.model->bodies)
      if (!std::holds_alternative<geo::Plane>(b.shape)) box.grow(world_bounds(b));
  }
  if (!(box.min.array() <= box.max.array()).all()) return {};
  return {0.5 * (box.min + box.max), std::max(0.5 * (box.max - box.min).norm(), 1e-3)};
}

std::vector<std::string> shape_names(const Simulation& sim) {
  std::vector<std::string> names = sim.shape_names;
  for (std::size_t s = names.size(); s < sim.model->shapes.size(); ++s)
    names.push_back(sim.model->shapes[s].is_sphere() ? "sphere" : "cluster " + std::to_string(s));
  return names;
}

// values[i] for the particles i in `order`.
template <class T>
std::vector<T> pick(const std::vector<std::size_t>& order, const std::vector<T>& values) {
  std::vector<T> out;
  out.reserve(order.size());
  for (const std::size_t i : order) out.push_back(values[i]);
  return out;
}

// The same for vectors, their components one after the other.
std::vector<double> pick(const std::vector<std::size_t>& order, const std::vector<Vec3>& values) {
  std::vector<double> out;
  out.reserve(3 * order.size());
  for (const std::size_t i : order) {
    const Vec3& v = values[i];
    out.insert(out.end(), {v.x(), v.y(), v.z()});
  }
  return out;
}

// Quaternions as (w, x, y, z), the order of ParaView's glyph orientation.
std::vector<double> pick(const std::vector<std::size_t>& order, const std::vector<Quat>& values) {
  std::vector<double> out;
  out.reserve(4 * order.size());
  for (const std::size_t i : order) {
    const Quat& q = values[i];
    out.insert(out.end(), {q.w(), q.x(), q.y(), q.z()});
  }
  return out;
}

// names[index[i]] for the particles i in `order`.
std::vector<std::string> pick_names(const std::vector<std::size_t>& order,
                                    const std::vector<std::int32_t>& index,
                                    const std::vector<std::string>& names) {
  std::vector<std::string> out;
  out.reserve(order.size());
  for (const std::size_t i : order) out.push_back(names[std::size_t(index[i])]);
  return out;
}

}  // namespace

TrajectoryWriter::TrajectoryWriter(const std::filesystem::path& dir, const Simulation& sim,
                                   std::vector<double> shape_size, Start start)
    : dir_(dir),
      sim_(&sim),
      shape_size_(std::move(shape_size)),
      every_(sim.output.trajectories.every) {
  if (every_ <= 0.0) return;
  for (const Material& m : sim.model->materials.materials()) material_names_.push_back(m.name);
  shape_names_ = shape_names(sim);
  if (sim.output.trajectories.vtk) {
    std::filesystem::create_directories(dir_ / "trajectories");
    for (const ParticleShape& s : sim.model->shapes) clusters_ = clusters_ || !s.is_sphere();
    for (std::size_t b = 0; b < sim.model->bodies.size(); ++b) {
      const RigidBody& body = sim.model->bodies[b];
      part_names_.push_back(body.name);
      (moves(body) ? moving_bodies_ : static_bodies_).push_back(int(b));
    }
    for (const NamedElectrode& e : sim.electrodes) part_names_.push_back(e.name);
    plane_ = plane_extent(sim);
  }
  if (sim.output.trajectories.csv && start == Start::Fresh) {
    csv_ = AppendFile(dir_ / "trajectories.csv");
    csv_.write(
        "time_s,id,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,diameter_m,material,shape,charge_c,qw,qx,qy,"
        "qz,wx_radps,wy_radps,wz_radps,birth_s\n");
  }
}

void TrajectoryWriter::observe(const State& state) {
  if (every_ <= 0.0) return;
  const double due = state.time + 0.5 * sim_->model->step;
  if (due < double(next_frame_) * every_) return;
  next_frame_ = std::uint64_t(std::floor(due / every_)) + 1;
  sort_by_id(state.particles);
  if (sim_->output.trajectories.vtk) write_vtk(state);
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
  if (has_static_machine()) out.push_back(std::string("trajectories/") + kStaticMachine);
  for (std::size_t k = 0; k < frame_times_.size(); ++k)
    for (const std::string& f : frame_files(k)) out.push_back("trajectories/" + f);
  return out;
}

std::vector<std::string> TrajectoryWriter::frame_files(std::size_t frame) const {
  std::vector<std::string> out = {frame_name(frame)};
  if (clusters_) out.push_back(frame_name(frame, "_spheres"));
  if (!moving_bodies_.empty()) out.push_back(frame_name(frame, "_machine"));
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
    bool removed = false;
    for (const std::string& f : frame_files(k))
      removed = std::filesystem::remove(dir_ / "trajectories" / f) || removed;
    if (!removed) break;
  }
  if (!frame_times_.empty()) write_pvd();
}

void TrajectoryWriter::sort_by_id(const Particles& p) {
  order_.resize(p.size());
  std::iota(order_.begin(), order_.end(), std::size_t{0});
  std::sort(order_.begin(), order_.end(),
            [&](std::size_t a, std::size_t b) { return p.id[a] < p.id[b]; });
}

void TrajectoryWriter::write_vtk(const State& state) {
  const std::filesystem::path folder = dir_ / "trajectories";
  const std::size_t frame = frame_times_.size();
  write_file_atomic(folder / frame_name(frame), particles_vtp(state));
  if (clusters_) write_file_atomic(folder / frame_name(frame, "_spheres"), spheres_vtp(state));
  if (frame == 0 && has_static_machine())  // once: every frame lists it
    write_file_atomic(folder / kStaticMachine, machine_vtp(state, static_bodies_, true));
  if (!moving_bodies_.empty())
    write_file_atomic(folder / frame_name(frame, "_machine"),
                      machine_vtp(state, moving_bodies_, false));
}

std::string TrajectoryWriter::particles_vtp(const State& state) const {
  const Particles& p = state.particles;
  const std::vector<std::size_t>& o = order_;
  constexpr VtkSection point = VtkSection::PointData;
  std::vector<double> diameters, charges;
  for (const std::size_t i : o) {
    diameters.push_back(particle_diameter(shape_size_, p, i));
    charges.push_back(particle_charge(p, i));
  }
  VtpFile f(o.size());
  f.add(VtkSection::Field, "TimeValue", 1, std::vector<double>{state.time});
  f.add_strings(VtkSection::Field, "material_names", material_names_);
  f.add_strings(VtkSection::Field, "shape_names", shape_names_);
  f.set_active(point, "Scalars", "diameter");
  f.set_active(point, "Vectors", "velocity");
  f.add(point, "id", 1, pick(o, p.id));
  f.add(point, "diameter", 1, diameters);
  f.add(point, "material", 1, pick(o, p.material));
  f.add_strings(point, "material_name", pick_names(o, p.material, material_names_));
  f.add(point, "shape", 1, pick(o, p.shape));
  f.add_strings(point, "shape_name", pick_names(o, p.shape, shape_names_));
  f.add(point, "orientation", 4, pick(o, p.orientation));
  f.add(point, "velocity", 3, pick(o, p.velocity));
  f.add(point, "angular_velocity", 3, pick(o, p.angular_velocity));
  f.add(point, "charge", 1, charges);
  f.add(point, "birth", 1, pick(o, p.birth));
  f.add(VtkSection::Points, "position", 3, pick(o, p.position));
  f.add_vertex_per_point();
  return f.finish();
}

// Single precision: enough to draw them, and half the bytes of the largest
// file of a frame.
std::string TrajectoryWriter::spheres_vtp(const State& state) const {
  const Particles& p = state.particles;
  std::vector<float> centres, diameters, charges;
  std::vector<std::uint64_t> ids;
  std::vector<std::int32_t> materials;
  std::vector<std::string> names;
  for (const std::size_t i : order_) {
    const ParticleShape& s = sim_->model->shapes[std::size_t(p.shape[i])];
    for (std::size_t k = 0; k < s.centers.size(); ++k) {
      const Vec3 c = p.position[i] + p.orientation[i] * (p.scale[i] * s.centers[k]);
      centres.insert(centres.end(), {float(c.x()), float(c.y()), float(c.z())});
      diameters.push_back(float(2.0 * p.scale[i] * s.radii[k]));
      ids.push_back(p.id[i]);
      materials.push_back(p.material[i]);
      names.push_back(material_names_[std::size_t(p.material[i])]);
      charges.push_back(float(particle_charge(p, i)));
    }
  }
  VtpFile f(ids.size());
  f.add(VtkSection::Field, "TimeValue", 1, std::vector<double>{state.time});
  f.add_strings(VtkSection::Field, "material_names", material_names_);
  f.set_active(VtkSection::PointData, "Scalars", "diameter");
  f.add(VtkSection::PointData, "id", 1, ids);
  f.add(VtkSection::PointData, "diameter", 1, diameters);
  f.add(VtkSection::PointData, "material", 1, materials);
  f.add_strings(VtkSection::PointData, "material_name", names);
  f.add(VtkSection::PointData, "charge", 1, charges);
  f.add(VtkSection::Points, "position", 3, centres);
  f.add_vertex_per_point();
  return f.finish();
}

std::string TrajectoryWriter::machine_vtp(const State& state, const std::vector<int>& bodies,
                                          bool electrodes) const {
  SurfaceMesh mesh;
  for (const int b : bodies)
    add_surface(sim_->model->bodies[std::size_t(b)].shape, state.bodies.pose[std::size_t(b)], b,
                plane_, mesh);
  if (electrodes && sim_->electrostatics)
    for (std::size_t e = 0; e < sim_->electrodes.size(); ++e)
      add_z_cylinder(sim_->electrodes[e].electrode.centre, sim_->electrodes[e].electrode.radius,
                     sim_->electrostatics->drum.half_width,
                     int(sim_->model->bodies.size() + e), mesh);
  std::vector<double> points;
  for (const Vec3& v : mesh.points) points.insert(points.end(), {v.x(), v.y(), v.z()});
  std::vector<std::string> names;
  for (const std::int32_t part : mesh.part) names.push_back(part_names_[std::size_t(part)]);
  VtpFile f(mesh.points.size());
  f.add(VtkSection::Field, "TimeValue", 1, std::vector<double>{state.time});
  f.add_strings(VtkSection::Field, "part_names", part_names_);
  f.set_active(VtkSection::CellData, "Scalars", "part");
  f.add(VtkSection::CellData, "part", 1, mesh.part);
  f.add_strings(VtkSection::CellData, "part_name", names);
  f.add(VtkSection::Points, "position", 3, points);
  f.add_polygons(mesh.connectivity, mesh.offsets);
  return f.finish();
}

void TrajectoryWriter::write_pvd() {
  std::string pvd =
      "<?xml version=\"1.0\"?>\n"
      "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      "  <Collection>\n";
  for (std::size_t k = 0; k < frame_times_.size(); ++k) {
    std::string time;
    append_number(time, frame_times_[k]);
    // The reader gathers the data sets of a frame by their equal timestep.
    auto entry = [&](int part, const char* name, const std::string& file) {
      pvd += "    <DataSet timestep=\"" + time + "\" group=\"\" part=\"" + std::to_string(part) +
             "\" name=\"" + name + "\" file=\"trajectories/" + file + "\"/>\n";
    };
    entry(0, "particles", frame_name(k));
    if (clusters_) entry(1, "spheres", frame_name(k, "_spheres"));
    if (has_static_machine()) entry(2, "machine (static)", kStaticMachine);
    if (!moving_bodies_.empty()) entry(3, "machine (moving)", frame_name(k, "_machine"));
  }
  pvd += "  </Collection>\n</VTKFile>\n";
  write_file_atomic(dir_ / "trajectories.pvd", pvd);
}

void TrajectoryWriter::append_csv(const State& state) {
  const Particles& p = state.particles;
  text_.clear();
  CsvWriter row(text_);
  for (const std::size_t i : order_) {
    row << state.time << p.id[i] << p.position[i].x() << p.position[i].y() << p.position[i].z()
        << p.velocity[i].x() << p.velocity[i].y() << p.velocity[i].z()
        << particle_diameter(shape_size_, p, i) << material_names_[std::size_t(p.material[i])]
        << shape_names_[std::size_t(p.shape[i])] << particle_charge(p, i) << p.orientation[i].w()
        << p.orientation[i].x() << p.orientation[i].y() << p.orientation[i].z()
        << p.angular_velocity[i].x() << p.angular_velocity[i].y() << p.angular_velocity[i].z()
        << p.birth[i];
    row.end_row();
  }
  csv_.write(text_);
}

}  // namespace ces::output
