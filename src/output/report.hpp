// report.html: one self-contained page (no network: its styles, scripts,
// pictures and data are inside it) that a browser opens on a run's folder:
// the products, the balance, the solver's figures, the warnings, the landing
// distribution, the field picture, and an animation of the machine's cross
// section with the particles coloured by material or by charge.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "common/serial.hpp"
#include "model/state.hpp"
#include "spec/simulation.hpp"

namespace ces::output {

// The animation's frames: the particles' centres projected on the cross
// section (x, y; the drum's axis is z), sampled at kFrames times over the
// run. Past kPoints points in all, a frame keeps the particles whose id is a
// multiple of a stride, so the page stays a few megabytes whatever the run.
class CrossSection {
 public:
  static constexpr int kFrames = 100;
  static constexpr std::size_t kPoints = 150000;

  CrossSection(const Simulation& sim);
  // Records a frame if one is due at state.time.
  void observe(const State& state);

  struct Frame {
    double time = 0.0;
    std::vector<std::int32_t> x, y;  // 0.1 mm
    std::vector<std::int32_t> material;
    std::vector<float> charge;  // C
  };
  const std::vector<Frame>& frames() const { return frames_; }

  void save(ByteWriter& out) const;
  void load(ByteReader& in);

 private:
  double every_, step_;
  std::vector<Frame> frames_;
};

// The page. summary_json is summary.json's text; the pictures are the SVG
// texts (empty: not drawn).
std::string report_html(const Simulation& sim, const std::string& summary_json,
                        const std::string& distribution_svg, const std::string& field_svg,
                        const CrossSection& section);

}  // namespace ces::output
