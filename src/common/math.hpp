// Linear-algebra vocabulary shared by every stage. Double precision throughout:
// a 0.1 mm particle on a 0.16 m drum needs it.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <numbers>

namespace ces {

using Vec3 = Eigen::Vector3d;
using Vec2 = Eigen::Vector2d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

inline constexpr double kPi = std::numbers::pi;

struct Pose {
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();

  Vec3 apply(const Vec3& local) const { return position + orientation * local; }
  Vec3 inverse_apply(const Vec3& world) const {
    return orientation.conjugate() * (world - position);
  }
};

// Rotation taking +z onto `axis` (unit); the drum and cylinder shapes are
// defined along local z.
Quat rotation_from_z(const Vec3& axis);

}  // namespace ces
