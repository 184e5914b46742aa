// Where particles leave a run: the collect stage, which takes out of the
// state the particles that crossed a collector plane this step (collected)
// and those that left the domain or whose state stopped being finite (lost,
// with the reason). Keeps the exact tallies behind bins.csv, products.csv and
// the summary's balance over the whole run, and the records of the last
// step only: a long run collects millions of particles, so their records
// go to the disk as they come (output::CollectedLog), not into memory.
#pragma once
#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include <optional>

#include "collect/collector.hpp"
#include "common/serial.hpp"
#include "common/tally.hpp"
#include "geometry/shapes.hpp"
#include "model/state.hpp"

namespace ces::collect {

struct Crossing {
  std::uint64_t id = 0;
  double time = 0.0;  // when the centre crossed the plane (s)
  Vec3 position;      // where it crossed
  Vec3 velocity;
  double along = 0.0;  // coordinate along the collector axis (m)
  double diameter = 0.0;
  double mass = 0.0;
  double charge = 0.0;  // C
  int material = 0;
  int collector = 0;
  int bin = -1;      // -1: outside the collector's bins
  int product = -1;  // -1: in no product
};

enum class LossReason { LeftDomain, NonFinite };
inline constexpr std::array<LossReason, 2> kLossReasons = {LossReason::LeftDomain,
                                                           LossReason::NonFinite};
std::string_view to_string(LossReason r);

struct Loss {
  std::uint64_t id = 0;
  double time = 0.0;
  Vec3 position, velocity;
  double diameter = 0.0;
  double mass = 0.0;
  int material = 0;
  LossReason reason = LossReason::LeftDomain;
};

// Tallies of one collector, each indexed [slot * materials + material].
struct CollectorTallies {
  std::vector<Tally> bins;      // slot = bin
  std::vector<Tally> products;  // slot = product
  std::vector<Tally> outside;   // crossed outside the bins; slot = 0
  std::vector<Tally> total;     // everything collected; slot = 0
  // Per product and material, as `products`: the sum of the particles'
  // squared masses (kg^2), for the products' standard errors
  // (output/tables.hpp). A double, not exact units: an error estimate
  // needs no exact balance, and the squares of a heavy particle's units
  // would overflow 128 bits.
  std::vector<double> product_squares;
};

class Collection {
 public:
  // shape_size[s]: the diameter of Model shape s at scale 1 (m). Without a
  // domain nothing is lost by leaving it.
  Collection(std::vector<Collector> collectors, std::optional<geo::Aabb> domain,
             std::size_t materials, std::vector<double> shape_size);

  // The stage, after the step that ended at t_end and took h: removes what
  // it collects or loses from `particles`.
  void collect(double t_end, double h, Particles& particles);

  std::size_t material_count() const { return materials_; }
  const std::vector<CollectorTallies>& collectors() const { return tallies_; }
  const std::vector<Tally>& lost(LossReason r) const { return lost_[std::size_t(r)]; }
  // Material m over every collector, and over every way of being lost.
  Tally collected_total(std::size_t m) const;
  Tally lost_total(std::size_t m) const;
  // Material m's sum of squared masses (kg^2) over everything collected
  // and lost: the denominator's, for the recoveries' standard errors.
  double settled_squares(std::size_t m) const { return settled_squares_[m]; }

  // The last step's records, in (time, id) order.
  const std::vector<Crossing>& crossings() const { return crossings_; }
  const std::vector<Loss>& losses() const { return losses_; }

  // The tallies, for checkpoints (a checkpoint is taken between steps, so
  // the records are already written).
  void save(ByteWriter& out) const;
  void load(ByteReader& in);

 private:
  bool leaves(const Particles& p, std::size_t i, double t_end, double h);
  bool try_collect(const Particles& p, std::size_t i, double t_end, double h);
  void lose(const Particles& p, std::size_t i, double t_end, LossReason reason);
  void tally_crossing(const Crossing& c);
  void tally_squares();

  std::vector<Collector> collectors_;
  std::optional<geo::Aabb> domain_;
  std::vector<double> shape_size_;
  std::size_t materials_;
  std::vector<Vec3> axes_;  // unit bin axis per collector
  std::vector<CollectorTallies> tallies_;
  std::array<std::vector<Tally>, kLossReasons.size()> lost_;  // per material
  std::vector<double> settled_squares_;                       // per material
  std::vector<Crossing> crossings_;                           // the last step's
  std::vector<Loss> losses_;                                  // the last step's
};

}  // namespace ces::collect

namespace ces {
template <> struct PlainBytes<collect::Crossing> : std::true_type {};
template <> struct PlainBytes<collect::Loss> : std::true_type {};
}  // namespace ces
