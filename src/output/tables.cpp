#include "output/tables.hpp"

#include <algorithm>

#include "output/format.hpp"

namespace ces::output {
namespace {

const std::string& material_name(const Simulation& sim, int m) {
  return sim.model->materials.materials()[std::size_t(m)].name;
}

// Mass of material m whose fate is known: collected anywhere, or lost.
MassUnits settled_mass(const Collection& c, int m) {
  return c.collected_total(std::size_t(m)).mass + c.lost_total(std::size_t(m)).mass;
}

ProductResult product_result(const Collection& c, int collector, int product,
                             const std::vector<int>& materials) {
  const CollectorTallies& t = c.collectors()[std::size_t(collector)];
  const std::size_t base = std::size_t(product) * c.material_count();
  ProductResult r;
  r.collector = collector;
  r.product = product;
  MassUnits total = 0, main = 0;
  for (const int m : materials) {
    const Tally& cell = t.products[base + std::size_t(m)];
    total += cell.mass;
    if (cell.mass > main) {  // ties keep the first (lower index) material
      main = cell.mass;
      r.main_material = m;
    }
  }
  r.total_kg = to_kg(total);
  for (const int m : materials) {
    const Tally& cell = t.products[base + std::size_t(m)];
    ProductShare& s = r.shares.emplace_back();
    s.count = cell.count;
    s.kg = cell.kg();
    if (cell.mass == 0) continue;
    s.grade = double(cell.mass) / double(total);
    s.recovery = double(cell.mass) / double(settled_mass(c, m));
    if (m == r.main_material) {
      r.grade = s.grade;
      r.recovery = s.recovery;
    }
  }
  return r;
}

void append_xyz(CsvWriter& row, const Vec3& v) { row << v.x() << v.y() << v.z(); }

}  // namespace

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
          << s.kg << s.grade << s.recovery;
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
