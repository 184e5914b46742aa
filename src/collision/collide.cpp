#include "collision/collide.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <span>
#include <tuple>
#include <utility>

#include "common/parallel.hpp"

namespace ces {
namespace {


constexpr std::size_t kChunk = 128;  // fixed, so contact order never depends on threads

double smallest_radius(const ParticleShape& s) {
  return *std::min_element(s.radii.begin(), s.radii.end());
}

// Particle i's bounding radius, at its scale.
double bounding_radius(const Model& model, const Particles& p, std::size_t i) {
  return model.shapes[std::size_t(p.shape[i])].bounding_radius * p.scale[i];
}

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

// One pair's contacts before the manifold reduction, side by side: most
// are dropped (a flake on the drum keeps its hull's corners), so they go
// to Contacts' nine arrays only once kept.
struct Candidate {
  Vec3 normal, point;
  double gap, radius;
  ContactKey key;
};

void sphere_sphere(const Vec3& ca, double ra, const Vec3& cb, double rb, double envelope,
                   const ContactKey& key, std::vector<Candidate>& out) {
  const Vec3 d = cb - ca;
  const double len = d.norm();
  const double gap = len - ra - rb;
  if (gap >= envelope) return;
  const Vec3 n = safe_direction(d, len);
  out.push_back({n, ca + n * (ra + 0.5 * gap), gap, std::min(ra, rb), key});
}

// A member's place in the plane across its group's normal; by position,
// ties by contact order.
struct Planar {
  double x, y;
  std::size_t k;  // the candidate
  bool operator<(const Planar& o) const { return std::tie(x, y, k) < std::tie(o.x, o.y, o.k); }
};

// a[0, m) in order, by way of spare[0, m). A comparison sort of a flake
// pair's hundred members mispredicts about every other comparison, so
// they are first dealt into m buckets by x: a bucket's index never falls
// as x rises (rounding is monotonic), so the buckets are in order and an
// insertion sort then only moves members within their bucket. The same
// order as std::sort; a NaN, which has no place in it, or a span of x too
// small to divide, leaves the sort to std::sort.
void sort_planar(Planar* a, Planar* spare, std::size_t m, std::vector<std::uint32_t>& counts) {
  double lo = a[0].x, hi = a[0].x;
  bool finite = true;
  for (std::size_t i = 0; i < m; ++i) {
    lo = std::min(lo, a[i].x);
    hi = std::max(hi, a[i].x);
    finite = finite && std::isfinite(a[i].x) && std::isfinite(a[i].y);
  }
  const double scale = double(m) / (hi - lo);  // inf or NaN where hi - lo is 0 or subnormal
  if (!finite || !std::isfinite(scale)) {
    std::sort(a, a + m);
    return;
  }
  auto bucket = [&](double x) { return std::min(m - 1, std::size_t((x - lo) * scale)); };
  counts.assign(m + 1, 0);
  for (std::size_t i = 0; i < m; ++i) ++counts[bucket(a[i].x) + 1];
  for (std::size_t b = 0; b < m; ++b) counts[b + 1] += counts[b];
  for (std::size_t i = 0; i < m; ++i) spare[counts[bucket(a[i].x)]++] = a[i];
  for (std::size_t i = 0; i < m; ++i) {
    const Planar p = spare[i];
    std::size_t j = i;
    for (; j > 0 && p < a[j - 1]; --j) a[j] = a[j - 1];
    a[j] = p;
  }
}

// Twice the signed area of the triangle (o, a, b): positive where a to b
// turns left about o.
double cross(const Planar& o, const Planar& a, const Planar& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// The hull of a group's members across its normal, as hull_points leaves
// it in its thread's buffer until its next call: the members in the plane,
// and the hull's corners in order, counter-clockwise (the first and the
// last corner of each chain appear twice).
struct Hull {
  const Planar* members = nullptr;
  std::size_t count = 0;
  const Planar* corners = nullptr;
  std::size_t corner_count = 0;
};

// A hull's fan of triangles from its first corner o, for interpolating at
// its many members: each corner's offset from o and each triangle's (o, i,
// i + 1) doubled area, made once per hull, where each member would make
// them again. A member's weights in a triangle are cross()'s own numbers.
class Fan {
 public:
  explicit Fan(const Hull& hull);
  // `value` (one per corner) interpolated linearly at p, on the first
  // triangle that holds it; `outside` if none does (a hull with no area:
  // members in a line).
  double interpolate(const Planar& p, const std::vector<double>& value, double outside) const;

 private:
  static constexpr double kEdge = 1e-9;  // of the triangle's area: a point on an edge is in it
  const Hull& hull_;
  // In the thread's buffer (per corner: dx, dy; per triangle: area, and
  // below it a weight surely under -kEdge), until the next Fan.
  const double *dx_ = nullptr, *dy_ = nullptr, *area_ = nullptr, *below_ = nullptr;
};

Fan::Fan(const Hull& hull) : hull_(hull) {
  static thread_local std::vector<double> buffer;
  const std::size_t n = hull.corner_count;
  buffer.resize(4 * n);
  double* dx = buffer.data();
  double* dy = dx + n;
  double* area = dy + n;
  double* below = area + n;
  const Planar& o = hull.corners[0];
  for (std::size_t i = 0; i < n; ++i) {
    dx[i] = hull.corners[i].x - o.x;
    dy[i] = hull.corners[i].y - o.y;
  }
  for (std::size_t i = 1; i + 1 < n; ++i) {
    area[i] = dx[i] * dy[i + 1] - dy[i] * dx[i + 1];  // cross(o, a, b)
    // A cross product under this has a weight under -kEdge whatever the
    // division rounds to: most triangles are passed over without one. (An
    // area so small that the bound would round coarsely, near the
    // subnormals, leaves every triangle to the division.)
    below[i] = area[i] > 1e-290 ? -kEdge * area[i] * (1.0 + 1e-6)
                                : -std::numeric_limits<double>::infinity();
  }
  dx_ = dx;
  dy_ = dy;
  area_ = area;
  below_ = below;
}

double Fan::interpolate(const Planar& p, const std::vector<double>& value, double outside) const {
  const Planar& o = hull_.corners[0];
  const double px = p.x - o.x, py = p.y - o.y;
  for (std::size_t i = 1; i + 1 < hull_.corner_count; ++i) {
    const double area = area_[i];
    if (!(area > 0.0)) continue;
    const double cs = px * dy_[i + 1] - py * dx_[i + 1];  // cross(o, p, b)
    if (cs < below_[i]) continue;
    const double ct = dx_[i] * py - dy_[i] * px;  // cross(o, a, p)
    if (ct < below_[i]) continue;
    const double s = cs / area, t = ct / area;
    if (s < -kEdge || t < -kEdge || s + t > 1.0 + kEdge) continue;
    return (1.0 - s - t) * value[0] + s * value[i] + t * value[i + 1];
  }
  return outside;
}

// A group's kept: the deepest and the corners of the members' convex hull
// in the plane across the group's normal (Andrew's monotone chain, members
// ordered by position, ties by contact order, so the choice is the same
// whatever the gaps). Returns the hull, for keep_unheld.
Hull hull_points(const std::vector<Candidate>& c, std::span<const std::size_t> members,
                 std::vector<std::uint8_t>& keep) {
  std::size_t deepest = members[0];
  for (std::size_t k : members)
    if (c[k].gap < c[deepest].gap) deepest = k;
  keep[deepest] = 1;
  const Vec3& n = c[members[0]].normal;
  const Vec3 u = n.unitOrthogonal(), v = n.cross(u);
  // The members, a spare for sorting them, then the chain (at most two
  // entries a member: the lower hull and the upper), in one buffer per
  // thread, kept across pairs. Used through plain pointers: the compiler
  // then keeps the chain's top in a register, not in the thread's storage
  // at every push and pop.
  static thread_local std::vector<Planar> buffer;
  static thread_local std::vector<std::uint32_t> counts;
  const std::size_t m = members.size();
  buffer.resize(4 * m);
  Planar* const order = buffer.data();
  Planar* const chain = order + 2 * m;
  for (std::size_t i = 0; i < m; ++i) {
    const Vec3& x = c[members[i]].point;
    order[i] = {x.dot(u), x.dot(v), members[i]};
  }
  sort_planar(order, order + m, m, counts);
  // Lower hull left to right, then upper hull right to left.
  std::size_t top = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const std::size_t floor = top;
    for (std::size_t i = 0; i < m; ++i) {
      const Planar& p = order[pass == 0 ? i : m - 1 - i];
      while (top >= floor + 2 && !(cross(chain[top - 2], chain[top - 1], p) > 0.0)) --top;
      chain[top++] = p;
    }
  }
  for (std::size_t i = 0; i < top; ++i) keep[chain[i].k] = 1;
  return {order, m, chain, top};
}

// Of `plane`, the member farthest from `from` (ties to the first), or null
// if all are at it.
const Planar* farthest(std::span<const Planar> plane, const Planar& from) {
  const Planar* far = nullptr;
  double most = 0.0;
  for (const Planar& q : plane) {
    const double dx = q.x - from.x, dy = q.y - from.y, squared = dx * dx + dy * dy;
    if (squared > most) {
      most = squared;
      far = &q;
    }
  }
  return far;
}

// Of `plane`, the members farthest from the line a to b on its left and on
// its right (ties to the first); null on a side with none off the line.
std::pair<const Planar*, const Planar*> farthest_sides(std::span<const Planar> plane,
                                                       const Planar& a, const Planar& b) {
  const Planar *left = nullptr, *right = nullptr;
  double high = 0.0, low = 0.0;
  for (const Planar& q : plane) {
    const double area = cross(a, b, q);
    if (area > high) {
      high = area;
      left = &q;
    }
    if (area < low) {
      low = area;
      right = &q;
    }
  }
  return {left, right};
}

// A group's four (Manifold::Four): the deepest, the member farthest from
// it and, on each side of the line through those two, the member farthest
// from it: the triangles of largest area on that line, as Jolt prunes a
// face's contacts. Each of the three is a corner of the members' hull (a
// distance from a point, or from a line, is largest at a corner), so no
// hull is made: one pass places the members in the plane across the
// group's normal, three scans choose. Members in a line keep the deepest
// and both ends.
void keep_four(const std::vector<Candidate>& c, std::span<const std::size_t> members,
               std::vector<std::uint8_t>& keep) {
  static thread_local std::vector<Planar> plane;
  const Vec3& n = c[members[0]].normal;
  const Vec3 u = n.unitOrthogonal(), v = n.cross(u);
  plane.resize(members.size());
  std::size_t deepest = 0;
  for (std::size_t i = 0; i < members.size(); ++i) {
    const Vec3& x = c[members[i]].point;
    plane[i] = {x.dot(u), x.dot(v), members[i]};
    if (c[members[i]].gap < c[members[deepest]].gap) deepest = i;
  }
  const Planar& d = plane[deepest];
  keep[d.k] = 1;
  const Planar* far = farthest(plane, d);
  if (!far) return;
  keep[far->k] = 1;
  const auto [left, right] = farthest_sides(plane, d, *far);
  if (left) keep[left->k] = 1;
  if (right) keep[right->k] = 1;
  if (!left && !right) keep[farthest(plane, *far)->k] = 1;
}

// The motion of a pair's B side relative to its A side at the step's
// start: how far a point of B moves against A in one step.
struct PairMotion {
  Vec3 xa, va, wa, xb, vb, wb;
  double h;
  SpeedChange ca, cb;  // what each side's velocity can change by within the step
  double travel(const Vec3& p) const {
    return h * (vb + wb.cross(p - xb) - va - wa.cross(p - xa)).norm();
  }
  // The most the pair can close at p this step: the start's travel plus
  // each side's change of velocity there, over the step.
  double reach(const Vec3& p) const {
    const double a = ca.linear + ca.angular * (p - xa).norm();
    const double b = cb.linear + cb.angular * (p - xb).norm();
    return travel(p) + h * (a + b);
  }
};

// The members the kept rows of a group do not hold. Across a rigid face the
// normal velocity is affine, so where the kept rows hold (each closes by at
// most its gap) the group's normal closes, at a member inside the hull, by
// at most the corners' gaps interpolated there. That bounds the member's
// own row only as far as the normals are the group's: turned by |n - n_g|,
// a row also takes that much of the pair's travel across it (each side's
// slack). And the gaps themselves are affine only between flat surfaces:
// between two flakes' spheres a member can be nearer than the corners
// around it. A member that could so end overlapping by more than the
// overlap aim (SolverSettings::overlap_aim) with every kept row met (two
// flakes spinning against each other in the brush nip) is kept too, unless
// its gap is more than the pair can close there this step (motion.reach):
// then no row is needed to hold it. A flat face on a wall keeps its
// corners alone.
void keep_unheld(const std::vector<Candidate>& c, const Vec3& n_g, const Hull& hull,
                 const PairMotion& motion, double tolerance, std::vector<std::uint8_t>& keep) {
  // A group the hull and the deepest hold whole (a 7-sphere flake: its
  // ring and centre) has no member left to test.
  bool all_kept = true;
  for (std::size_t i = 0; i < hull.count && all_kept; ++i) all_kept = keep[hull.members[i].k];
  if (all_kept) return;
  auto slack = [&](std::size_t k) {
    return (c[k].normal - n_g).norm() * motion.travel(c[k].point);
  };
  static thread_local std::vector<double> closing;  // per corner: gap + slack
  closing.resize(hull.corner_count);
  double most = -std::numeric_limits<double>::infinity();
  const std::size_t last = hull.corner_count - 1;
  for (std::size_t i = 0; i < hull.corner_count; ++i) {
    const std::size_t k = hull.corners[i].k;
    // The chains' ends appear twice (Hull): their slack, two square roots,
    // is taken once.
    if (i > 0 && k == hull.corners[i - 1].k)
      closing[i] = closing[i - 1];
    else if (i == last && i > 0 && k == hull.corners[0].k)
      closing[i] = closing[0];
    else
      closing[i] = c[k].gap + slack(k);
    most = std::max(most, closing[i]);
  }
  const Fan fan(hull);
  for (std::size_t i = 0; i < hull.count; ++i) {
    const Planar& p = hull.members[i];
    if (keep[p.k] || c[p.k].gap > motion.reach(c[p.k].point)) continue;
    const double allowed = c[p.k].gap - slack(p.k) + tolerance * c[p.k].radius;
    if (allowed < most && allowed < fan.interpolate(p, closing, most)) keep[p.k] = 1;
  }
}

// The envelope of a particle at rest: a fraction of its smallest sphere's
// radius.
double resting_envelope(const Model& model, const Particles& p, std::size_t i) {
  const ParticleShape& s = model.shapes[std::size_t(p.shape[i])];
  return model.contact.envelope_fraction * smallest_radius(s) * p.scale[i];
}

// Each particle's envelope grows with its own travel in the step, so two
// flakes riding the drum together list each other's spheres a millimetre
// apart that their relative motion never closes. Out go the candidates
// farther than the pair's resting envelopes plus what it can close there
// this step (motion.reach): the envelope of the relative travel, which a
// pile at rest has already.
void drop_unreachable(const PairMotion& motion, double resting, std::vector<Candidate>& c) {
  std::erase_if(c, [&](const Candidate& k) { return k.gap > resting + motion.reach(k.point); });
}

// How reduce_manifold reduces a group: the scene's choice, and the overlap
// aim Manifold::Hold holds the members to.
struct Reduction {
  Manifold manifold;
  double tolerance;
};

// A flat face resting on another touches it with many of its spheres at
// once (a flake lying on the drum: 19). The corners of the face's hull hold
// it as well and cost less, so per group of nearly parallel normals a
// pair's candidates keep the deepest (it carries the overlap) and the
// hull's corners (manifold reduction, as Box2D and Jolt do it): under
// Manifold::Hold all the corners and the members those cannot hold
// (keep_unheld), under Manifold::Four three corners (keep_four). A group
// with other normals (a corner) keeps its own. The kept go to `out` in the
// candidates' order.
void reduce_manifold(const std::vector<Candidate>& c, int body_a, int body_b,
                     std::uint32_t surfaces, const PairMotion& motion, Reduction rule,
                     Contacts& out) {
  constexpr std::size_t kKeep = 5;
  constexpr double kSameNormal = 0.95;  // cos 18°
  const std::size_t n = c.size();
  auto push = [&](const Candidate& k) {
    out.push(body_a, body_b, k.normal, k.point, k.gap, k.radius, surfaces, k.key);
  };
  if (n <= kKeep) {
    for (const Candidate& k : c) push(k);
    return;
  }
  static thread_local std::vector<int> group;
  static thread_local std::vector<std::uint8_t> keep;
  static thread_local std::vector<std::size_t> by_group, start, fill, leader;
  group.resize(n);
  keep.assign(n, 0);
  // A candidate joins the first group (in the order they were opened) whose
  // first member's normal is close to its own, or opens one. Most join the
  // first: a flake on the drum makes one group, a pair of flakes two or three.
  leader.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3& ni = c[i].normal;
    std::size_t g = 0;
    while (g < leader.size() && ni.dot(c[leader[g]].normal) <= kSameNormal) ++g;
    if (g == leader.size()) leader.push_back(i);
    group[i] = int(g);
  }
  // The contacts by group, each group's in contact order (a counting sort),
  // where scanning every contact for each group costs as much as the
  // grouping. One group (most pairs) is the contacts as they are.
  const std::size_t groups = leader.size();
  by_group.resize(n);
  start.assign(groups + 1, 0);
  if (groups == 1) {
    for (std::size_t i = 0; i < n; ++i) by_group[i] = i;
    start[1] = n;
  } else {
    for (std::size_t i = 0; i < n; ++i) ++start[std::size_t(group[i]) + 1];
    for (std::size_t g = 0; g < groups; ++g) start[g + 1] += start[g];
    fill.assign(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < n; ++i) by_group[fill[std::size_t(group[i])]++] = i;
  }
  for (std::size_t g = 0; g < groups; ++g) {
    const std::span<const std::size_t> members(by_group.data() + start[g], start[g + 1] - start[g]);
    if (members.size() <= kKeep) {
      for (std::size_t k : members) keep[k] = 1;
      continue;
    }
    if (rule.manifold == Manifold::Four) {
      keep_four(c, members, keep);
      continue;
    }
    const Hull hull = hull_points(c, members, keep);
    keep_unheld(c, c[members[0]].normal, hull, motion, rule.tolerance, keep);
  }
  for (std::size_t k = 0; k < n; ++k)
    if (keep[k]) push(c[k]);
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
  const std::size_t count = (n + kChunk - 1) / kChunk;
  // Never shrink: the buffers keep their capacity from step to step.
  if (chunks.size() < count) chunks.resize(count);
  // Chunks by for_each_chunk: the particles are ordered in space, so those
  // near a body (19 queries a flake) or in a pile come in runs, and with
  // static halves the less busy thread would idle through most of the
  // body-contact loops; here it takes over the rest of the busier share.
  // Handed out as threads free up (dynamic), the chunks' buffers would move
  // between the cores every step, which costs the pair loop what the second
  // thread gains. Each chunk fills its own list: the same contacts.
  for_each_chunk(count, count > 1, [&](std::size_t ch) {
    chunks[ch].clear();
    fill(ch * kChunk, std::min(n, (ch + 1) * kChunk), chunks[ch]);
  });
  // Copied into place in parallel at `used`: 112 bytes a contact, on one
  // thread the largest serial part of the stage. `out` keeps the last
  // step's length until the stage ends (Collider::collide), so it is
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

void Collider::broadphase(const Model& model, const Particles& p, const Bodies& bodies) {
  const std::size_t n = p.size();
  const double h = model.step;
  centers_.resize(n);
  reach_.resize(n);
  envelope_.resize(n);
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
    envelope_[i] = resting_envelope(model, p, i) + travel;
    centers_[i] = p.position[i];
    reach_[i] = bounding + envelope_[i];
  }
  for (std::size_t b = 0; b < model.bodies.size(); ++b) struck_by_body(model, p, bodies, int(b));
  grid_.find_pairs(centers_, reach_, pairs_);
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
  const Vec3& v_body = bodies.velocity[std::size_t(body)];
  const Vec3& w_body = bodies.angular_velocity[std::size_t(body)];
  const bool moving = v_body.squaredNorm() > 0.0 || w_body.squaredNorm() > 0.0;
  const RigidBody& rb = model.bodies[std::size_t(body)];
  const Pose& pose = bodies.pose[std::size_t(body)];
  const geo::Aabb bounds = geo::local_bounds(rb.shape);
  const double h = model.step;
  const double body_travel = travel_in_step(bounds, v_body, w_body, h);
  const Mat3 to_local = pose.orientation.conjugate().toRotationMatrix();
  const Mat3 to_world = pose.orientation.toRotationMatrix();
  const std::size_t n = p.size();
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t si = 0; si < std::ptrdiff_t(n); ++si) {
    static thread_local std::vector<geo::SurfaceHit> hits;
    const auto i = std::size_t(si);
    const Vec3 local = to_local * (p.position[i] - pose.position);
    const double reach = reach_[i] + body_travel;
    if (!bounds.inflated(reach).overlaps({local, local})) continue;
    hits.clear();
    geo::query(rb.shape, local, reach, hits);
    if (hits.empty()) continue;
    const Vec3 v_rel = p.velocity[i] - v_body - w_body.cross(p.position[i] - pose.position);
    double approach = 0.0;
    for (const geo::SurfaceHit& hit : hits)
      approach = std::max(approach, -v_rel.dot(to_world * hit.normal));
    const double spin = p.angular_velocity[i].norm() + w_body.norm();
    const double closing =
        approach + spin * bounding_radius(model, p, i) + forced_change(model, p, i).norm();
    const SurfacePair surface = model.materials.pair(rb.material, p.material[i]);
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
  const std::size_t n = p.size();
  const double h = model.step;
  // World centres of every particle's spheres, once per step: the pair loop
  // below visits each of them once per neighbour.
  sphere_first_.resize(n + 1);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::size_t i = 0; i < n; ++i)
    sphere_first_[i] = model.shapes[std::size_t(p.shape[i])].centers.size();
  sphere_first_[n] = 0;
  exclusive_scan(sphere_first_);
  sphere_centre_.resize(sphere_first_[n]);
#pragma omp parallel for schedule(static) if (std::ptrdiff_t(n) > kParallelMin)
  for (std::ptrdiff_t s = 0; s < std::ptrdiff_t(n); ++s) {
    const auto i = std::size_t(s);
    const ParticleShape& shape = model.shapes[std::size_t(p.shape[i])];
    const Mat3 R = p.orientation[i].toRotationMatrix() * p.scale[i];
    for (std::size_t k = 0; k < shape.centers.size(); ++k)
      sphere_centre_[sphere_first_[i] + k] = p.position[i] + R * shape.centers[k];
  }
  speed_changes(model, p);
  particle_pairs(model, p, out);
  // A particle can also be struck this step by a neighbour and leave faster
  // than it came: a light grain hit by a heavy one in a 10 m/s stream can
  // go through a plate it had no contact with. An impact with a particle of
  // mass m_j changes its velocity by at most (1 + e) m_j / (m_i + m_j) of
  // their relative speed, so against bodies its envelope grows by that
  // speed times h, for each pair that is a contact this step. (Chains can
  // pass on more; the wall guard, dynamics/safeguards.cpp, covers the
  // contacts found.)
  // In parallel: a maximum is the same in any order.
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
  for (std::size_t b = 0; b < model.bodies.size(); ++b) body_contacts(model, p, bodies, int(b), out);
  out.resize(used_);
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
      if (p.id[std::size_t(i)] > p.id[std::size_t(j)]) std::swap(i, j);
      const auto ui = std::size_t(i), uj = std::size_t(j);
      const ParticleShape& si = model.shapes[std::size_t(p.shape[ui])];
      const ParticleShape& sj = model.shapes[std::size_t(p.shape[uj])];
      const std::uint32_t surfaces = mat.pair_index(p.material[ui], p.material[uj]);
      const double envelope = envelope_[ui] + envelope_[uj];
      const double sci = p.scale[ui], scj = p.scale[uj];
      candidates.clear();
      const Vec3* centre_i = &sphere_centre_[sphere_first_[ui]];
      const Vec3* centre_j = &sphere_centre_[sphere_first_[uj]];
      const double reach_j = sj.bounding_radius * scj + envelope;
      for (std::size_t a = 0; a < si.centers.size(); ++a) {
        const Vec3& ca = centre_i[a];
        // Skip a sphere of i that cannot reach any sphere of j.
        const double far = reach_j + sci * si.radii[a];
        if ((ca - p.position[uj]).squaredNorm() > far * far) continue;
        for (std::size_t b = 0; b < sj.centers.size(); ++b) {
          const Vec3& cb = centre_j[b];
          const ContactKey key{p.id[ui], p.id[uj], std::uint32_t(a), std::uint32_t(b)};
          sphere_sphere(ca, sci * si.radii[a], cb, scj * sj.radii[b], envelope, key, candidates);
        }
      }
      const PairMotion motion{p.position[ui], p.velocity[ui], p.angular_velocity[ui],
                              p.position[uj], p.velocity[uj], p.angular_velocity[uj],
                              h,              change_[ui],   change_[uj]};
      drop_unreachable(motion, resting_envelope(model, p, ui) + resting_envelope(model, p, uj),
                       candidates);
      reduce_manifold(candidates, i, j, surfaces, motion, rule, part);
    }
  });
}

void Collider::body_contacts(const Model& model, const Particles& p, const Bodies& bodies,
                             int body, Contacts& out) {
  const RigidBody& rb = model.bodies[std::size_t(body)];
  const Pose& pose = bodies.pose[std::size_t(body)];
  const geo::Aabb bounds = geo::local_bounds(rb.shape);
  const Vec3& v_body = bodies.velocity[std::size_t(body)];
  const Vec3& w_body = bodies.angular_velocity[std::size_t(body)];
  const double w_norm = w_body.norm(), v_norm = v_body.norm();
  const double body_travel = travel_in_step(bounds, v_body, w_body, model.step);
  // Matrices, not the quaternion, for the many points taken to the body's
  // frame and normals taken back.
  const Mat3 to_local = pose.orientation.conjugate().toRotationMatrix();
  const Mat3 to_world = pose.orientation.toRotationMatrix();
  auto local = [&](const Vec3& x) -> Vec3 { return to_local * (x - pose.position); };
  const int solver_index = int(p.size()) + body;
  // Against a body the cull leaves nothing out as out of reach, and the
  // manifold holds every member whatever the scene's contact.manifold: the
  // wall guard (dynamics/safeguards.cpp) finishes only the rows that are
  // listed, and a grain in the brush nip is driven by a chain of blows no
  // single bound covers. (A flake of four rows on the drum sinks into it
  // past the tolerance, nearer its image charge.)
  const SpeedChange unbounded{std::numeric_limits<double>::infinity(), 0.0};
  const Reduction rule{Manifold::Hold, model.solver.overlap_aim()};
  const auto& mat = model.materials;
  run_chunked(p.size(), chunks_, out, used_, [&](std::size_t begin, std::size_t end, Contacts& part) {
    // Per thread and kept across steps: no allocation per chunk.
    static thread_local std::vector<geo::SurfaceHit> hits;
    static thread_local std::vector<Candidate> candidates;
    for (std::size_t i = begin; i < end; ++i) {
      // Cull by the particle's bounding sphere in the body frame.
      const Vec3 local_centre = local(p.position[i]);
      if (!bounds.inflated(reach_[i] + body_travel).overlaps({local_centre, local_centre})) continue;
      const ParticleShape& s = model.shapes[std::size_t(p.shape[i])];
      // A cluster (a flake: 19 spheres) far from the surface is passed over
      // on one query of its centre. Distances to a surface are 1-Lipschitz,
      // so no sphere within the bounding radius can then come closer than
      // its own query's reach (below): the same hits, at 1 query, not 19.
      if (s.centers.size() > 1) {
        const double bounding = p.scale[i] * s.bounding_radius * (1.0 + 1e-9);
        const double arm = (p.position[i] - pose.position).norm() + bounding;
        const double surface_travel = (v_norm + w_norm * arm) * model.step;
        hits.clear();
        geo::query(rb.shape, local_centre, bounding + envelope_[i] + surface_travel, hits);
        if (hits.empty()) continue;
      }
      const std::uint32_t surfaces = mat.pair_index(rb.material, p.material[i]);
      candidates.clear();
      for (std::size_t k = 0; k < s.centers.size(); ++k) {
        const Vec3& c = sphere_centre_[sphere_first_[i] + k];
        const double r = p.scale[i] * s.radii[k];
        // The body's surface may close in too (a splitter on its slide), by
        // its speed along the normal; a drum turning in place adds nothing.
        const Vec3 v_surface = v_body + w_body.cross(c - pose.position);
        const double surface_travel = v_surface.norm() * model.step;
        hits.clear();
        geo::query(rb.shape, local(c), r + envelope_[i] + surface_travel, hits);
        for (const geo::SurfaceHit& hit : hits) {
          const double gap = hit.distance - r;
          const Vec3 n = to_world * hit.normal;
          if (gap >= envelope_[i] + std::max(0.0, v_surface.dot(n)) * model.step) continue;
          const ContactKey key{kBodyTag | std::uint64_t(body), p.id[i], hit.feature,
                               std::uint32_t(k)};
          candidates.push_back({n, c - n * (r + 0.5 * gap), gap, r, key});
        }
      }
      const PairMotion motion{pose.position,         v_body,     w_body,    p.position[i],
                              p.velocity[i],         p.angular_velocity[i], model.step,
                              unbounded,             change_[i]};
      reduce_manifold(candidates, solver_index, int(i), surfaces, motion, rule, part);
    }
  });
}

}  // namespace ces
