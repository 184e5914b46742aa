// Built without OpenCASCADE: STL/OBJ still work, STEP says what is missing.
#include "parts.hpp"

namespace ces::exporter {

bool have_step_reader() { return false; }

std::vector<Part> read_step(const std::string& path, const StepOptions&, std::string&) {
  throw InputError("cannot read " + path +
                   ": ces-export was built without OpenCASCADE, which STEP files need; install "
                   "libocct-data-exchange-dev, libocct-ocaf-dev and "
                   "libocct-modeling-algorithms-dev (bash .ci/setup does) and rebuild, or export "
                   "the parts as STL/OBJ files");
}

}  // namespace ces::exporter
