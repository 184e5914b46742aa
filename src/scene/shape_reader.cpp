#include "scene/shape_reader.hpp"

#include <cmath>
#include <stdexcept>

#include "feed/shapes.hpp"
#include "fields/electrostatics.hpp"
#include "scene/compile_support.hpp"
#include "scene/limits.hpp"
#include "scene/schema.hpp"

namespace ces::scene {

namespace fs = std::filesystem;

namespace {

// The extent of a cluster's spheres along its widest axis over its smallest
// radius; infinite where that is not a finite number.
double shape_span(const feed::SphereList& list) {
  Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
  double smallest = kInf;
  for (std::size_t k = 0; k < list.centers.size(); ++k) {
    lo = lo.cwiseMin(list.centers[k] - Vec3::Constant(list.radii[k]));
    hi = hi.cwiseMax(list.centers[k] + Vec3::Constant(list.radii[k]));
    smallest = std::min(smallest, list.radii[k]);
  }
  const double span = (hi - lo).maxCoeff() / smallest;
  return std::isfinite(span) ? span : kInf;
}

}  // namespace

ShapeReader::ShapeReader(const Node& root, fs::path scene_dir, Diagnostics& diags, Model& model,
                         std::vector<std::string>& shape_names)
    : root_(root),
      scene_dir_(std::move(scene_dir)),
      diags_(diags),
      model_(&model),
      shape_names_(shape_names) {}

// A flake or rod whose dimensions are drawn: its laws and the ladder of
// contact shapes the drawn aspects reach; nullopt: reported.
std::optional<DrawnShape> ShapeReader::drawn_shape(const Node& c) {
  const Node* shape = c.find("shape");
  const std::string name = shape ? shape->string() : "sphere";
  if (name != "flake" && name != "rod") {
    diags_.error(shape ? *shape : c.at("thickness"),
                 "a drawn thickness needs shape: flake or rod, expected one of them");
    return std::nullopt;
  }
  const bool flake = name == "flake";
  const char* extent_key = flake ? "width" : "length";
  for (const char* key : {"size", "aspect", flake ? "length" : "width"})
    if (const Node* extra = c.find(key)) {
      diags_.error(*extra, std::string("the ") + name +
                               "'s dimensions are drawn from thickness and " + extent_key +
                               ", expected no " + key);
      return std::nullopt;
    }
  const Node* extent = c.find(extent_key);
  if (!extent) {
    diags_.error(c, std::string("missing key '") + extent_key + "', expected the " + name +
                        "'s " + extent_key + " law with its thickness");
    return std::nullopt;
  }
  const auto t = size_distribution(c.at("thickness"), feed::Basis::number);
  const auto e = size_distribution(*extent, feed::Basis::number);
  if (!t || !e) return std::nullopt;
  DrawnShape d;
  d.kind = flake ? DrawnShape::Kind::Flake : DrawnShape::Kind::Rod;
  d.thickness = *t;
  d.extent = *e;
  d.ladder = ladder(name, t->quantile_by_number(0.0) / e->quantile_by_number(1.0),
                    t->quantile_by_number(1.0) / e->quantile_by_number(0.0));
  return d;
}

// The rungs of aspect a0 1.1^k (and 1) the drawn aspects [lo, hi] reach.
// The shapes of those not compiled yet are made side by side, each on a
// thread: integrating a cluster's mass properties (make_particle_shape) is
// most of a scene's load, and each rung's is its own.
std::vector<DrawnShape::Rung> ShapeReader::ladder(const std::string& name, double lo, double hi) {
  const double a0 = name == "flake" ? kFlakeMinAspect : kRodMinAspect;
  std::vector<double> aspects, reached, fresh;
  for (double a = a0; a < 1.0; a *= kLadderRatio) aspects.push_back(a);
  aspects.push_back(1.0);
  for (std::size_t k = 0; k < aspects.size(); ++k) {
    const bool below = k + 1 < aspects.size() && aspects[k + 1] <= lo;
    const bool above = k > 0 && aspects[k - 1] >= hi;
    if (below || above) continue;
    reached.push_back(aspects[k]);
    if (!shape_index_.contains(rung_key(name, aspects[k]))) fresh.push_back(aspects[k]);
  }
  std::vector<ParticleShape> made(fresh.size());
#pragma omp parallel for schedule(dynamic) if (fresh.size() > 1)
  for (std::size_t k = 0; k < fresh.size(); ++k) {
    const feed::SphereList spheres = builtin_spheres(name, fresh[k]);
    made[k] = make_particle_shape(spheres.centers, spheres.radii);
  }
  for (std::size_t k = 0; k < fresh.size(); ++k)
    shape_index_[rung_key(name, fresh[k])] = add_shape(made[k], nullptr, name).value();
  std::vector<DrawnShape::Rung> out;
  for (const double a : reached) out.push_back(rung(name, a));
  return out;
}

std::string ShapeReader::rung_key(const std::string& name, double aspect) {
  return name + "~" + format(aspect);
}

// A rung of the ladder, its shape compiled (ladder).
DrawnShape::Rung ShapeReader::rung(const std::string& name, double aspect) {
  const int index = *shape_index_.at(rung_key(name, aspect));
  const ParticleShape& shape = model_->shapes[std::size_t(index)];
  const double extent =
      name == "flake" ? std::sqrt(4.0 * fields::footprint_area(shape) / kPi) : 1.0;
  sizes_[std::size_t(index)] = extent;
  return {index, aspect, extent};
}

// The component's shape, compiled on first use: a shapes entry (which
// wins over a built-in of the same name), or the built-in sphere, flake
// or rod.
std::optional<int> ShapeReader::particle_shape(const Node& component) {
  const Node* ref = component.find("shape");
  const std::string name = ref ? ref->string() : "sphere";
  const Node* shapes = root_.find("shapes");
  const Node* entry = shapes ? shapes->find(name) : nullptr;
  if (!entry && !is_builtin_shape(name)) {
    report_unknown_shape(*ref, shapes);
    return std::nullopt;
  }
  const auto aspect = shape_aspect(component, name, entry != nullptr);
  if (!aspect) return std::nullopt;
  const std::string key = entry ? "shapes." + name : name + "@" + format(*aspect);
  if (const auto it = shape_index_.find(key); it != shape_index_.end()) return it->second;
  if (shape_index_.size() == limits::kParticleShapes) {
    diags_.error(ref ? *ref : component,
                 "a particle shape past the first " + std::to_string(limits::kParticleShapes) +
                     " (each shapes entry fed and each flake or rod aspect is one), expected "
                     "fewer");
    return shape_index_[key] = std::nullopt;
  }
  const auto spheres = entry ? cluster_spheres(*entry) : builtin_spheres(name, *aspect);
  std::optional<int> index;
  if (spheres)
    index = add_shape(make_particle_shape(spheres->centers, spheres->radii), entry, name);
  shape_index_[key] = index;
  return index;
}

bool ShapeReader::is_builtin_shape(const std::string& name) {
  return name == "sphere" || name == "flake" || name == "rod";
}

void ShapeReader::report_unknown_shape(const Node& ref, const Node* shapes) {
  NameTable known("shape");
  if (shapes)
    for (const Entry& e : shapes->entries) known.declare(e.key, e.key_mark, "", 0, diags_);
  known.resolve(ref, diags_, {"sphere", "flake", "rod"});
}

// The aspect of a built-in flake or rod (given, or the schema's default
// for the shape); 0 for shapes without one; nullopt: reported.
std::optional<double> ShapeReader::shape_aspect(const Node& component, const std::string& name,
                                                bool scene_entry) {
  const Node* aspect = component.find("aspect");
  const bool takes_aspect = !scene_entry && name != "sphere";
  if (aspect && !takes_aspect) {
    diags_.error(*aspect, "'" + name + "' has no aspect, expected aspect only with flake or rod");
    return std::nullopt;
  }
  if (!takes_aspect) return 0.0;
  if (aspect) return aspect->number();
  return schema()
      .at("definitions")
      .at("mix_component")
      .at("properties")
      .at("aspect")
      .at("x-default-by-shape")
      .at(name)
      .get<double>();
}

feed::SphereList ShapeReader::builtin_spheres(const std::string& name, double aspect) {
  if (name == "flake") return feed::flake_spheres(aspect);
  if (name == "rod") return feed::rod_spheres(aspect);
  return {{Vec3::Zero()}, {0.5}};
}

// Listed in the scene or read from a file: exactly one of the two.
std::optional<feed::SphereList> ShapeReader::cluster_spheres(const Node& entry) {
  const Node* spheres = entry.find("spheres");
  const Node* file = entry.find("file");
  if (!spheres == !file) {
    diags_.error(entry, spheres ? "both spheres and file given, expected one of them"
                                : "neither spheres nor file given, expected one of them");
    return std::nullopt;
  }
  feed::SphereList list;
  if (file) {
    const fs::path path = scene_dir_ / file->string();
    try {
      if (const std::string why = too_large(path, limits::kFileBytes); !why.empty())
        throw std::runtime_error(path.string() + ": " + why);
      list = feed::read_sphere_csv(path);
    } catch (const std::exception& e) {
      diags_.error(*file, std::string("cannot read the shape: ") + e.what());
      return std::nullopt;
    }
  } else {
    for (const Node& sphere : spheres->items) {
      list.centers.push_back(vec3(sphere));
      list.radii.push_back(sphere.items[3].number());
    }
  }
  const Node& where = file ? *file : *spheres;
  if (list.centers.size() > limits::kShapeSpheres) {
    diags_.error(where, "a shape of " + std::to_string(list.centers.size()) +
                            " spheres, expected at most " + std::to_string(limits::kShapeSpheres));
    return std::nullopt;
  }
  const double span = shape_span(list);
  if (span <= limits::kShapeSpan) return list;
  diags_.error(where, "a shape " + format(span) +
                          " times its smallest sphere's radius across, expected at most " +
                          format(limits::kShapeSpan) + " times");
  return std::nullopt;
}

// Size at scale 1: a scene entry's `size` or its bounding diameter; for
// the built-in flake and rod the diameter of the sphere of equal volume,
// so that a size law gives the same masses whatever the built-in shape
// (the unit sphere's is exactly 1).
std::optional<int> ShapeReader::add_shape(const ParticleShape& shape, const Node* entry,
                                          const std::string& name) {
  const Node* size = entry ? entry->find("size") : nullptr;
  const double ratio = size ? size->number() / (2.0 * shape.bounding_radius) : 1.0;
  if (!(ratio <= limits::kShapeScale && ratio >= 1.0 / limits::kShapeScale)) {
    diags_.error(*size, "size " + format(size->number()) + " is " + format(ratio) +
                            " times the spheres' bounding diameter, expected within a factor " +
                            format(limits::kShapeScale) + " of it");
    return std::nullopt;
  }
  if (size)
    sizes_.push_back(size->number());
  else if (entry)
    sizes_.push_back(2.0 * shape.bounding_radius);
  else
    sizes_.push_back(name == "sphere" ? 1.0 : equal_volume_diameter(shape.volume));
  model_->shapes.push_back(shape);
  shape_names_.push_back(name);
  return int(model_->shapes.size()) - 1;
}

std::optional<feed::SizeDistribution> ShapeReader::size_distribution(const Node& size,
                                                                    feed::Basis basis) {
  const Entry& law = size.entries.front();  // the schema allows exactly one
  const Node& s = law.value;
  try {
    if (law.key == "constant") return feed::SizeDistribution::constant(s.number());
    if (law.key == "sieve") return sieve(s, basis);
    const double min = s.find("min") ? s.at("min").number() : 0.0;
    const double max = s.find("max") ? s.at("max").number() : kInf;
    if (!(min < max)) {
      diags_.error(s.at("max"), "max " + metres(max) + " is not above min " + metres(min) +
                                    ", expected max > min");
      return std::nullopt;
    }
    if (law.key == "uniform") return feed::SizeDistribution::uniform(min, max, basis);
    if (law.key == "normal")
      return feed::SizeDistribution::normal(s.at("mean").number(), s.at("sd").number(), min, max,
                                            basis);
    return feed::SizeDistribution::lognormal(s.at("median").number(), s.at("sigma").number(), min,
                                             max, basis);
  } catch (const std::invalid_argument& e) {
    diags_.error(size, std::string(e.what()) + ", expected a size law with particles in it");
    return std::nullopt;
  }
}

std::optional<feed::SizeDistribution> ShapeReader::sieve(const Node& rows, feed::Basis basis) {
  std::vector<feed::SizeDistribution::SievePoint> table;
  for (const Node& row : rows.items) {
    const feed::SizeDistribution::SievePoint p{row.items[0].number(), row.items[1].number()};
    if (!table.empty() && !(p.size > table.back().size))
      return sieve_error(row, "sizes must increase from row to row");
    if (!table.empty() && p.passing < table.back().passing)
      return sieve_error(row, "the fraction passing must not decrease");
    table.push_back(p);
  }
  if (table.front().passing != 0.0)
    return sieve_error(rows.items.front(), "the first row must pass 0");
  if (table.back().passing != 1.0)
    return sieve_error(rows.items.back(), "the last row must pass 1");
  return feed::SizeDistribution::sieve(table, basis);
}

std::nullopt_t ShapeReader::sieve_error(const Node& row, const std::string& what) {
  diags_.error(row, "invalid sieve row: " + what +
                        ", expected [size, fraction passing] rows with sizes rising "
                        "and fractions rising from 0 to 1");
  return std::nullopt;
}

}  // namespace ces::scene
