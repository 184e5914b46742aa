#include "collision/manifold.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <utility>

#include "common/hull.hpp"

namespace ces {
namespace {

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
// them again. A member's weights in a triangle are turn()'s own numbers.
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
    area[i] = dx[i] * dy[i + 1] - dy[i] * dx[i + 1];  // turn(o, a, b)
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
    const double cs = px * dy_[i + 1] - py * dx_[i + 1];  // turn(o, p, b)
    if (cs < below_[i]) continue;
    const double ct = dx_[i] * py - dy_[i] * px;  // turn(o, a, p)
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
  const std::size_t top = monotone_chain(order, m, chain, [](const Planar& o, const Planar& a,
                                                             const Planar& b) {
    return turn(o, a, b) > 0.0;
  });
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
    const double area = turn(a, b, q);
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

bool on_face(const Candidate& c) {
  return c.key.feature_a == kPlateFeature || c.key.feature_b == kPlateFeature;
}

// A pair's candidates in groups of nearly parallel normals, each group's
// in candidate order. A candidate joins the first group (in the order they
// were opened) whose first member's normal is close to its own, or opens
// one. Most join the first: a flake on the drum makes one group, a pair of
// flakes two or three. A plate's face (contact.flake_faces flat) makes a
// group of its own: its rows have gaps affine over it, so its corners hold
// it, which a rim's row with a normal near the face's would not.
class NormalGroups {
 public:
  void make(const std::vector<Candidate>& c) {
    constexpr double kSameNormal = 0.95;  // cos 18°
    const std::size_t n = c.size();
    group_.resize(n);
    leader_.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3& ni = c[i].normal;
      const bool face = on_face(c[i]);
      std::size_t g = 0;
      while (g < leader_.size() &&
             (on_face(c[leader_[g]]) != face || ni.dot(c[leader_[g]].normal) <= kSameNormal))
        ++g;
      if (g == leader_.size()) leader_.push_back(i);
      group_[i] = g;
    }
    order_by_group();
  }
  std::size_t count() const { return leader_.size(); }
  std::span<const std::size_t> members(std::size_t g) const {
    return {by_group_.data() + start_[g], start_[g + 1] - start_[g]};
  }

 private:
  // A counting sort, where scanning every candidate for each group costs
  // as much as the grouping. One group (most pairs) is the candidates as
  // they are.
  void order_by_group() {
    const std::size_t n = group_.size(), groups = count();
    by_group_.resize(n);
    start_.assign(groups + 1, 0);
    if (groups == 1) {
      for (std::size_t i = 0; i < n; ++i) by_group_[i] = i;
      start_[1] = n;
      return;
    }
    for (std::size_t i = 0; i < n; ++i) ++start_[group_[i] + 1];
    for (std::size_t g = 0; g < groups; ++g) start_[g + 1] += start_[g];
    fill_.assign(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < n; ++i) by_group_[fill_[group_[i]]++] = i;
  }

  std::vector<std::size_t> group_, leader_, by_group_, start_, fill_;
};

}  // namespace

// Within those balls reach is at most h (L + W (bounds + E / 2)), L the
// relative speed and both sides' linear changes, W both spins and angular
// changes; E is the least envelope above resting plus that, with a margin
// far above the rounding of the gaps and the reach. Where the spins turn
// the pair by a radian or more in a step (h W >= 1), no such E is worth
// solving for.
double PairMotion::search_envelope(double resting, double bounds, double envelopes) const {
  const double L = (vb - va).norm() + ca.linear + cb.linear;
  const double W = wa.norm() + wb.norm() + ca.angular + cb.angular;
  const double shrink = 1.0 - 0.5 * h * W;
  if (!(shrink > 0.5)) return envelopes;
  const double E = (resting + h * (L + W * bounds)) / shrink * (1.0 + 1e-6);
  return std::min(envelopes, E + std::numeric_limits<double>::min());  // above a gap of 0 kept
}

void reduce_manifold(const std::vector<Candidate>& c, int body_a, int body_b,
                     std::uint32_t surfaces, const PairMotion& motion, Reduction rule,
                     Contacts& out) {
  constexpr std::size_t kKeep = 5;
  const std::size_t n = c.size();
  auto push = [&](const Candidate& k) {
    out.push(body_a, body_b, k.normal, k.point, k.gap, k.radius, surfaces, k.key);
  };
  if (n <= kKeep) {
    for (const Candidate& k : c) push(k);
    return;
  }
  static thread_local NormalGroups groups;
  static thread_local std::vector<std::uint8_t> keep;
  groups.make(c);
  keep.assign(n, 0);
  for (std::size_t g = 0; g < groups.count(); ++g) {
    const std::span<const std::size_t> members = groups.members(g);
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

}  // namespace ces
