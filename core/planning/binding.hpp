// Which limit sets the pace of a motion, stretch by stretch: one type for the time-optimal
// timing (the limit that binds on each grid interval, time_optimal.hpp) and for the
// joint-space report of any motion (the most used joint limit at each sample,
// joint_motion.hpp), as the API's BindingStretch is one message.
#pragma once

#include <cstddef>

namespace geotraj::core {

/// Which limit a stretch is about.
enum class BindingKind {
  kJointVelocity,            ///< |q_dot_j| <= maxVelocity [rad/s or m/s]
  kJointAcceleration,        ///< |q_ddot_j| <= maxAcceleration [rad/s^2 or m/s^2]
  kJointJerk,                ///< |q_dddot_j| <= maxJerk [rad/s^3 or m/s^3] (on samples: by differences)
  kCartesianSpeed,           ///< s_dot <= maxSpeed [m/s]
  kTangentialAcceleration,   ///< |s_ddot| <= maxAcceleration [m/s^2]
  kCentripetalAcceleration,  ///< kappa s_dot^2 <= maxAcceleration [m/s^2]
  kAngularSpeed,             ///< |omega| <= maxAngularSpeed [rad/s]
  kAngularAcceleration,      ///< |alpha| <= maxAngularAcceleration [rad/s^2]
  kJointTorque,              ///< |tau_j| <= maxTorque [N m or N] (dynamics.hpp)
};

/// The name of a kind ("joint velocity", ...).
constexpr const char* name(BindingKind kind) {
  switch (kind) {
    case BindingKind::kJointVelocity: return "joint velocity";
    case BindingKind::kJointAcceleration: return "joint acceleration";
    case BindingKind::kJointJerk: return "joint jerk";
    case BindingKind::kCartesianSpeed: return "Cartesian speed";
    case BindingKind::kTangentialAcceleration: return "tangential acceleration";
    case BindingKind::kCentripetalAcceleration: return "centripetal acceleration";
    case BindingKind::kAngularSpeed: return "angular speed";
    case BindingKind::kAngularAcceleration: return "angular acceleration";
    case BindingKind::kJointTorque: return "joint torque";
  }
  return "limit";
}

constexpr bool is_joint_kind(BindingKind kind) {
  return kind == BindingKind::kJointVelocity || kind == BindingKind::kJointAcceleration ||
         kind == BindingKind::kJointJerk || kind == BindingKind::kJointTorque;
}

/// A path's or a line's Cartesian limits as the request gives them (MotionSpec's maxSpeed
/// [m/s], maxAcceleration [m/s^2] on the tangential and the centripetal part each,
/// maxAngularSpeed [rad/s], maxAngularAcceleration [rad/s^2]); 0: not limited.
struct CartesianLimits {
  double speed = 0.0;
  double acceleration = 0.0;
  double angular_speed = 0.0;
  double angular_acceleration = 0.0;
  bool any() const { return speed > 0.0 || acceleration > 0.0 || angular_speed > 0.0 || angular_acceleration > 0.0; }
};

/// A stretch of the motion over which one limit sets the pace.
struct BindingStretch {
  BindingKind kind = BindingKind::kCartesianSpeed;
  std::size_t joint = 0;    ///< zero-based joint (joint kinds only)
  double t_start = 0.0;     ///< [s] from the motion's start
  double t_end = 0.0;
  double s_start = 0.0;     ///< arc length from the path's start [m] (0 for joint moves)
  double s_end = 0.0;
  double usage = 0.0;       ///< value / limit (1: at the limit)
  double value = 0.0;       ///< the constraint's largest value on the stretch (|q_dot|, s_dot, ...)
  double limit = 0.0;       ///< the limit it is compared with
  /// Where the stretch lies besides t and s: the portion of MotionPlan::portions (timing),
  /// the first and last sample (joint-space report; consecutive stretches share one).
  std::size_t portion = 0;
  std::size_t sample_start = 0, sample_end = 0;
};

}  // namespace geotraj::core
