// ces-export INPUT -a ANNOTATIONS -o FOLDER [--include-path DIR]... [--quiet]
//
// Turns a CAD export (a STEP file, or STL/OBJ files) and an annotation
// file into a ces-sim scene: FOLDER/scene.yaml, FOLDER/meshes/*.stl and
// FOLDER/export_report.json. Exit codes: 0 done, 2 bad input (nothing
// written), 4 internal error.
#include <CLI/CLI.hpp>
#include <iostream>

#include "export.hpp"
#include "parts.hpp"

int main(int argc, char** argv) {
  using namespace ces::exporter;
  ExportOptions options;
  CLI::App app{
      "ces-export: CAD (STEP, or a folder of STL/OBJ files) + annotations -> a ces-sim scene"};
  app.add_option("input", options.input,
                 "STEP file (.step/.stp), STL/OBJ file, or a folder of STL/OBJ files")
      ->required();
  app.add_option("-a,--annotations", options.annotations,
                 "annotations.yaml: roles, parameters, scene keys")
      ->required();
  app.add_option("-o,--output", options.output,
                 "Folder to write (replaces an earlier export's files)")
      ->required();
  app.add_option("--include-path", options.include_paths,
                 "Folder the annotations' includes may come from besides their own (repeatable)");
  app.add_flag("-q,--quiet", options.quiet, "No report on stdout");
  app.set_version_flag("--version",
                       std::string("ces-export ") + CES_VERSION +
                           (have_step_reader() ? " (STEP: OpenCASCADE)" : " (STEP: not built)"));
  app.footer("Exit codes: 0 done, 2 bad input (nothing written), 4 internal error.");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitBadInput;
  }
  return run_export(options, std::cout, std::cerr);
}
