// Joints chosen for a whole motion ahead of the samples (optim/redundancy's optimum): a
// redundant arm's tracker follows them instead of choosing its self-motion sample by sample
// (joint_motion.hpp). The joints q_k at t_k = k dt [s], k = 0 .. K, interpolated joint by
// joint by the C2 cubic spline through them with zero velocity at both ends (the motion
// rests there): q(t), q_dot(t), q_ddot(t) for any t in [0, K dt] (clamped). Units: rad or m.
#pragma once

#include <vector>

#include "core/robot/robot.hpp"

namespace geotraj::core {

class JointReference {
 public:
  /// The spline through `q` (at least 2 samples, all of one size) at steps of dt > 0 [s].
  /// Precondition (checked).
  JointReference(std::vector<JointVector> q, double dt);

  /// The joints, their velocities and accelerations at t [s] (no heap allocation when the
  /// outputs already have the joints' size).
  void at(double t, JointVector& q, JointVector& q_dot, JointVector& q_ddot) const;
  double duration() const { return dt_ * static_cast<double>(q_.size() - 1); }
  double dt() const { return dt_; }
  const std::vector<JointVector>& samples() const { return q_; }
  /// The second derivatives at the samples [rad/s^2 or m/s^2]: q_ddot is linear between
  /// them (its extremes are there), q_dddot constant (m_{k+1} - m_k) / dt.
  const std::vector<JointVector>& second_derivatives() const { return m_; }

 private:
  std::vector<JointVector> q_;
  std::vector<JointVector> m_;  // second derivatives at the samples
  double dt_;
};

}  // namespace geotraj::core
