#include "output/tables.hpp"

#include <algorithm>
#include <cmath>

#include "output/format.hpp"

namespace ces::output {
namespace {

const std::string& material_name(const Simulation& sim, int m) {
  return sim.model->materials.materials()[std::size_t(m)].name;
}

// Material m whose fate is known: collected anywhere, or lost.
Tally settled(const Collection& c, int m) {
  return c.collected_total(std::size_t(m)) + c.lost_total(std::size_t(m));
}

// Material m's share of a product whose reported materials sum to
// `product` (squares: their squared masses), from its cell.
ProductShare share(const Collection& c, int m, const Tally& cell, double cell_squares,
                   const Tally& product, double squares) {
  ProductShare s;
  s.material = m;
  s.count = cell.count;
  s.kg = cell.kg();
  if (cell.mass == 0) return s;
  const Tally known = settled(c, m);
  s.grade = double(cell.mass) / double(product.mass);
  s.recovery = double(cell.mass) / double(known.mass);
  s.grade_se = ratio_standard_error(s.kg, product.kg(), cell_squares, squares, product.count);
  s.recovery_se = ratio_standard_error(s.kg, known.kg(), cell_squares,
                                       c.settled_squares(std::size_t(m)), known.count);
  return s;
}

ProductResult product_result(const Collection& c, int collector, int product,
                             const std::vector<int>& materials) {
  const CollectorTallies& t = c.collectors()[std::size_t(collector)];
  const std::size_t base = std::size_t(product) * c.material_count();
  ProductResult r;
  r.collector = collector;
  r.product = product;
  Tally total;
  MassUnits main = 0;
  double squares = 0.0;
  for (std::size_t i = 0; i < materials.size(); ++i) {
    const std::size_t at = base + std::size_t(materials[i]);
    const Tally& cell = t.products[at];
    total += cell;
    squares += t.product_squares[at];
    if (cell.mass > main) {  // ties keep the first (lower index) material
      main = cell.mass;
      r.main_share = int(i);
    }
  }
  r.total_kg = total.kg();
  for (const int m : materials) {
    const std::size_t at = base + std::size_t(m);
    r.shares.push_back(share(c, m, t.products[at], t.product_squares[at], total, squares));
  }
  return r;
}

void append_xyz(CsvWriter& row, const Vec3& v) { row << v.x() << v.y() << v.z(); }

}  // namespace

double ratio_standard_error(double part, double whole, double q_part, double q_whole,
                            std::uint64_t n) {
  if (n < 2 || !(whole > 0.0)) return 0.0;
  const double r = part / whole;
  const double residuals = (1.0 - r) * (1.0 - r) * q_part + r * r * (q_whole - q_part);
  return std::sqrt(std::max(0.0, residuals) * double(n) / double(n - 1)) / whole;
}

std::vector<int> fed_materials(const Simulation& sim) {
  std::vector<int> m;
  for (const Feed& f : sim.feeds)
    for (const FeedComponent& c : f.mix) m.push_back(c.material);
  std::sort(m.begin(), m.end());
  m.erase(std::unique(m.begin(), m.end()), m.end());
  return m;
}

std::vector<ProductResult> product_results(const Simulation& sim, const Collection& c,
                                           const std::vector<int>& materials) {
  std::vector<ProductResult> out;
  for (std::size_t k = 0; k < sim.collectors.size(); ++k)
    for (std::size_t p = 0; p < sim.collectors[k].products.size(); ++p)
      out.push_back(product_result(c, int(k), int(p), materials));
  return out;
}

std::string bins_csv(const Simulation& sim, const Collection& c,
                     const std::vector<int>& materials) {
  std::string text = std::string(kBinsHeader) + '\n';
  CsvWriter row(text);
  for (std::size_t k = 0; k < sim.collectors.size(); ++k) {
    const Collector& col = sim.collectors[k];
    const CollectorTallies& t = c.collectors()[k];
    const double width = (col.to - col.from) / col.bins;
    for (int b = 0; b < col.bins; ++b) {
      const double from = col.from + b * width;
      const double to = b + 1 == col.bins ? col.to : col.from + (b + 1) * width;
      for (const int m : materials) {
        const Tally& cell = t.bins[std::size_t(b) * c.material_count() + std::size_t(m)];
        row << col.name << b << from << to << material_name(sim, m) << cell.count << cell.kg();
        row.end_row();
      }
    }
  }
  return text;
}

std::string products_csv(const Simulation& sim, const std::vector<ProductResult>& products,
                         const std::vector<int>& materials) {
  std::string text = std::string(kProductsHeader) + '\n';
  CsvWriter row(text);
  for (const ProductResult& r : products) {
    const Collector& col = sim.collectors[std::size_t(r.collector)];
    const Product& p = col.products[std::size_t(r.product)];
    for (std::size_t m = 0; m < materials.size(); ++m) {
      const ProductShare& s = r.shares[m];
      row << col.name << p.name << p.from << p.to << material_name(sim, materials[m]) << s.count
          << s.kg << s.grade << s.recovery << s.grade_se << s.recovery_se;
      row.end_row();
    }
  }
  return text;
}

std::string crossing_rows(const Simulation& sim, const Collection& c) {
  std::string text;
  CsvWriter row(text);
  for (const Crossing& k : c.crossings()) {
    const Collector& col = sim.collectors[std::size_t(k.collector)];
    row << k.id << k.time;
    append_xyz(row, k.position);
    append_xyz(row, k.velocity);
    row << k.along << k.diameter << k.mass << material_name(sim, k.material) << k.charge << col.name
        << k.bin << (k.product < 0 ? std::string() : col.products[std::size_t(k.product)].name);
    row.end_row();
  }
  return text;
}

std::string lost_rows(const Simulation& sim, const Collection& c) {
  std::string text;
  CsvWriter row(text);
  for (const Loss& l : c.losses()) {
    row << l.id << l.time;
    append_xyz(row, l.position);
    append_xyz(row, l.velocity);
    row << l.diameter << l.mass << material_name(sim, l.material) << to_string(l.reason);
    row.end_row();
  }
  return text;
}

}  // namespace ces::output
