// Joints and motors as bilateral rows of the step's CCP.
#pragma once
#include <vector>

#include "dynamics/ccp.hpp"
#include "model/model.hpp"
#include "model/state.hpp"

namespace ces {

// A joint's anchor and axis in each body's frame, fixed at t = 0.
struct JointFrame {
  Vec3 anchor_a, anchor_b;
  Vec3 axis_a, axis_b;
  Quat relative0;  // q_a^-1 q_b at t = 0 (orientation the joint locks)
};

std::vector<JointFrame> make_joint_frames(const Model& model, const Bodies& bodies);

// Appends the rows of every joint and motor. Machine body i is solver body
// `first_body + i`. Returns the largest position error of the joints (m).
double joint_rows(const Model& model, const std::vector<JointFrame>& frames,
                  const Bodies& bodies, int first_body, double h,
                  std::vector<BilateralRow>& rows);

}  // namespace ces
