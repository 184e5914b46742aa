// The CAD side: named parts with their triangles in metres, read from a STEP
// assembly (OpenCASCADE) or from a folder of STL/OBJ files (assimp).
#pragma once
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "fit.hpp"
#include "mesh.hpp"

namespace ces::exporter {

// Bad input (unreadable file, wrong units, ...): the command exits with 2.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The largest cylindrical surface of a STEP part, from its exact geometry.
struct ExactCylinder {
  Cylinder cylinder;
  int faces = 0;            // faces of that surface (CAD often splits one in two)
  int other_cylinders = 0;  // cylindrical faces of other radii or axes, ignored
};

struct Part {
  std::string name;                             // product name (STEP) or file stem (STL/OBJ)
  std::string instance;                         // assembly instance name when the file gives one
  std::string source;                           // where it was read from, for messages
  Mesh mesh;                                    // metres, raw triangles (cleaned by the exporter)
  std::optional<ExactCylinder> exact_cylinder;  // STEP only
};

// Metres per unit, for the names annotations use (mm, cm, m, in) and the
// names STEP files declare (millimetre, inch, ...); nullopt if unknown.
std::optional<double> unit_scale(const std::string& name);

struct StepOptions {
  double deflection = 1e-4;           // m: largest chord error of the tessellation
  double angle = 20.0 * kPi / 180.0;  // rad: largest angle between neighbouring facets
  // Metres per file unit, when the annotations override the file's own unit.
  std::optional<double> unit_override;
};

// Throws InputError. `file_unit` receives the unit the file declares.
std::vector<Part> read_step(const std::string& path, const StepOptions& options,
                            std::string& file_unit);
bool have_step_reader();

// One part per file (name: the file stem), coordinates times `scale`.
// `path` is a folder of .stl/.obj files or one such file. Throws InputError.
std::vector<Part> read_mesh_files(const std::string& path, double scale);

}  // namespace ces::exporter
