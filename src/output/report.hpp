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
// section (x, y; the drum's axis is z), evenly spaced over the run however
// long it turns out (a run until its particles are collected ends before
// time.end): a frame every `every_`, from one a step; whenever the frames
// reach 2 kFrames, every other one goes and `every_` doubles. So a run of
// more than kFrames steps keeps kFrames to 2 kFrames - 1 of them, and the
// run's last state as one more (finish). Past kPoints points in all, a
// frame keeps the particles whose id is a multiple of a stride, so the
// page stays a few megabytes whatever the run.
class CrossSection {
 public:
  static constexpr int kFrames = 100;
  static constexpr std::size_t kPoints = 300000;

  explicit CrossSection(double step);
  // Records a frame if one is due at state.time.
  void observe(const State& state);
  // The run's last state, once the run has ended: a frame after the evenly
  // spaced ones unless the last of them is it.
  void finish(const State& state);

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
  Frame frame(const State& state) const;
  void thin();

  double every_, step_;
  std::vector<Frame> frames_;
};

// The page. summary_json is summary.json's text; the pictures are the SVG
// texts (empty: not drawn).
std::string report_html(const Simulation& sim, const std::string& summary_json,
                        const std::string& distribution_svg, const std::string& field_svg,
                        const CrossSection& section);

}  // namespace ces::output
