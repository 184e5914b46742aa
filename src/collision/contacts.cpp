#include "collision/contacts.hpp"

#include <algorithm>

#include "common/parallel.hpp"

namespace ces {

void Contacts::clear() {
  body_a.clear();
  body_b.clear();
  normal.clear();
  point.clear();
  gap.clear();
  radius.clear();
  surfaces.clear();
  key.clear();
}

void Contacts::push(int a, int b, const Vec3& n, const Vec3& p, double g, double r,
                    std::uint32_t surface_pair, const ContactKey& k) {
  body_a.push_back(a);
  body_b.push_back(b);
  normal.push_back(n);
  point.push_back(p);
  gap.push_back(g);
  radius.push_back(r);
  surfaces.push_back(surface_pair);
  key.push_back(k);
}

void Contacts::resize(std::size_t n) {
  body_a.resize(n);
  body_b.resize(n);
  normal.resize(n);
  point.resize(n);
  gap.resize(n);
  radius.resize(n);
  surfaces.resize(n);
  key.resize(n);
}

namespace {
template <class T>
void put(std::vector<T>& to, std::size_t at, const std::vector<T>& from) {
  std::copy(from.begin(), from.end(), to.begin() + std::ptrdiff_t(at));
}
}  // namespace

void Contacts::copy_at(std::size_t at, const Contacts& o) {
  put(body_a, at, o.body_a);
  put(body_b, at, o.body_b);
  put(normal, at, o.normal);
  put(point, at, o.point);
  put(gap, at, o.gap);
  put(radius, at, o.radius);
  put(surfaces, at, o.surfaces);
  put(key, at, o.key);
}

}  // namespace ces
