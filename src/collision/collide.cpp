#include "collision/collide.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <utility>

#include "common/hull.hpp"
#include "common/parallel.hpp"

namespace ces {
namespace {

constexpr std::size_t kContactChunk = 128;  // fixed, so contact order never depends on threads

// What gravity and the forces change particle i's velocity by within the
// step (the forces are this step's after the collision: the last step's
// stand in for them, still in p.force).
Vec3 forced_change(const Model& model, const Particles& p, std::size_t i) {
  return model.step * (model.gravity + p.inv_mass[i] * p.force[i]);
}

// The largest impulse one contact can pass in a step between sides of
// reduced mass m_red closing at v_close: the normal one is at most
// (1 + e) m_red v_close, and friction, inside its cone, adds at most mu
// times that across the normal.
double largest_blow(const SurfacePair& s, double m_red, double v_close) {
  return (1.0 + s.restitution) * std::sqrt(1.0 + s.friction * s.friction) * m_red * v_close;
}

// A deterministic normal for coincident centres (degenerate spawns).
Vec3 safe_direction(const Vec3& d, double len) {
  return len > 0.0 ? Vec3(d / len) : Vec3::UnitY();
}

// A candidate contact of two spheres closer than the envelope. Most sphere
// pairs of two flakes are far apart: they are passed over on the squared
// distance, with a margin far above its rounding, before the square root
// decides the rest.
void sphere_sphere(const Vec3& ca, double ra, const Vec3& cb, double rb, double envelope,
                   const ContactKey& key, std::vector<Candidate>& out) {
  const Vec3 d = cb - ca;
  const double squared = d.squaredNorm(), reach = ra + rb + envelope;
  if (squared > reach * reach * (1.0 + 1e-9)) return;
  const double len = std::sqrt(squared);
  const double gap = len - ra - rb;
  if (gap >= envelope) return;
  const Vec3 n = safe_direction(d, len);
  out.push_back({n, ca + n * (ra + 0.5 * gap), gap, std::min(ra, rb), key});
}

// A flake's plate frame in the world, its shape turned by `turn` and
// scaled about its centre at `position`.
PlateFrame plate_frame(const FlatFace& face, const Mat3& turn, const Vec3& position,
                       double scale) {
  return {turn * face.normal, turn * face.x_axis, turn * face.y_axis,
          position + scale * (turn * face.origin)};
}

// A plate's hull edges in the world: made once per pair, and read by each
// of its rim queries and each pair of the two rims' edges.
struct RimEdges {
  std::vector<Vec3> start, edge;
  std::vector<double> squared;  // the edge's squared length

  void make(const FlatFace& face, const Vec3* centres) {
    const std::vector<std::uint32_t>& k = face.corners;
    start.resize(k.size());
    edge.resize(k.size());
    squared.resize(k.size());
    for (std::size_t e = 0; e < k.size(); ++e) {
      start[e] = centres[k[e]];
      edge[e] = centres[k[next_corner(e, k.size())]] - start[e];
      squared[e] = edge[e].squaredNorm();
    }
  }
  std::size_t size() const { return start.size(); }
};

// A flake's plate this step (FlatFace): its frame (PlateFrame) and its rim
// in the world (`edges`, filled from its spheres' centres). Inactive for a
// shape that is not flat, or where the scene keeps sphere on sphere.
struct Plate : PlateFrame {
  const FlatFace* face = nullptr;
  const RimEdges* rim = nullptr;
  Vec3 position;
  double scale = 1.0, radius = 0.0, reach = 0.0;

  Plate() = default;
  Plate(const ParticleShape& s, const PlateFrame& frame, const Vec3& position, double scale,
        const Vec3* centres, RimEdges& edges) {
    if (!s.face.flat()) return;
    PlateFrame::operator=(frame);
    face = &s.face;
    edges.make(s.face, centres);
    rim = &edges;
    this->position = position;
    this->scale = scale;
    radius = scale * s.radii[0];
    reach = scale * s.bounding_radius;
  }
  bool active() const { return face != nullptr; }
  // Whether a point d from the origin is over the face (its projection in
  // the hull).
  bool over(const Vec3& d) const {
    return face->covers(d.dot(x_axis) / scale, d.dot(y_axis) / scale);
  }
  // The point of the hull's edges nearest c (the first of equals).
  Vec3 nearest_on_rim(const Vec3& c) const {
    Vec3 best = rim->start[0];
    double least = std::numeric_limits<double>::infinity();
    for (std::size_t e = 0; e < rim->size(); ++e) {
      const Vec3& a = rim->start[e];
      const Vec3& edge = rim->edge[e];
      // Clamped to the edge before dividing: c is beside most edges' ends.
      const double along = (c - a).dot(edge), squared_edge = rim->squared[e];
      const double t = along <= 0.0            ? 0.0
                       : along >= squared_edge ? 1.0
                                               : along / squared_edge;
      const Vec3 q = a + t * edge;
      const double squared = (c - q).squaredNorm();
      if (squared < least) {
        least = squared;
        best = q;
      }
    }
    return best;
  }
};

// A candidate contact of a sphere (c, r) with a plate, its point nearest c
// being q: over the face, q is c's foot on the mid-plane; beside it, on
// the rim. The sphere is the pair's A side or its B side; the normal
// points from A to B.
void sphere_plate(const Vec3& c, double r, const Vec3& q, const Vec3& up_hint, const Plate& plate,
                  bool sphere_is_a, double envelope, const ContactKey& key,
                  std::vector<Candidate>& out) {
  const Vec3 d = c - q;
  const double len = d.norm(), gap = len - r - plate.radius;
  if (gap >= envelope) return;
  const Vec3 up = len > 0.0 ? Vec3(d / len) : up_hint;  // from the plate to c
  const Vec3 n = sphere_is_a ? Vec3(-up) : up;
  out.push_back({n, c - up * (r + 0.5 * gap), gap, std::min(r, plate.radius), key});
}

// The candidate contacts of one particle's spheres with another's plate.
// A sphere over the face meets the face; one beside it meets the rim,
// unless the particle is itself a plate and the sphere is not one of its
// hull's corners: between two plates' rims the nearest points are at a
// corner of one of them. `a_side`: the spheres are the pair's A side.
void spheres_on_plate(const Vec3* centres, const ParticleShape& s, double scale,
                      const Plate& plate, bool corners_only, bool a_side, ContactKey key,
                      double envelope, std::vector<Candidate>& out) {
  std::uint32_t& own = a_side ? key.feature_a : key.feature_b;
  std::uint32_t& other = a_side ? key.feature_b : key.feature_a;
  // The plate's face and rim lie in its mid-plane (to a billionth of its
  // size, FlatFace): a sphere farther from the plane than it can reach
  // meets neither, and is passed over before the hull is searched. The
  // margin is far above both.
  const double slack = 1e-6 * plate.reach;
  for (std::size_t k = 0; k < s.centers.size(); ++k) {
    const Vec3& c = centres[k];
    const double r = scale * s.radii[k], far = plate.reach + r + envelope;
    if ((c - plate.position).squaredNorm() > far * far) continue;
    const Vec3 d = c - plate.origin;
    const double height = d.dot(plate.normal);
    if (std::abs(height) > r + plate.radius + envelope + slack) continue;
    own = std::uint32_t(k);
    if (plate.over(d)) {
      other = kPlateFeature;
      const Vec3 up = height < 0.0 ? Vec3(-plate.normal) : plate.normal;
      sphere_plate(c, r, c - height * plate.normal, up, plate, a_side, envelope, key, out);
    } else if (!corners_only || s.face.at_corner[k] != 0) {
      other = kRimFeature;
      sphere_plate(c, r, plate.nearest_on_rim(c), plate.normal, plate, a_side, envelope, key, out);
    }
  }
}

// Two plates' rims where they cross (two flakes edge on edge): the rows
// between edges of each whose nearest points are inside both. Elsewhere
// the nearest points of two rims are at a corner of one (spheres_on_plate),
// and so are those of parallel edges.
void rims_crossing(const Plate& a, const Plate& b, ContactKey key, double envelope,
                   std::vector<Candidate>& out) {
  const RimEdges &ea = *a.rim, &eb = *b.rim;
  const double far = a.reach + b.reach + envelope;
  if ((a.position - b.position).squaredNorm() > far * far) return;
  for (std::size_t i = 0; i < ea.size(); ++i) {
    const Vec3& p = ea.start[i];
    const Vec3& d1 = ea.edge[i];
    for (std::size_t j = 0; j < eb.size(); ++j) {
      const Vec3& q = eb.start[j];
      const Vec3& d2 = eb.edge[j];
      // The lines' nearest points (Ericson, Real-Time Collision Detection,
      // 5.1.9), kept only where both are inside their edges.
      const Vec3 r = p - q;
      const double aa = ea.squared[i], e = eb.squared[j], bb = d1.dot(d2);
      const double denom = aa * e - bb * bb;
      if (!(denom > 1e-6 * aa * e)) continue;  // parallel, or nearly
      // s and t are in (0, 1) only where their numerators are in (0,
      // denom): most pairs of edges are passed over before dividing.
      const double s_num = bb * d2.dot(r) - e * d1.dot(r);
      const double t_num = aa * d2.dot(r) - bb * d1.dot(r);
      if (!(s_num > 0.0 && s_num < denom && t_num > 0.0 && t_num < denom)) continue;
      const double s = s_num / denom, t = t_num / denom;
      if (!(s > 0.0 && s < 1.0 && t > 0.0 && t < 1.0)) continue;
      const Vec3 c1 = p + s * d1, c2 = q + t * d2, d = c2 - c1;
      const double len = d.norm(), gap = len - a.radius - b.radius;
      if (gap >= envelope) continue;
      const Vec3 n = len > 0.0 ? Vec3(d / len) : a.normal;
      key.feature_a = kEdgeFeature | std::uint32_t(i);
      key.feature_b = kEdgeFeature | std::uint32_t(j);
      out.push_back({n, c1 + n * (a.radius + 0.5 * gap), gap, std::min(a.radius, b.radius), key});
    }
  }
}

// The envelope of a particle at rest: a fraction of its smallest sphere's
// radius.
double resting_envelope(const Model& model, const Particles& p, std::size_t i) {
  const ParticleShape& s = model.shapes[std::size_t(p.shape[i])];
  return model.contact.envelope_fraction * s.smallest_radius() * p.scale[i];
}

// The cull, point by point, that PairMotion::search_envelope bounds for the
// whole pair: out go the candidates farther than the pair's resting
// envelopes plus what it can close there this step (motion.reach), the
// envelope of the relative travel, which a pile at rest has already.
void drop_unreachable(const PairMotion& motion, double resting, std::vector<Candidate>& c) {
  std::erase_if(c, [&](const Candidate& k) { return k.gap > resting + motion.reach(k.point); });
}

// How far any point of a body moves in a step, for the culls: it turns
// about its frame's origin, reaching at most the farthest corner of its
// bounds. (A plane's are infinite: only a turning body adds the term.)
double travel_in_step(const geo::Aabb& bounds, const Vec3& v, const Vec3& w, double h) {
  const double w_norm = w.norm();
  const double swing =
      w_norm > 0.0 ? w_norm * bounds.min.cwiseAbs().cwiseMax(bounds.max.cwiseAbs()).norm() : 0.0;
  return (v.norm() + swing) * h;
}

// target = max(target, value), atomically: threads may raise one target.
void raise_to(double& target, double value) {
  std::atomic_ref<double> ref(target);
  double seen = ref.load(std::memory_order_relaxed);
  while (value > seen && !ref.compare_exchange_weak(seen, value, std::memory_order_relaxed)) {
  }
}

template <class Fill>
void run_chunked(std::size_t n, std::vector<OwnLine<Contacts>>& chunks, Contacts& out,
                 std::size_t& used, Fill fill) {
  const std::size_t count = chunk_count(n, kContactChunk);
  // Never shrink: the buffers keep their capacity from step to step.
  if (chunks.size() < count) chunks.resize(count);
  // Chunks by for_each_chunk: the particles are ordered in space, so those
  // near a body (19 queries a flake) or in a pile come in runs, and with
  // static halves the less busy thread would idle through most of the
  // body-contact loops; here it takes over the rest of the busier share.
  // Handed out as threads free up (dynamic), the chunks' buffers would move
  // between the cores every step, which costs the pair loop what the second
  // thread gains. Each chunk fills its own list: the same contacts.
  for_each_range(n, kContactChunk, true, [&](std::size_t ch, std::size_t begin, std::size_t end) {
    chunks[ch].clear();
    fill(begin, end, chunks[ch]);
  });
  // Copied into place in parallel at `used`: on one thread it would be the
  // largest serial part of the stage. `out` keeps the last step's length
  // until the stage ends (Collider::narrowphase), so it is
  // zero-filled only where this step has more contacts, not rewritten.
  // (Named through a reference: in the parallel loop the thread_local
  // itself would be each worker's own.)
  static thread_local std::vector<std::size_t> offsets;
  std::vector<std::size_t>& at = offsets;
  at.resize(count + 1);
  at[0] = used;
  for (std::size_t ch = 0; ch < count; ++ch) at[ch + 1] = at[ch] + chunks[ch].size();
  if (out.size() < at[count]) out.resize(at[count]);
#pragma omp parallel for schedule(static) if (count > 1)
  for (std::size_t ch = 0; ch < count; ++ch) out.copy_at(at[ch], chunks[ch]);
  used = at[count];
}

}  // namespace

// A body over this step, as its contacts with particles read it: its pose
// and velocity, its shape's box in its own frame and how far that moves,
// and the rotations to and from its frame (matrices, not the quaternion,
// for the many points taken there and normals taken back).
struct BodyStep {
  BodyStep(const Model& model, const Bodies& bodies, int body);
  Vec3 local(const Vec3& x) const { return to_local * (x - pose.position); }

  const geo::Shape& shape;
  const Pose& pose;
  geo::Aabb bounds;
  Vec3 v, w;
  double v_norm, w_norm;
  double travel;  // of the box's farthest point this step
  Mat3 to_local, to_world;
};

BodyStep::BodyStep(const Model& model, const Bodies& bodies, int body)
    : shape(model.bodies[std::size_t(body)].shape),
      pose(bodies.pose[std::size_t(body)]),
      bounds(geo::local_bounds(shape)),
      v(bodies.velocity[std::size_t(body)]),
      w(bodies.angular_velocity[std::size_t(body)]),
      v_norm(v.norm()),
      w_norm(w.norm()),
      travel(travel_in_step(bounds, v, w, model.step)),
      to_local(pose.orientation.conjugate().toRotationMatrix()),
      to_world(pose.orientation.toRotationMatrix()) {}

void Collider::broadphase(const Model& model, const Particles& p, const Bodies& bodies) {
  const std::size_t n = p.size();
  const double h = model.step;
  reach_.resize(n);
  envelope_.resize(n);
  resting_.resize(n);
  bounding_.resize(n);
  blow_.assign(n, 0.0);
  neighbour_blow_.assign(n, 0.0);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t si = 0; si < std::ptrdiff_t(n); ++si) {
    const auto i = std::size_t(si);
    // The envelope grows with the distance the particle can travel this step
    // (translation plus the swing of its outermost sphere), so nothing tunnels.
    // The translation includes what gravity and the external forces add to
    // the velocity within the step (forced_change): without them, at a 10 ms
    // step, a charged flake pulled to the drum by its image charge
    // (~100 m/s^2) outruns its envelope and goes millimetres into the drum.
    const double bounding = bounding_radius(model, p, i);
    const double speed = (p.velocity[i] + forced_change(model, p, i)).norm();
    const double travel =
        (std::max(p.velocity[i].norm(), speed) + p.angular_velocity[i].norm() * bounding) * h;
    resting_[i] = resting_envelope(model, p, i);
    bounding_[i] = bounding;
    envelope_[i] = resting_[i] + travel;
    reach_[i] = bounding + envelope_[i];
  }
  for (std::size_t b = 0; b < model.bodies.size(); ++b) struck_by_body(model, p, bodies, int(b));
  grid_.find_pairs(p.position, reach_, pairs_);
  struck_by_neighbours(model, p);
}

// A body can strike a particle this step. For the manifold's cull
// (speed_changes), every body's blow is bounded by largest_blow(m_i,
// closing speed), a body's mass being no less than the particle's: any
// point of the particle closes on the surface at most at the centre's
// approach along the surface's normals, plus both spins across the
// particle, plus what gravity and the forces add within the step.
// A moving body's blow also widens the particle's envelope against its
// neighbours: a falling plate drives a grain of a pile into the one below
// it. The blow changes the particle's velocity by at most (1 + e) times
// its approach speed along the surface's normal, and friction by mu times
// that across it: the envelope grows by that change times the step. A
// surface that slides past without closing in (a drum under the particles
// riding it) adds nothing, nor does a body at rest, which sends nothing
// back faster than it came.
void Collider::struck_by_body(const Model& model, const Particles& p, const Bodies& bodies,
                              int body) {
  const BodyStep frame(model, bodies, body);
  const bool moving = frame.v.squaredNorm() > 0.0 || frame.w.squaredNorm() > 0.0;
  const int material = model.bodies[std::size_t(body)].material;
  const double h = model.step;
  const std::size_t n = p.size();
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t si = 0; si < std::ptrdiff_t(n); ++si) {
    static thread_local std::vector<geo::SurfaceHit> hits;
    const auto i = std::size_t(si);
    const Vec3 local = frame.local(p.position[i]);
    const double reach = reach_[i] + frame.travel;
    if (!frame.bounds.inflated(reach).overlaps({local, local})) continue;
    hits.clear();
    geo::query(frame.shape, local, reach, hits);
    if (hits.empty()) continue;
    const Vec3 v_rel = p.velocity[i] - frame.v - frame.w.cross(p.position[i] - frame.pose.position);
    double approach = 0.0;
    for (const geo::SurfaceHit& hit : hits)
      approach = std::max(approach, -v_rel.dot(frame.to_world * hit.normal));
    const double spin = p.angular_velocity[i].norm() + frame.w_norm;
    const double closing =
        approach + spin * bounding_radius(model, p, i) + forced_change(model, p, i).norm();
    const SurfacePair surface = model.materials.pair(material, p.material[i]);
    blow_[i] += largest_blow(surface, p.mass[i], closing);  // one from each body
    if (!moving || approach == 0.0) continue;
    const double kick = (1.0 + surface.restitution) * (1.0 + surface.friction) * approach * h;
    envelope_[i] += kick;
    reach_[i] += kick;
  }
}

// For the manifold's cull (speed_changes): the largest blow a neighbour
// can give each particle this step. Each pair whose envelopes meet can
// pass at most largest_blow of their reduced mass and the speed at which
// any two of their points can close: the centres' relative velocity, the
// forces' change of it within the step and both spins across the
// particles. A particle keeps the largest; a chain can pass on more,
// which the bound leaves to the solve's overlap stop and the wall guard
// (dynamics/safeguards.cpp). In parallel: a maximum is the same in any
// order.
void Collider::struck_by_neighbours(const Model& model, const Particles& p) {
  const double h = model.step;
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(pairs_.size()) > kParallelMin)
  for (std::ptrdiff_t k = 0; k < std::ptrdiff_t(pairs_.size()); ++k) {
    const auto i = std::size_t(pairs_[std::size_t(k)].first);
    const auto j = std::size_t(pairs_[std::size_t(k)].second);
    const Vec3 forces = h * (p.inv_mass[i] * p.force[i] - p.inv_mass[j] * p.force[j]);
    const double closing = (p.velocity[i] - p.velocity[j]).norm() + forces.norm() +
                           p.angular_velocity[i].norm() * bounding_radius(model, p, i) +
                           p.angular_velocity[j].norm() * bounding_radius(model, p, j);
    const double mi = p.mass[i], mj = p.mass[j];
    const SurfacePair surface = model.materials.pair(p.material[i], p.material[j]);
    const double blow = largest_blow(surface, mi * mj / (mi + mj), closing);
    raise_to(neighbour_blow_[i], blow);
    raise_to(neighbour_blow_[j], blow);
  }
}

// What each particle's velocity can change by within the step: gravity and
// the forces (as in broadphase), and the blows of the bodies and of a
// neighbour, in its centre's velocity (blow / m) and in its spin (the blow
// on the longest lever, the bounding radius, over the smallest moment of
// inertia; the torques too), which moves a point d from the centre by
// that times d.
void Collider::speed_changes(const Model& model, const Particles& p) {
  const double h = model.step;
  const std::size_t n = p.size();
  change_.resize(n);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t si = 0; si < std::ptrdiff_t(n); ++si) {
    const auto i = std::size_t(si);
    const double blow = blow_[i] + neighbour_blow_[i];
    const double linear = forced_change(model, p, i).norm();
    const double angular = h * p.torque[i].norm() + blow * bounding_radius(model, p, i);
    change_[i] = {linear + blow * p.inv_mass[i], angular * p.inv_inertia[i].maxCoeff()};
  }
}

void Collider::narrowphase(const Model& model, const Particles& p, const Bodies& bodies,
                           Contacts& out) {
  used_ = 0;  // out is cut to this at the end; see run_chunked
  place_spheres(model, p);
  speed_changes(model, p);
  particle_pairs(model, p, out);
  widen_by_kicks(model, p, out);
  for (std::size_t b = 0; b < model.bodies.size(); ++b)
    body_contacts(model, p, bodies, int(b), out);
  out.resize(used_);
}

// World centres of every particle's spheres, once per step: the pair loop
// visits each of them once per neighbour. And each flake's plate frame,
// once per step, not once per neighbour.
void Collider::place_spheres(const Model& model, const Particles& p) {
  const std::size_t n = p.size();
  sphere_first_.resize(n + 1);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::size_t i = 0; i < n; ++i)
    sphere_first_[i] = model.shapes[std::size_t(p.shape[i])].centers.size();
  sphere_first_[n] = 0;
  exclusive_scan(sphere_first_);
  sphere_centre_.resize(sphere_first_[n]);
  const bool flat = model.contact.flat_faces;
  if (flat) plate_frame_.resize(n);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(n); ++s) {
    const auto i = std::size_t(s);
    const ParticleShape& shape = model.shapes[std::size_t(p.shape[i])];
    const Mat3 turn = p.orientation[i].toRotationMatrix();
    const Mat3 R = turn * p.scale[i];
    for (std::size_t k = 0; k < shape.centers.size(); ++k)
      sphere_centre_[sphere_first_[i] + k] = p.position[i] + R * shape.centers[k];
    if (flat && shape.face.flat())
      plate_frame_[i] = plate_frame(shape.face, turn, p.position[i], p.scale[i]);
  }
}

// A particle can also be struck this step by a neighbour and leave faster
// than it came: a light grain hit by a heavy one in a 10 m/s stream can go
// through a plate it had no contact with. An impact with a particle of mass
// m_j changes its velocity by at most (1 + e) m_j / (m_i + m_j) of their
// relative speed, so against bodies its envelope grows by that speed times
// h, for each pair that is a contact this step (the first used_ of out).
// (Chains can pass on more; the wall guard, dynamics/safeguards.cpp, covers
// the contacts found.) In parallel: a maximum is the same in any order.
void Collider::widen_by_kicks(const Model& model, const Particles& p, const Contacts& out) {
  const std::size_t n = p.size();
  const double h = model.step;
  kick_.assign(n, 0.0);
  const auto particle_contacts = std::ptrdiff_t(used_);
#pragma omp parallel for schedule(static) if (particle_contacts > kParallelMin)
  for (std::ptrdiff_t k = 0; k < particle_contacts; ++k) {
    const auto i = std::size_t(out.body_a[std::size_t(k)]);
    const auto j = std::size_t(out.body_b[std::size_t(k)]);
    const double e = model.materials.surfaces(out.surfaces[std::size_t(k)]).restitution;
    const double rel = (p.velocity[i] - p.velocity[j]).norm() * h * (1.0 + e);
    const double mi = p.mass[i], mj = p.mass[j];
    raise_to(kick_[i], rel * mj / (mi + mj));
    raise_to(kick_[j], rel * mi / (mi + mj));
  }
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t i = 0; i < std::ptrdiff_t(n); ++i) {
    envelope_[std::size_t(i)] += kick_[std::size_t(i)];
    reach_[std::size_t(i)] += kick_[std::size_t(i)];
  }
}

void Collider::particle_pairs(const Model& model, const Particles& p, Contacts& out) {
  const auto& mat = model.materials;
  const double h = model.step;
  const Reduction rule{model.contact.manifold, model.solver.overlap_aim()};
  run_chunked(pairs_.size(), chunks_, out, used_, [&](std::size_t begin, std::size_t end, Contacts& part) {
    static thread_local std::vector<Candidate> candidates;  // kept across steps
    for (std::size_t k = begin; k < end; ++k) {
      // A before B by id, not index: particles move in the arrays (removal,
      // spatial reorder), and the key must stay the same for the warm start
      // and DEM's tangential history.
      auto [i, j] = pairs_[k];
      // Two sleepers ride their carriers together (dynamics/sleep.hpp).
      if (p.asleep(std::size_t(i)) && p.asleep(std::size_t(j))) continue;
      if (p.id[std::size_t(i)] > p.id[std::size_t(j)]) std::swap(i, j);
      const auto ui = std::size_t(i), uj = std::size_t(j);
      const std::uint32_t surfaces = mat.pair_index(p.material[ui], p.material[uj]);
      const PairMotion motion{p.position[ui], p.velocity[ui], p.angular_velocity[ui],
                              p.position[uj], p.velocity[uj], p.angular_velocity[uj],
                              h,              change_[ui],   change_[uj]};
      const double resting = resting_[ui] + resting_[uj];
      const double bounds = bounding_[ui] + bounding_[uj];
      const double envelope =
          motion.search_envelope(resting, bounds, envelope_[ui] + envelope_[uj]);
      // Bounding spheres farther apart than the envelope: every sphere's,
      // face's and rim's test in pair_candidates would fail (each sphere
      // lies within its particle's bounding sphere). The margin is far
      // above the rounding.
      const double reach = (bounds + envelope) * (1.0 + 1e-9);
      if ((p.position[ui] - p.position[uj]).squaredNorm() > reach * reach) continue;
      candidates.clear();
      pair_candidates(model, p, ui, uj, envelope, candidates);
      drop_unreachable(motion, resting, candidates);
      reduce_manifold(candidates, i, j, surfaces, motion, rule, part);
    }
  });
}

void Collider::pair_candidates(const Model& model, const Particles& p, std::size_t i,
                               std::size_t j, double envelope,
                               std::vector<Candidate>& candidates) const {
  const ParticleShape& si = model.shapes[std::size_t(p.shape[i])];
  const ParticleShape& sj = model.shapes[std::size_t(p.shape[j])];
  const double sci = p.scale[i], scj = p.scale[j];
  const Vec3* centre_i = &sphere_centre_[sphere_first_[i]];
  const Vec3* centre_j = &sphere_centre_[sphere_first_[j]];
  const bool flat = model.contact.flat_faces;
  static thread_local RimEdges rim_i, rim_j;  // kept across pairs: no allocation per pair
  const Plate plate_i =
      flat ? Plate(si, plate_frame_[i], p.position[i], sci, centre_i, rim_i) : Plate();
  const Plate plate_j =
      flat ? Plate(sj, plate_frame_[j], p.position[j], scj, centre_j, rim_j) : Plate();
  if (plate_i.active() || plate_j.active()) {
    // A plate meets the other's spheres, or both plates each other's.
    const ContactKey key{p.id[i], p.id[j], 0, 0};
    if (plate_j.active())
      spheres_on_plate(centre_i, si, sci, plate_j, plate_i.active(), true, key, envelope,
                       candidates);
    if (plate_i.active())
      spheres_on_plate(centre_j, sj, scj, plate_i, plate_j.active(), false, key, envelope,
                       candidates);
    if (plate_i.active() && plate_j.active())
      rims_crossing(plate_i, plate_j, key, envelope, candidates);
    return;
  }
  const double reach_j = sj.bounding_radius * scj + envelope;
  for (std::size_t a = 0; a < si.centers.size(); ++a) {
    const Vec3& ca = centre_i[a];
    const double ra = sci * si.radii[a];
    // Skip a sphere of i that cannot reach any sphere of j.
    const double far = reach_j + ra;
    if ((ca - p.position[j]).squaredNorm() > far * far) continue;
    for (std::size_t b = 0; b < sj.centers.size(); ++b) {
      const ContactKey key{p.id[i], p.id[j], std::uint32_t(a), std::uint32_t(b)};
      sphere_sphere(ca, ra, centre_j[b], scj * sj.radii[b], envelope, key, candidates);
    }
  }
}

void Collider::body_contacts(const Model& model, const Particles& p, const Bodies& bodies,
                             int body, Contacts& out) {
  const BodyStep frame(model, bodies, body);
  const int solver_index = int(p.size()) + body;
  // Against a body the cull leaves nothing out as out of reach, and the
  // manifold holds every member whatever the scene's contact.manifold: the
  // wall guard (dynamics/safeguards.cpp) finishes only the rows that are
  // listed, and a grain in the brush nip is driven by a chain of blows no
  // single bound covers. (A flake of four rows on the drum sinks into it
  // past the tolerance, nearer its image charge.)
  const SpeedChange unbounded{std::numeric_limits<double>::infinity(), 0.0};
  const Reduction rule{Manifold::Hold, model.solver.overlap_aim()};
  const int material = model.bodies[std::size_t(body)].material;
  run_chunked(p.size(), chunks_, out, used_, [&](std::size_t begin, std::size_t end, Contacts& part) {
    // Per thread and kept across steps: no allocation per chunk.
    static thread_local std::vector<geo::SurfaceHit> hits;
    static thread_local std::vector<Candidate> candidates;
    for (std::size_t i = begin; i < end; ++i) {
      if (p.carrier[i] == body) continue;  // it rides the body (dynamics/sleep.hpp)
      candidates.clear();
      if (!body_candidates(model, p, frame, body, i, hits, candidates)) continue;
      const PairMotion motion{frame.pose.position, frame.v,       frame.w,
                              p.position[i],       p.velocity[i], p.angular_velocity[i],
                              model.step,          unbounded,     change_[i]};
      reduce_manifold(candidates, solver_index, int(i),
                      model.materials.pair_index(material, p.material[i]), motion, rule, part);
    }
  });
}

// Particle i's candidate contacts with the body; false when its bounding
// sphere cannot reach the body this step.
bool Collider::body_candidates(const Model& model, const Particles& p, const BodyStep& frame,
                               int body, std::size_t i, std::vector<geo::SurfaceHit>& hits,
                               std::vector<Candidate>& candidates) const {
  // Cull by the particle's bounding sphere in the body frame.
  const Vec3 local_centre = frame.local(p.position[i]);
  if (!frame.bounds.inflated(reach_[i] + frame.travel).overlaps({local_centre, local_centre}))
    return false;
  const ParticleShape& s = model.shapes[std::size_t(p.shape[i])];
  const double h = model.step;
  // A cluster (a flake: 19 spheres) far from the surface is passed over
  // on one query of its centre. Distances to a surface are 1-Lipschitz,
  // so no sphere within the bounding radius can then come closer than
  // its own query's reach (below): the same hits, at 1 query, not 19.
  if (s.centers.size() > 1) {
    const double bounding = p.scale[i] * s.bounding_radius * (1.0 + 1e-9);
    const double arm = (p.position[i] - frame.pose.position).norm() + bounding;
    const double surface_travel = (frame.v_norm + frame.w_norm * arm) * h;
    hits.clear();
    geo::query(frame.shape, local_centre, bounding + envelope_[i] + surface_travel, hits);
    if (hits.empty()) return false;
  }
  for (std::size_t k = 0; k < s.centers.size(); ++k) {
    const Vec3& c = sphere_centre_[sphere_first_[i] + k];
    const double r = p.scale[i] * s.radii[k];
    // The body's surface may close in too (a splitter on its slide), by
    // its speed along the normal; a drum turning in place adds nothing.
    const Vec3 v_surface = frame.v + frame.w.cross(c - frame.pose.position);
    const double surface_travel = v_surface.norm() * h;
    hits.clear();
    geo::query(frame.shape, frame.local(c), r + envelope_[i] + surface_travel, hits);
    for (const geo::SurfaceHit& hit : hits) {
      const double gap = hit.distance - r;
      const Vec3 n = frame.to_world * hit.normal;
      if (gap >= envelope_[i] + std::max(0.0, v_surface.dot(n)) * h) continue;
      const ContactKey key{kBodyTag | std::uint64_t(body), p.id[i], hit.feature, std::uint32_t(k)};
      candidates.push_back({n, c - n * (r + 0.5 * gap), gap, r, key});
    }
  }
  return true;
}

}  // namespace ces
