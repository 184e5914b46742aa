#include "collision/contacts.hpp"

namespace ces {

void Contacts::clear() {
  body_a.clear();
  body_b.clear();
  normal.clear();
  point.clear();
  gap.clear();
  radius.clear();
  friction.clear();
  restitution.clear();
  key.clear();
}

void Contacts::push(int a, int b, const Vec3& n, const Vec3& p, double g, double r,
                    double mu, double e, const ContactKey& k) {
  body_a.push_back(a);
  body_b.push_back(b);
  normal.push_back(n);
  point.push_back(p);
  gap.push_back(g);
  radius.push_back(r);
  friction.push_back(mu);
  restitution.push_back(e);
  key.push_back(k);
}

namespace {
template <class T>
void extend(std::vector<T>& to, const std::vector<T>& from) {
  to.insert(to.end(), from.begin(), from.end());
}
}  // namespace

void Contacts::append(const Contacts& o) {
  extend(body_a, o.body_a);
  extend(body_b, o.body_b);
  extend(normal, o.normal);
  extend(point, o.point);
  extend(gap, o.gap);
  extend(radius, o.radius);
  extend(friction, o.friction);
  extend(restitution, o.restitution);
  extend(key, o.key);
}

void Contacts::compact_tail(std::size_t first, const std::vector<std::uint8_t>& keep) {
  auto squeeze = [&](auto& v) {
    std::size_t to = first;
    for (std::size_t k = 0; k < keep.size(); ++k)
      if (keep[k]) v[to++] = v[first + k];
    v.resize(to);
  };
  squeeze(body_a);
  squeeze(body_b);
  squeeze(normal);
  squeeze(point);
  squeeze(gap);
  squeeze(radius);
  squeeze(friction);
  squeeze(restitution);
  squeeze(key);
}

}  // namespace ces
