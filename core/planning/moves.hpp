// The thesis's basic moves (6.2.2): a joint-interpolated move (6.2.2.1) and a Cartesian
// straight-line move (6.2.2.2, Eqs. 6.1 and 6.2), each rest to rest on one speed profile
// (speed_profile.hpp) and sampled at the cycle rate like a motion along a path (motion.hpp).
//
// Plans are values; samplers are workspaces (no heap allocation per sample) that write a
// MoveSample, the tool's full state in the world frame W and, for a joint move, the joints.
// Units: SI (m, rad, s); joint values [rad] (revolute) or [m] (prismatic).
//
// Timing: both moves put a rest-to-rest profile on a progress coordinate and follow it
// exactly (analytic velocities and accelerations, no finite differences):
//  - with MotionSpec::duration_s = D > 0, the ramp-fraction profile (TRAPEZOIDAL: Eqs.
//    6.11-6.13; S_CURVE: the same ramps with a triangular acceleration) over T = D /
//    speedScale;
//  - with D = 0, the minimum-time profile (trapezoid or double S) under the limits, each
//    scaled by speedScale (v s, a s^2, j s^3), as plan_motion does.
// Samples are at t_k = k / cycleRateHz plus one at exactly t = T when the grid does not land
// on it; when it lands (to 1e-9 of a period) the last grid sample is taken at exactly T
// (MotionPlan::sample_count's rule). The first sample is the start at rest, the last the
// goal at rest, exactly.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/speed_profile.hpp"
#include "core/planning/joint_reference.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// One sample of a move: the tool's state in W and, for a joint move, the joints.
struct MoveSample {
  double t = 0.0;  ///< time [s]
  /// Progress in [0, 1]: the joint move's x (6.2.2.1); the linear move's s / L, or the
  /// rotated fraction of the angle for a pure rotation.
  double u = 0.0;
  /// Distance travelled along the straight line [m] (linear move); 0 for a joint move.
  double s = 0.0;
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();  ///< tool origin p_WT [m]
  Eigen::Vector3d v_W = Eigen::Vector3d::Zero();  ///< its velocity [m/s]
  Eigen::Vector3d a_W = Eigen::Vector3d::Zero();  ///< its acceleration [m/s^2]
  double speed = 0.0;                             ///< |v_W| [m/s]
  /// Tool orientation R_WT (unit). A sampler keeps successive samples in one hemisphere
  /// (q and -q are one rotation), so the stream of quaternions is continuous.
  Eigen::Quaterniond q_WT = Eigen::Quaterniond::Identity();
  Eigen::Vector3d omega_W = Eigen::Vector3d::Zero();  ///< tool angular velocity [rad/s]
  Eigen::Vector3d alpha_W = Eigen::Vector3d::Zero();  ///< tool angular acceleration [rad/s^2]
  JointVector q;       ///< joints [rad or m] (joint move; empty otherwise)
  JointVector q_dot;   ///< [rad/s or m/s]
  JointVector q_ddot;  ///< [rad/s^2 or m/s^2]
  /// Yoshikawa's manipulability sqrt(det(J J^T)) at q (joint move; 0 otherwise).
  double manipulability = 0.0;
  bool has_joints = false;  ///< q, q_dot, q_ddot and manipulability are set
};

// ---------------------------------------------------------------------------------------
// Joint-interpolated move (thesis 6.2.2.1)

/// A joint move (proto JointMove; field paths `jointMove.start[i]`, `jointMove.goal[i]`).
/// Plain vectors so that a wrong size is reported, not truncated.
struct JointMoveSpec {
  std::vector<double> start;  ///< q0 [rad or m], one per joint
  std::vector<double> goal;   ///< q1 [rad or m], one per joint
};

/// A timed joint move: every joint on the straight line of joint space,
///   q(t) = q0 + x(t) (q1 - q0),  q_dot = x_dot (q1 - q0),  q_ddot = x_ddot (q1 - q0),
/// with x(t) from 0 to 1 on `profile` (a SpeedProfile over the dimensionless length 1:
/// its s is x, its v is x_dot [1/s], its a is x_ddot [1/s^2]).
/// The plan holds the robot it was planned for (shared and immutable): it stands alone,
/// whatever becomes of the caller's copy.
struct JointMovePlan {
  ValidRobot model;
  MotionSpec spec;  ///< as given
  JointVector q0;   ///< start [rad or m]
  JointVector q1;   ///< goal [rad or m]
  SpeedProfile profile;  ///< x(t) over [0, duration_s]
  double duration_s = 0.0;
  std::size_t sample_count = 0;
  /// Minimum-time plans: the slowest joint, whose own minimum-time move (under its own
  /// limits, scaled by speedScale) takes longest; 0 with a duration or when nothing moves.
  std::size_t limiting_joint = 0;
  /// Largest |q_dot_i| / maxVelocity_i and |q_ddot_i| / maxAcceleration_i over the joints
  /// and the move (exact: from the profile's peaks). A minimum-time plan keeps them within
  /// speedScale and speedScale^2, and one of them (or the jerk's) reaches its bound; with a
  /// duration they may exceed 1 (the time is honoured as given).
  double velocity_usage = 0.0;
  double acceleration_usage = 0.0;
};

/// Plans the joint move from spec.start to spec.goal (thesis 6.2.2.1).
///  - With motion.duration_s > 0: the profile of motion.profile (rampFraction) over
///    T = durationS / speedScale. The joint limits are not used (as for a path); the plan's
///    velocity_usage and acceleration_usage say how close they come.
///  - With durationS = 0: the fastest synchronised move. Each joint's own minimum-time
///    profile would be the one of x under maxVelocity_i / |dq_i| and maxAcceleration_i /
///    |dq_i|; the move takes the tightest of these normalised limits,
///      x_dot <= min_i vmax_i / |dq_i|,  x_ddot <= min_i amax_i / |dq_i|,
///      x_dddot <= min_i jmax_i / |dq_i|  (S_CURVE, over the joints that have a maxJerk),
///    (times speedScale, speedScale^2, speedScale^3). Every joint stays within its limits
///    and at least one reaches one of them. When one joint is the tightest in every limit,
///    it moves on its own minimum-time profile and the others are scaled to finish with it,
///    as the thesis says. Deviation: when different joints bind the speed and the
///    acceleration, the move is slightly slower than the slowest joint's own minimum time,
///    because scaling that joint's profile onto the others would break their limits.
///    S_CURVE: the double S when some moving joint has a maxJerk; when none has, the
///    fastest rampFraction S-curve within the speed and acceleration bounds.
///    The MotionSpec's Cartesian limits (maxSpeed, ...) are not used by a joint move.
///  - Nothing moves (q0 == q1) in minimum time: one sample at rest, duration 0.
/// The model was checked where it entered (ValidRobot): nothing of it is checked here.
/// Errors (all collected): `jointMove.start` / `jointMove.goal` with the wrong number of
/// values, `jointMove.start[i]` / `jointMove.goal[i]` not finite or outside joint i's
/// position limits, the MotionSpec's own fields (validate_motion; the Cartesian maxSpeed and
/// maxAcceleration are not needed),
/// and `motion.durationS` when the move would have more than kMaxMotionSamples samples or
/// its speeds overflow.
Expected<JointMovePlan> plan_joint_move(const ValidRobot& robot, const JointMoveSpec& spec,
                                        const MotionSpec& motion);

/// The joint move at time t [s]: q, q_dot, q_ddot; the tool pose X_WT = FK(q)
/// (kinematics.hpp); [v; omega] = J q_dot (1.8); [a; alpha] = J q_ddot + J_dot q_dot
/// (1.10, 1.11). q lies between q0 and q1 joint by joint (so within the limits). At rest at
/// q0 for t < 0; at t = 0, q0 with the first piece's one-sided acceleration (as
/// MotionSampler's first sample); from t = duration on, q1 exactly, at rest. `cursor` makes
/// a non-decreasing sequence of times O(1) each. No heap allocation.
void joint_move_at(const JointMovePlan& plan, double t, ProfileCursor& cursor, MoveSample& out);
void joint_move_at(const JointMovePlan& plan, double t, MoveSample& out);

/// The tool's state in W of the joints out.q, out.q_dot, out.q_ddot (sizes: the model's):
/// X_WT = FK(q) (kinematics.hpp), [v; omega] = J q_dot (1.8), [a; alpha] = J q_ddot +
/// J_dot q_dot (1.10, 1.11), speed, manipulability; has_joints set. t, u and s untouched.
/// No heap allocation.
void joint_tool_state(const RobotModel& model, MoveSample& out);

// ---------------------------------------------------------------------------------------
// Cartesian straight-line move (thesis 6.2.2.2)

/// A tool pose in W (proto Pose).
struct ToolPose {
  Eigen::Vector3d p_WT = Eigen::Vector3d::Zero();            ///< (position) tool origin [m]
  Eigen::Quaterniond q_WT = Eigen::Quaterniond::Identity();  ///< (orientation) R_WT, unit
};

/// A straight-line move (proto LinearMove; field paths `linearMove.start.position`,
/// `linearMove.start.orientation`, `linearMove.goal.position`, `linearMove.goal.orientation`).
struct LinearMoveSpec {
  ToolPose start;  ///< X0
  ToolPose goal;   ///< X1
};

/// A timed straight-line move. With d = p1 - p0, L = |d| and d_hat = d / L:
///   p(t) = p0 + s(t) d_hat  (6.1),  v = s_dot d_hat,  a = s_ddot d_hat,
/// and the tool turns by SLERP (6.2) on the same progress sigma = s / L, written as a
/// rotation about the fixed world axis a_W by the angle theta in [0, pi] of q1 q0^-1 (the
/// shorter way round):
///   q(sigma) = exp(sigma theta a_W / 2) q0,  omega = a_W theta sigma_dot,
///   alpha = a_W theta sigma_ddot,
/// so the angular speed follows the speed profile. A pure rotation (L = 0) runs the
/// profile over the angle: sigma = phi / theta.
struct LinearMovePlan {
  MotionSpec spec;  ///< as given
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();  ///< start position [m]
  Eigen::Vector3d p1 = Eigen::Vector3d::Zero();  ///< goal position [m]
  Eigen::Quaterniond q0 = Eigen::Quaterniond::Identity();  ///< start orientation (normalised)
  /// Goal orientation (normalised), negated when needed to lie in q0's hemisphere: the
  /// same rotation as the spec's goal, reached continuously.
  Eigen::Quaterniond q1 = Eigen::Quaterniond::Identity();
  Eigen::Vector3d direction_W = Eigen::Vector3d::Zero();  ///< d_hat (zero when L = 0)
  double length = 0.0;                                     ///< L [m]
  Eigen::Vector3d axis_W = Eigen::Vector3d::Zero();  ///< a_W, unit (zero when theta = 0)
  double theta = 0.0;                                ///< [rad], in [0, pi]
  /// The profile's distance: s over L [m] when L > 0, else the angle [rad] over theta
  /// (the SpeedProfile's units are then rad, rad/s, rad/s^2).
  SpeedProfile profile;
  double duration_s = 0.0;
  std::size_t sample_count = 0;
  double peak_speed = 0.0;                  ///< largest tool speed [m/s]
  double peak_acceleration = 0.0;           ///< largest |tool acceleration| [m/s^2]
  double peak_angular_speed = 0.0;          ///< largest |omega| [rad/s]
  double peak_angular_acceleration = 0.0;   ///< largest |alpha| [rad/s^2]
  /// With a redundant robot: the joints chosen ahead for the whole line (optim/redundancy),
  /// which the samplers' tracker follows (JointTracker::set_reference); null: sample by sample.
  std::shared_ptr<const JointReference> joints = nullptr;
  /// With a robot whose tool's roll is free (RobotSpec.toolAxisFree): the roll phi(t) [rad]
  /// about the tool's z axis chosen ahead, applied to every sample's tool state (trajectory.hpp's
  /// samplers); null: the orientation as planned.
  std::shared_ptr<const JointReference> roll = nullptr;
};

/// The factor f >= 1 by which a joint move's time must stretch for every joint torque to keep
/// within maxTorque (with the model's payload, under standard gravity: dynamics.hpp). Along
/// the move q = q0 + x (q1 - q0), the torque is tau = M(q) dq x_ddot + C(q, dq) dq x_dot^2 +
/// g(q): a uniform stretch (speedScale / f: the time f times longer) divides the part beyond
/// gravity's by f^2, so each joint at each instant asks for f^2 >= (tau - g) / (+-maxTorque -
/// g). Measured on the profile at `rate_hz` (and at each piece's start), two
/// inverse-dynamics calls per instant. 1 without torque limits (torque_limited); +infinity
/// where gravity alone needs more than a joint's maxTorque somewhere on the move.
double torque_stretch(const JointMovePlan& plan, double rate_hz);

/// Plans the straight-line move from spec.start to spec.goal (thesis 6.2.2.2).
///  - With motion.duration_s > 0: the rampFraction profile over T = durationS / speedScale,
///    over L (or over theta for a pure rotation; a move that neither translates nor turns
///    rests for T).
///  - With durationS = 0: the minimum-time trapezoid or double S over L under maxSpeed,
///    maxAcceleration (and maxJerk), each scaled by speedScale; the rotation follows on the
///    same progress, its rate not bounded by these (Cartesian, linear) limits.
/// Errors (all collected): `linearMove.start.position` / `linearMove.goal.position` not
/// finite or beyond 1e6 m of the origin; `linearMove.start.orientation` /
/// `linearMove.goal.orientation` not finite or not a unit quaternion (|q| within 1e-3 of 1;
/// then it is normalised); validate_motion's; `motion.durationS` for a pure rotation
/// without a duration (the limits bound the translation only), too many samples
/// (kMaxMotionSamples) or speeds that overflow.
Expected<LinearMovePlan> plan_linear_move(const LinearMoveSpec& spec, const MotionSpec& motion);

/// The straight-line move at time t [s]: X0 at t <= 0 (at rest before 0; at 0 with the
/// first piece's one-sided acceleration) and exactly (p1, q1) at rest from t = duration
/// on. has_joints is false. No heap allocation.
void linear_move_at(const LinearMovePlan& plan, double t, ProfileCursor& cursor, MoveSample& out);
void linear_move_at(const LinearMovePlan& plan, double t, MoveSample& out);

// ---------------------------------------------------------------------------------------
// Sampling either move at the cycle rate

/// Streams the samples of a move at the cycle rate (a workspace: no heap allocation per
/// sample): sample k at the grid's time k, the profile's cursor carried from one sample to the
/// next, the tool's quaternion kept in the previous sample's hemisphere (q and -q are one
/// rotation). `plan` must outlive the sampler.
template <class MovePlan>
class MoveSampler {
 public:
  explicit MoveSampler(const MovePlan& plan);
  /// Writes the next sample and returns true, or returns false after the last one.
  bool next(MoveSample& sample);
  /// Writes the sample at time t [s], off the grid (live execution); times must not
  /// decrease from one call to the next; t is clamped to [0, duration].
  void at(double t, MoveSample& sample);
  /// Starts again from t = 0.
  void reset();
  /// Index of the next sample.
  std::size_t index() const { return k_; }

 private:
  const MovePlan* plan_;
  ProfileCursor cursor_;
  Eigen::Quaterniond q_prev_ = Eigen::Quaterniond::Identity();
  std::size_t k_ = 0;
};

using JointMoveSampler = MoveSampler<JointMovePlan>;
using LinearMoveSampler = MoveSampler<LinearMovePlan>;
extern template class MoveSampler<JointMovePlan>;
extern template class MoveSampler<LinearMovePlan>;

}  // namespace geotraj::core
