// The convex hull of points in a plane, by Andrew's monotone chain, and its
// turn test: what the manifold reduction (a pair's contacts in the plane
// across their normal) and a flake's plate (its sphere centres) both build
// their hulls on.
#pragma once
#include <cstddef>

namespace ces {

// Twice the signed area of the triangle (o, a, b), of points with x and y:
// positive where a to b turns left about o.
template <class Point>
double turn(const Point& o, const Point& a, const Point& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// The corner after corner i of a hull of n, round the loop, without a
// division.
inline std::size_t next_corner(std::size_t i, std::size_t n) { return i + 1 == n ? 0 : i + 1; }

// Of m points sorted by x, then y, the hull's corners into `chain` (room for
// 2m): the lower hull left to right, then the upper right to left. Each
// chain's last point starts the next, so the two ends appear twice.
// `keeps(o, a, b)`: whether a, after o, stays a corner when b follows (a
// turn to the left; how strict is the caller's). Returns the chain's length.
// Plain pointers, so that the chain's top stays in a register.
template <class Point, class Keeps>
std::size_t monotone_chain(const Point* sorted, std::size_t m, Point* chain, Keeps keeps) {
  std::size_t top = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const std::size_t floor = top;
    for (std::size_t i = 0; i < m; ++i) {
      const Point& p = sorted[pass == 0 ? i : m - 1 - i];
      while (top >= floor + 2 && !keeps(chain[top - 2], chain[top - 1], p)) --top;
      chain[top++] = p;
    }
  }
  return top;
}

}  // namespace ces
