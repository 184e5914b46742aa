#include "dynamics/sleep.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>

#include "common/parallel.hpp"

namespace ces {
namespace {

// Of the friction a sleeper's forces may take, the share that keeps it
// asleep: the rest is the reserve that wakes it before it could slip.
constexpr double kReserve = 0.5;
// The pushes' fixed point: an impulse unit far below any particle's weight
// over a step (a 0.1 mm grain's is 1e-11 N s at 0.1 ms), and a cap per
// contact and component far above any blow (1 mg at 100 m/s), at which 90
// contacts still sum within the 64 bits.
constexpr double kPushUnit = 1e-21;
constexpr double kPushCap = 1e-4;
constexpr std::int32_t kNone = -1, kSeveral = -2;

void wake(Particles& p, std::size_t i) {
  p.carrier[i] = Particles::kAwake;
  p.at_rest[i] = 0.0;
}

// The body pressing a particle: the first one found, or kSeveral. The
// same in any order of the writes.
void mark_support(std::int32_t& slot, std::int32_t body) {
  std::atomic_ref<std::int32_t> ref(slot);
  std::int32_t seen = ref.load(std::memory_order_relaxed);
  while (seen != body && seen != kSeveral) {
    const std::int32_t want = seen == kNone ? body : kSeveral;
    if (ref.compare_exchange_weak(seen, want, std::memory_order_relaxed)) return;
  }
}

// Adds the impulse J to a particle's pushes, component by component.
void add_push(std::array<std::int64_t, 3>& slot, const Vec3& J) {
  for (int c = 0; c < 3; ++c)
    slot[std::size_t(c)] += std::int64_t(std::clamp(J[c], -kPushCap, kPushCap) / kPushUnit);
}

// Whether particle i moves with body k's surface, within the speed.
bool at_rest(const Model& model, const Bodies& bodies, const Particles& p, std::size_t i,
             std::size_t k) {
  const Vec3 slip = p.velocity[i] - bodies.velocity_at(k, p.position[i]);
  const Vec3 spin = p.angular_velocity[i] - bodies.angular_velocity[k];
  return slip.norm() + spin.norm() * bounding_radius(model, p, i) <= model.sleep.speed;
}

// Where particle i rests on body k: the outward normal at the surface
// nearest its centre, the centre's distance from it, and the spheres that
// bear on it: those whose gaps, in their radii, are within kSupportGap of
// the lowest.
struct Support {
  Vec3 normal = Vec3::Zero();
  double height = 0.0;
  std::vector<Vec3> arms;  // from the centre to each bearing sphere's centre
};

constexpr double kSupportGap = 0.1;

// The body's surface nearest x within `reach`, in the world frame: false
// if there is none.
bool nearest_surface(const RigidBody& body, const Pose& pose, const Vec3& x, double reach,
                     Vec3& normal, double& distance) {
  static thread_local std::vector<geo::SurfaceHit> hits;
  hits.clear();
  geo::query(body.shape, pose.inverse_apply(x), reach, hits);
  if (hits.empty()) return false;
  const auto nearest = std::min_element(hits.begin(), hits.end(), [](const auto& u, const auto& v) {
    return u.distance < v.distance;
  });
  normal = pose.orientation * nearest->normal;
  distance = nearest->distance;
  return true;
}

bool find_support(const Model& model, const Bodies& bodies, const Particles& p, std::size_t i,
                  std::size_t k, Support& out) {
  const RigidBody& body = model.bodies[k];
  const Pose& pose = bodies.pose[k];
  const double bounding = bounding_radius(model, p, i);
  if (!nearest_surface(body, pose, p.position[i], 2.0 * bounding, out.normal, out.height))
    return false;
  const ParticleShape& shape = model.shapes[std::size_t(p.shape[i])];
  const Mat3 R = p.orientation[i].toRotationMatrix() * p.scale[i];
  static thread_local std::vector<double> gaps;
  gaps.assign(shape.centers.size(), std::numeric_limits<double>::infinity());
  double lowest = std::numeric_limits<double>::infinity();
  for (std::size_t s = 0; s < shape.centers.size(); ++s) {
    const double r = shape.radii[s] * p.scale[i];
    Vec3 n;
    double d = 0.0;
    if (!nearest_surface(body, pose, p.position[i] + R * shape.centers[s], 2.0 * r, n, d)) continue;
    gaps[s] = (d - r) / r;
    lowest = std::min(lowest, gaps[s]);
  }
  out.arms.clear();
  for (std::size_t s = 0; s < shape.centers.size(); ++s)
    if (gaps[s] <= lowest + kSupportGap) out.arms.push_back(R * shape.centers[s]);
  return !out.arms.empty();
}

// How far along t the normal force can shift its centre from under the
// centre of mass: to the farthest bearing sphere that way.
double reach_along(const Support& s, const Vec3& t) {
  double most = 0.0;
  for (const Vec3& arm : s.arms) most = std::max(most, arm.dot(t));
  return most;
}

}  // namespace

void Sleep::wake_near_bodies(const Model& model, const Bodies& bodies, Particles& p) {
  const std::size_t nb = model.bodies.size();
  if (bounds_.size() != nb) {  // the model's bodies are fixed: once per run
    bounds_.resize(nb);
    for (std::size_t b = 0; b < nb; ++b) bounds_[b] = geo::local_bounds(model.bodies[b].shape);
  }
  const auto n = std::ptrdiff_t(p.size());
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (std::ptrdiff_t s = 0; s < n; ++s) {
    const auto i = std::size_t(s);
    if (!p.asleep(i)) continue;
    const auto carrier = std::size_t(p.carrier[i]);
    if (!turns_in_place(model, bodies, carrier)) {
      wake(p, i);
      continue;
    }
    static thread_local std::vector<geo::SurfaceHit> hits;
    const Vec3& x = p.position[i];
    const double ride = bodies.velocity_at(carrier, x).norm();
    for (std::size_t b = 0; b < nb; ++b) {
      if (b == carrier) continue;
      // Near enough that the awake particle's envelope, one step's travel
      // past its spheres, would list the body's contacts next step.
      const double reach = 2.0 * bounding_radius(model, p, i) +
                           (ride + bodies.velocity_at(b, x).norm()) * model.step;
      const Vec3 local = bodies.pose[b].inverse_apply(x);
      if (!bounds_[b].inflated(reach).overlaps({local, local})) continue;
      hits.clear();
      geo::query(model.bodies[b].shape, local, reach, hits);
      if (hits.empty()) continue;
      wake(p, i);
      break;
    }
  }
}

void Sleep::carry(const std::vector<Pose>& before, const Bodies& bodies, Particles& p) {
  const auto n = std::ptrdiff_t(p.size());
#pragma omp parallel for schedule(static) if (n > kParallelMin)
  for (std::ptrdiff_t s = 0; s < n; ++s) {
    const auto i = std::size_t(s);
    if (!p.asleep(i)) continue;
    const auto k = std::size_t(p.carrier[i]);
    const Pose& from = before[k];
    const Pose& to = bodies.pose[k];
    p.position[i] = to.apply(from.inverse_apply(p.position[i]));
    p.orientation[i] =
        (to.orientation * from.orientation.conjugate() * p.orientation[i]).normalized();
    p.velocity[i] = bodies.velocity_at(k, p.position[i]);
    p.angular_velocity[i] = bodies.angular_velocity[k];
  }
}

void Sleep::read_contacts(const Contacts& c, const std::vector<Vec3>& impulses,
                          std::size_t np) {
  pressed_by_.assign(np, kNone);
  const auto nc = std::ptrdiff_t(c.size());
  const int threads = nc > kParallelMin ? omp_get_max_threads() : 1;
  // Each thread adds into pushes of its own, the first into push_, and
  // the others' are added to it after: integers, so the sums are the same
  // whatever the threads, without an atomic add per contact.
  push_.assign(np, {0, 0, 0});
  more_push_.resize(std::size_t(threads - 1));
  for (auto& part : more_push_) part.assign(np, {0, 0, 0});
#pragma omp parallel num_threads(threads)
  {
    const auto t = std::size_t(omp_get_thread_num());
    std::vector<std::array<std::int64_t, 3>>& push = t == 0 ? push_ : more_push_[t - 1];
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < nc; ++s) {
      const auto k = std::size_t(s);
      const auto a = std::size_t(c.body_a[k]), b = std::size_t(c.body_b[k]);
      const Vec3& impulse = impulses[k];
      if (a >= np) {  // a body's contact names the body first
        if (impulse.dot(c.normal[k]) > 0.0) mark_support(pressed_by_[b], std::int32_t(a - np));
        continue;
      }
      add_push(push[a], -impulse);
      add_push(push[b], impulse);
    }
  }
  if (more_push_.empty()) return;
#pragma omp parallel for schedule(static)
  for (std::size_t i = 0; i < np; ++i)
    for (const auto& part : more_push_)
      for (std::size_t d = 0; d < 3; ++d) push_[i][d] += part[i][d];
}

// Whether the force body k must give particle i to carry it on its circle,
// R = m (a - g) - F - P (P: its neighbours' pushes this step), presses it
// on the surface with the tangential part T within kReserve of friction,
// and whether the normal force can balance T's torque about the centre (T
// times the centre's height) within kReserve of the most it can: N times
// the reach of the bearing spheres along T. A sphere has no reach: it rolls.
bool Sleep::held(const Model& model, const Bodies& bodies, const Particles& p, std::size_t i,
                 std::size_t k) const {
  static thread_local Support support;
  if (!find_support(model, bodies, p, i, k, support)) return false;
  const Vec3& n = support.normal;
  const Vec3& w = bodies.angular_velocity[k];
  const Vec3 centripetal = w.cross(w.cross(p.position[i] - bodies.pose[k].position));
  const auto& units = push_[i];
  const Vec3 push = Vec3(double(units[0]), double(units[1]), double(units[2])) * kPushUnit;
  const Vec3 force = p.mass[i] * (centripetal - model.gravity) - p.force[i] - push / model.step;
  const double normal = force.dot(n);
  const Vec3 along = force - normal * n;
  const double tangent = along.norm();
  if (!(normal > 0.0)) return false;
  const auto& materials = model.materials;
  const double friction =
      materials.surfaces(materials.pair_index(model.bodies[k].material, p.material[i])).friction;
  if (tangent > kReserve * friction * normal) return false;
  if (tangent == 0.0) return true;
  return tangent * support.height <= kReserve * normal * reach_along(support, along / tangent);
}

std::size_t Sleep::update(const Model& model, const Bodies& bodies, const Contacts& contacts,
                          const std::vector<Vec3>& impulses, Particles& p) {
  read_contacts(contacts, impulses, p.size());
  // In fixed chunks, balanced between the threads (the sleepers, whose
  // support is looked for every step, lie together).
  return reduce_chunks<std::size_t>(p.size(),
                                    [&](std::size_t begin, std::size_t end, std::size_t& asleep) {
                                      for (std::size_t i = begin; i < end; ++i)
                                        asleep += update_one(model, bodies, p, i) ? 1 : 0;
                                    });
}

bool Sleep::update_one(const Model& model, const Bodies& bodies, Particles& p,
                       std::size_t i) const {
  if (p.asleep(i)) {
    if (held(model, bodies, p, i, std::size_t(p.carrier[i]))) return true;
    wake(p, i);
    return false;
  }
  const std::int32_t k = pressed_by_[i];
  if (k < 0 || !turns_in_place(model, bodies, std::size_t(k)) ||
      !at_rest(model, bodies, p, i, std::size_t(k)) || !held(model, bodies, p, i, std::size_t(k))) {
    p.at_rest[i] = 0.0;
    return false;
  }
  p.at_rest[i] += model.step;
  if (p.at_rest[i] < model.sleep.time) return false;
  p.carrier[i] = k;
  return true;
}

}  // namespace ces
