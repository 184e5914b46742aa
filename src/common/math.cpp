#include "common/math.hpp"

namespace ces {

Quat rotation_from_z(const Vec3& axis) {
  return Quat::FromTwoVectors(Vec3::UnitZ(), axis.normalized());
}

}  // namespace ces
