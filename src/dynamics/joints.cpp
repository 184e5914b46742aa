#include "dynamics/joints.hpp"

#include <algorithm>
#include <cmath>

namespace ces {
namespace {

Pose pose_of(const Bodies& bodies, int i) { return i < 0 ? Pose{} : bodies.pose[std::size_t(i)]; }

void perpendiculars(const Vec3& axis, Vec3& p1, Vec3& p2) {
  p1 = axis.unitOrthogonal();
  p2 = axis.cross(p1);
}

// The joint's current geometry in world coordinates.
struct Current {
  int a, b;            // solver indices, -1: ground
  Vec3 ra, rb;         // anchors relative to the centres of mass
  Vec3 separation;     // anchor_b - anchor_a
  Vec3 axis_a, axis_b;
  Vec3 rotation_error; // small rotation taking q_a q_rel0 onto q_b
};

Current current(const Joint& j, const JointFrame& f, const Bodies& bodies, int first_body) {
  const Pose pa = pose_of(bodies, j.body_a), pb = pose_of(bodies, j.body_b);
  Current c;
  c.a = j.body_a < 0 ? -1 : first_body + j.body_a;
  c.b = j.body_b < 0 ? -1 : first_body + j.body_b;
  c.ra = pa.orientation * f.anchor_a;
  c.rb = pb.orientation * f.anchor_b;
  c.separation = (pb.position + c.rb) - (pa.position + c.ra);
  c.axis_a = pa.orientation * f.axis_a;
  c.axis_b = pb.orientation * f.axis_b;
  Quat err = pb.orientation * (pa.orientation * f.relative0).conjugate();
  if (err.w() < 0) err.coeffs() = -err.coeffs();
  c.rotation_error = 2.0 * err.vec();
  return c;
}

// A row constraining the relative velocity of the anchors along `dir`
// (dir fixed in body A, so A's lever arm includes the separation).
BilateralRow linear_row(const Current& c, const Vec3& dir, double bias) {
  BilateralRow r;
  r.a = c.a;
  r.b = c.b;
  r.lin_a = -dir;
  r.ang_a = -(c.ra + c.separation).cross(dir);
  r.lin_b = dir;
  r.ang_b = c.rb.cross(dir);
  r.bias = bias;
  return r;
}

BilateralRow angular_row(const Current& c, const Vec3& dir, double bias) {
  BilateralRow r;
  r.a = c.a;
  r.b = c.b;
  r.ang_a = -dir;
  r.ang_b = dir;
  r.bias = bias;
  return r;
}

}  // namespace

std::vector<JointFrame> make_joint_frames(const Model& model, const Bodies& bodies) {
  std::vector<JointFrame> frames;
  for (const Joint& j : model.joints) {
    const Pose pa = pose_of(bodies, j.body_a), pb = pose_of(bodies, j.body_b);
    const Vec3 axis = j.axis.normalized();
    frames.push_back({pa.inverse_apply(j.point), pb.inverse_apply(j.point),
                      pa.orientation.conjugate() * axis, pb.orientation.conjugate() * axis,
                      pa.orientation.conjugate() * pb.orientation});
  }
  return frames;
}

namespace {

// Joint j's rows, at its current geometry c; returns its position error.
// Stabilization: each row removes its whole position error in one step.
double add_joint_rows(const Joint& j, const Current& c, double h, std::vector<BilateralRow>& rows) {
  Vec3 p1, p2;
  perpendiculars(c.axis_a, p1, p2);
  const Vec3 axes[] = {Vec3::UnitX(), Vec3::UnitY(), Vec3::UnitZ()};
  double drift = 0.0;
  if (j.type == JointType::Prismatic) {
    for (const Vec3& d : {p1, p2}) rows.push_back(linear_row(c, d, d.dot(c.separation) / h));
    drift = std::hypot(p1.dot(c.separation), p2.dot(c.separation));
  } else {
    for (const Vec3& d : axes) rows.push_back(linear_row(c, d, d.dot(c.separation) / h));
    drift = c.separation.norm();
  }
  if (j.type == JointType::Revolute) {
    for (const Vec3& d : {p1, p2})
      rows.push_back(angular_row(c, c.axis_b.cross(d), d.dot(c.axis_b) / h));
  } else {
    for (const Vec3& d : axes) rows.push_back(angular_row(c, d, d.dot(c.rotation_error) / h));
  }
  return drift;
}

// Motor m's row on its joint j, at the joint's current geometry c: a speed
// about or along the axis (for a position target, the speed that reaches
// it in one step, capped), with the force capped.
BilateralRow motor_row(const Motor& m, const Joint& j, const Current& c, double h) {
  BilateralRow r;
  if (j.type == JointType::Revolute) {
    r = angular_row(c, c.axis_a, -m.target);
  } else {
    double speed = m.target;
    if (m.mode == Motor::Mode::Position)
      speed = std::clamp((m.target - c.axis_a.dot(c.separation)) / h, -m.max_speed, m.max_speed);
    r = linear_row(c, c.axis_a, -speed);
  }
  r.lo = -m.max_force * h;
  r.hi = m.max_force * h;
  return r;
}

}  // namespace

double joint_rows(const Model& model, const std::vector<JointFrame>& frames, const Bodies& bodies,
                  int first_body, double h, std::vector<BilateralRow>& rows) {
  // A motor's joint's geometry is made again where the motor needs it: a
  // few products, where keeping every joint's would allocate each step.
  auto geometry = [&](std::size_t k) {
    return current(model.joints[k], frames[k], bodies, first_body);
  };
  double drift = 0.0;
  for (std::size_t k = 0; k < model.joints.size(); ++k)
    drift = std::max(drift, add_joint_rows(model.joints[k], geometry(k), h, rows));
  for (const Motor& m : model.motors) {
    const auto k = std::size_t(m.joint);
    rows.push_back(motor_row(m, model.joints[k], geometry(k), h));
  }
  return drift;
}

}  // namespace ces
