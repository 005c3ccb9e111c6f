// Joints chosen for a whole motion ahead of the samples (optim/redundancy's optimum): a
// redundant arm's tracker follows them instead of choosing its self-motion sample by sample
// (joint_motion.hpp). The joints q_k at x_k = k h, k = 0 .. K, interpolated joint by joint by
// the C2 cubic spline through them, the parameter x either
//   - the time t [s] (h = dt): zero velocity at both ends (the motion rests there); q(t),
//     q_dot(t), q_ddot(t) for any t in [0, K dt] (clamped), or
//   - the arc length s [m] from the path's start (h = L / K): natural ends (q'' = 0); q(s),
//     q_s(s), q_ss(s), so that along any timing of the path q_dot = q_s s_dot and
//     q_ddot = q_ss s_dot^2 + q_s s_ddot: the timings (time_optimal.hpp) see the joints the
//     samples will follow, as the path's tool roll (RollProfile, orientation.hpp).
// Units: rad or m.
#pragma once

#include <vector>

#include "core/robot/robot.hpp"

namespace geotraj::core {

/// What a JointReference's samples are spaced in.
enum class ReferenceParameter { kTime, kArcLength };

class JointReference {
 public:
  /// The spline through `q` (at least 2 samples, all of one size) at steps of h > 0 (dt [s]
  /// or L / K [m]). Precondition (checked).
  JointReference(std::vector<JointVector> q, double h, ReferenceParameter over = ReferenceParameter::kTime);

  /// The joints and their first and second derivatives by the parameter at x (t [s] or s
  /// [m]; no heap allocation when the outputs already have the joints' size).
  void at(double x, JointVector& q, JointVector& q_dot, JointVector& q_ddot) const;
  /// The parameter's range: the duration [s] or the path's length [m].
  double duration() const { return dt_ * static_cast<double>(q_.size() - 1); }
  double dt() const { return dt_; }
  ReferenceParameter over() const { return over_; }
  const std::vector<JointVector>& samples() const { return q_; }
  /// The second derivatives at the samples [rad/s^2 or m/s^2]: q_ddot is linear between
  /// them (its extremes are there), q_dddot constant (m_{k+1} - m_k) / dt.
  const std::vector<JointVector>& second_derivatives() const { return m_; }

 private:
  std::vector<JointVector> q_;
  std::vector<JointVector> m_;  // second derivatives at the samples
  double dt_;
  ReferenceParameter over_;
};

}  // namespace geotraj::core
