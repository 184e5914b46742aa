// ces-export end to end: CAD + annotations -> a folder with scene.yaml,
// meshes/*.stl and export_report.json, validated by the simulator's own
// loader before it appears. Nothing is left behind on failure: the folder
// is built beside the target and moved into place at the end, file by file
// over an earlier export, whose other files stay.
#pragma once
#include <ostream>
#include <string>
#include <vector>

namespace ces::exporter {

struct ExportOptions {
  std::string input;        // a STEP file, an STL/OBJ file, or a folder of them
  std::string annotations;  // annotations.yaml
  std::string output;       // folder to create (or an earlier export to replace)
  bool quiet = false;       // no report on stdout (warnings still go to stderr)
  // Folders the annotations' includes may come from besides their own.
  std::vector<std::string> include_paths;
};

// Exit codes, as ces-sim's.
inline constexpr int kExitOk = 0;
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitInternal = 4;

// The report goes to `out`, warnings and errors to `err`. Returns an exit code.
int run_export(const ExportOptions& options, std::ostream& out, std::ostream& err);

}  // namespace ces::exporter
