#include "collect/collection.hpp"

#include <algorithm>

namespace ces::collect {
namespace {

bool finite_state(const Particles& p, std::size_t i) {
  return p.position[i].allFinite() && p.velocity[i].allFinite() &&
         p.angular_velocity[i].allFinite() && p.orientation[i].coeffs().allFinite();
}

bool contains(const geo::Aabb& box, const Vec3& x) {
  return (x.array() >= box.min.array()).all() && (x.array() <= box.max.array()).all();
}

// A step's records in (time, id) order: the order the particles are
// visited in depends on the state's layout, this one only on the run.
template <class Record>
void sort_by_time_and_id(std::vector<Record>& records) {
  std::sort(records.begin(), records.end(), [](const Record& a, const Record& b) {
    return a.time != b.time ? a.time < b.time : a.id < b.id;
  });
}

// Bin index of `along`, or -1 outside [from, to).
int bin_of(const Collector& c, double along) {
  if (!(along >= c.from && along < c.to)) return -1;
  return std::min(int((along - c.from) / (c.to - c.from) * c.bins), c.bins - 1);
}

int product_of(const Collector& c, double along) {
  for (std::size_t k = 0; k < c.products.size(); ++k)
    if (along >= c.products[k].from && along < c.products[k].to) return int(k);
  return -1;
}

}  // namespace

std::string_view to_string(LossReason r) {
  return r == LossReason::LeftDomain ? "left domain" : "non-finite state";
}

Collection::Collection(std::vector<Collector> collectors, std::optional<geo::Aabb> domain,
                       std::size_t materials, std::vector<double> shape_size)
    : collectors_(std::move(collectors)),
      domain_(domain),
      shape_size_(std::move(shape_size)),
      materials_(materials) {
  for (const Collector& c : collectors_) {
    axes_.push_back(c.axis.normalized());
    CollectorTallies t;
    t.bins.resize(std::size_t(c.bins) * materials_);
    t.products.resize(c.products.size() * materials_);
    t.outside.resize(materials_);
    t.total.resize(materials_);
    t.product_squares.resize(t.products.size());
    tallies_.push_back(std::move(t));
  }
  for (std::vector<Tally>& l : lost_) l.resize(materials_);
  settled_squares_.resize(materials_);
}

Tally Collection::collected_total(std::size_t m) const {
  Tally sum;
  for (const CollectorTallies& t : tallies_) sum += t.total[m];
  return sum;
}

Tally Collection::lost_total(std::size_t m) const {
  Tally sum;
  for (const std::vector<Tally>& reason : lost_) sum += reason[m];
  return sum;
}

void Collection::collect(double t_end, double h, Particles& p) {
  crossings_.clear();
  losses_.clear();
  // Backwards: swap_remove moves the last particle, already visited, into i.
  for (std::size_t i = p.size(); i-- > 0;)
    if (leaves(p, i, t_end, h)) p.swap_remove(i);
  sort_by_time_and_id(crossings_);
  sort_by_time_and_id(losses_);
  tally_squares();
}

// In the records' (time, id) order, not the particles': sums of doubles
// depend on their order, and this one does not depend on the arrays'.
void Collection::tally_squares() {
  for (const Crossing& c : crossings_) {
    const double square = c.mass * c.mass;
    settled_squares_[std::size_t(c.material)] += square;
    if (c.product >= 0)
      tallies_[std::size_t(c.collector)]
          .product_squares[std::size_t(c.product) * materials_ + std::size_t(c.material)] += square;
  }
  for (const Loss& l : losses_) settled_squares_[std::size_t(l.material)] += l.mass * l.mass;
}

bool Collection::leaves(const Particles& p, std::size_t i, double t_end, double h) {
  if (!finite_state(p, i)) {
    lose(p, i, t_end, LossReason::NonFinite);
    return true;
  }
  if (try_collect(p, i, t_end, h)) return true;
  if (domain_ && !contains(*domain_, p.position[i])) {
    lose(p, i, t_end, LossReason::LeftDomain);
    return true;
  }
  return false;
}

// The step moved the centre along a straight segment (positions advance by
// h * v, the new velocity), so the crossing point and time are exact.
bool Collection::try_collect(const Particles& p, std::size_t i, double t_end, double h) {
  const Vec3 travel = h * p.velocity[i];
  const Vec3 x1 = p.position[i];
  const Vec3 x0 = x1 - travel;
  int hit = -1;
  double hit_fraction = 2.0;
  for (std::size_t k = 0; k < collectors_.size(); ++k) {
    const Collector& c = collectors_[k];
    const double d0 = c.normal.dot(x0 - c.point), d1 = c.normal.dot(x1 - c.point);
    if (!(d0 > 0.0 && d1 <= 0.0)) continue;
    const double fraction = d0 / (d0 - d1);
    if (fraction < hit_fraction) {
      hit = int(k);
      hit_fraction = fraction;
    }
  }
  if (hit < 0) return false;
  const Collector& c = collectors_[std::size_t(hit)];
  Crossing k;
  k.id = p.id[i];
  k.time = t_end - (1.0 - hit_fraction) * h;
  k.position = x0 + hit_fraction * travel;
  k.velocity = p.velocity[i];
  k.along = axes_[std::size_t(hit)].dot(k.position);
  k.diameter = particle_diameter(shape_size_, p, i);
  k.mass = p.mass[i];
  k.charge = particle_charge(p, i);
  k.material = p.material[i];
  k.collector = hit;
  k.bin = bin_of(c, k.along);
  k.product = product_of(c, k.along);
  tally_crossing(k);
  crossings_.push_back(k);
  return true;
}

void Collection::tally_crossing(const Crossing& c) {
  CollectorTallies& t = tallies_[std::size_t(c.collector)];
  const MassUnits m = to_mass_units(c.mass);
  const auto m_index = std::size_t(c.material);
  t.total[m_index].add(m);
  if (c.bin >= 0)
    t.bins[std::size_t(c.bin) * materials_ + m_index].add(m);
  else
    t.outside[m_index].add(m);
  if (c.product >= 0) t.products[std::size_t(c.product) * materials_ + m_index].add(m);
}

void Collection::lose(const Particles& p, std::size_t i, double t_end, LossReason reason) {
  Loss l;
  l.id = p.id[i];
  l.time = t_end;
  l.position = p.position[i];
  l.velocity = p.velocity[i];
  l.diameter = particle_diameter(shape_size_, p, i);
  l.mass = p.mass[i];
  l.material = p.material[i];
  l.reason = reason;
  lost_[std::size_t(reason)][std::size_t(l.material)].add(to_mass_units(l.mass));
  losses_.push_back(l);
}

void Collection::save(ByteWriter& out) const {
  for (const CollectorTallies& t : tallies_) {
    for (const auto* v : {&t.bins, &t.products, &t.outside, &t.total}) out.values(*v);
    out.values(t.product_squares);
  }
  for (const std::vector<Tally>& l : lost_) out.values(l);
  out.values(settled_squares_);
}

void Collection::load(ByteReader& in) {
  auto sized = [&](auto& v, const char* what) {
    const std::size_t expected = v.size();
    in.values(v);
    if (v.size() != expected) throw CorruptData(what);
  };
  for (CollectorTallies& t : tallies_) {
    for (auto* v : {&t.bins, &t.products, &t.outside, &t.total})
      sized(*v, "a collector's bins or products have changed");
    sized(t.product_squares, "a collector's products have changed");
  }
  for (std::vector<Tally>& l : lost_) in.values(l);
  sized(settled_squares_, "the materials have changed");
  crossings_.clear();
  losses_.clear();
}

}  // namespace ces::collect
