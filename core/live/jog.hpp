// Jogging (teleoperation): the robot driven live by velocity commands, joint by joint or by a
// Cartesian twist of the tool in the world or the tool frame, each command a fraction in
// [-1, 1] of the maximum speed; one controller cycle at a time, within every joint's
// velocity, acceleration, jerk and position limits.
//
// Each cycle (period h = 1 / cycle_rate_hz):
//  1. Target joint velocities q_dot*.
//     Joint jog:     q_dot*_j = c_j v_max_j s                 (c_j the command, s velocity_scale)
//     Cartesian jog: xi = (c_v v_lin; c_w w_ang) in W, or (R_WT c_v v_lin; R_WT c_w w_ang) in
//                    the tool frame (R_WT of the current pose: the axes turn with the tool);
//                    damped least squares (Nakamura & Hanafusa 1986; Chiaverini 1997), with
//                    J the 6 x n geometric Jacobian in W (kinematics.hpp, Eq. 1.9) at the
//                    current q and its thin SVD J = U S V^T,
//                      q_dot* = J^T (J J^T + lambda^2 I)^-1 xi' = sum_i v_i s_i / (s_i^2 + lambda^2) u_i^T xi'
//                      lambda^2 = (1 - (sigma_min / eps)^2) lambda_max^2 when sigma_min < eps, else 0,
//                    then scaled down uniformly (the direction kept) when some |q_dot*_j|
//                    exceeds v_max_j s.
//                    Deviation: xi' = xi - h J_dot q_dot (Eqs. 1.10-1.11), not xi: the target
//                    is reached at the cycle's end, where the Jacobian is J + h J_dot + O(h^2),
//                    so the twist achieved there is xi + O(h^2) (with xi: xi + O(h), 2e-3 of
//                    it on the PA-10 at 100 Hz).
//  2. Each joint's velocity tracks its target by a jerk-limited rate change
//     (rate_profile.hpp): RateProfile::plan(q_dot, q_ddot, q_dot*, a_max, j_max), replanned
//     every cycle and integrated exactly over h (its x is the position change). So
//     |q_dot| <= v_max s, |q_ddot| <= a_max and |q_dddot| <= j_max at every instant
//     (j_max = max_jerk, or a_max / jerk_ramp_s for a joint without one).
//  3. Position limits (not for continuous joints). If following the profile for this cycle
//     and then braking (RateProfile::plan(q_dot, q_ddot, 0, a_max, j_max)) would carry the
//     joint past a limit, the joint starts braking within this cycle at the latest moment
//     x in [0, h] (bisection) at which braking stops it at or before the limit: it comes to
//     rest at the limit. From then on its target toward that limit is 0 (it may move away).
//     q is clamped into [min, max] against rounding.
//
// One forward kinematics (pose, Jacobian) and one SVD per cycle, at the cycle's end: they give
// the sample's pose, twist and sigma_min and the next cycle's Cartesian target.
//
// Limitations (of tracking each joint's target by its own rate profile):
//  - each joint ramps in its own least time, so while a Cartesian jog's joint velocities
//    change (its start, a new command, a stop) the tool leaves the commanded line a little
//    (a 0.125 m/s jog along x from home: 1.1 mm sideways on the PA-10, 0.06 mm on the UR5);
//    once they reach their targets it follows the twist (to 2e-4 of it on both at 100 Hz
//    and 1 kHz);
//  - a target that keeps changing at a rate c is followed with a lag of c |c| / (2 j_max) in
//    velocity (the profile plans to rest at the target): small while jogging slowly, about
//    1e-2 of the twist when a twist beyond the joints' speeds is scaled down (the scale then
//    changes quickly as the arm moves);
//  - while a joint is held at a position limit, a Cartesian jog moves the other joints as
//    commanded (the tool leaves the commanded direction; nothing redistributes the held
//    joint's share).
#pragma once

#include <array>
#include <bitset>
#include <cstddef>
#include <memory>
#include <optional>
#include <string_view>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The frame a Cartesian jog's twist is given in.
enum class JogFrame {
  kWorld,  ///< W
  kTool,   ///< T: the axes of the current tool frame, turning with it (the origin is the tool's)
};

/// What the operator commands: one joint fraction per joint, or a twist of the tool. Neither
/// (both empty) commands every target to 0, like Jogger::stop().
struct JogCommand {
  /// Joint jogging: one value per joint in [-1, 1], the fraction of the joint's max_velocity
  /// (times JogOptions::velocity_scale). Empty for a Cartesian jog.
  JointVector joints;
  /// Cartesian jogging: (vx, vy, vz, wx, wy, wz), each in [-1, 1], fractions of
  /// max_linear_speed [m/s] and max_angular_speed [rad/s], in `frame`. The linear part is
  /// the velocity of the tool's origin.
  std::optional<Vector6d> twist;
  JogFrame frame = JogFrame::kWorld;
};

/// How a jog runs (fixed for one Jogger). Proto JSON names in validate_jog_options.
struct JogOptions {
  double cycle_rate_hz = 100.0;     ///< (0, 1e5] [Hz]; the period is h = 1 / cycle_rate_hz
  double velocity_scale = 1.0;      ///< (0, 1]: what command 1 means as a fraction of each joint's max_velocity
  double max_linear_speed = 0.25;   ///< > 0 [m/s]: Cartesian command 1
  double max_angular_speed = 0.5;   ///< > 0 [rad/s]: Cartesian command 1
  double damping = 0.05;            ///< lambda_max >= 0 of damped least squares [m or rad, as J]
  /// eps > 0: sigma_min of J below which the damping starts (Chiaverini 1997; Nakamura &
  /// Hanafusa 1986): lambda^2 = (1 - (sigma_min / eps)^2) lambda_max^2.
  double singular_threshold = 0.04;
  /// > 0 [s]: for a joint without max_jerk, the jerk bound is max_acceleration / jerk_ramp_s
  /// (the acceleration ramps from 0 to its limit in this time).
  double jerk_ramp_s = 0.05;
};

/// One set point.
struct JogSample {
  double t = 0.0;                  ///< [s] from the start (cycle k at k / cycle_rate_hz)
  JointVector q;                   ///< [rad or m]
  JointVector q_dot;               ///< [rad/s or m/s]
  JointVector q_ddot;              ///< [rad/s^2 or m/s^2]
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();  ///< tool pose at q (base and tool included)
  Vector6d twist_W = Vector6d::Zero();  ///< achieved (v [m/s]; omega [rad/s]) of the tool in W: J(q) q_dot
  /// lambda [m or rad, as J] of this cycle's damped least squares: from the sigma_min at
  /// the cycle's start (the previous sample's). 0 far from singular and for joint jogging.
  double damping = 0.0;
  double sigma_min = 0.0;          ///< smallest singular value of J(q) at this sample's q
  /// Bit j: joint j is braking for, or held at, a position limit (its target toward the
  /// limit is 0). Cleared once neither its command nor its velocity points at the limit.
  std::bitset<kMaxJoints> limited;
  bool at_rest = false;            ///< every q_dot and q_ddot is exactly 0
};

/// One live jog (see the file comment): one per call, stepping one cycle at a time, with
/// no heap allocation after construction (the kinematics workspace is allocated once).
class Jogger {
 public:
  /// `model` valid (validate_robot) and outliving the jogger; q0 of model.dof() values within
  /// the position limits; `options` valid (validate_jog_options) and valid with the model
  /// (validate_jog_limits: the bounds it derives per joint). Checked (GEOTRAJ_CHECK): the
  /// caller's programmer errors (a request is refused by those validations first). Starts at
  /// rest with every target 0.
  Jogger(const RobotModel& model, JointVector q0, JogOptions options);
  ~Jogger();
  Jogger(Jogger&&) noexcept;
  Jogger& operator=(Jogger&&) noexcept;

  /// The new target (replaces the previous one), effective from the next cycle. Checked: a
  /// valid command (validate_jog_command with this model's dof).
  void command(const JogCommand& c);
  /// Every target 0 (deadman released, stop, drain): each joint brakes to rest.
  void stop();
  /// Advances one cycle (h = 1 / cycle_rate_hz) and writes its set point.
  void next(JogSample& out);
  /// Every joint's velocity and acceleration is exactly 0 (after the last next()).
  bool at_rest() const;

  /// The time [s] a stop from the current state takes: the longest of the joints' braking
  /// profiles, RateProfile::plan(q_dot_j, q_ddot_j, 0, a_max_j, j_max_j).duration().
  double stopping_time() const;
  /// The joint's jerk bound [rad/s^3 or m/s^3]: max_jerk, or max_acceleration / jerk_ramp_s.
  double jerk_bound(std::size_t joint) const { return j_max_[static_cast<Eigen::Index>(joint)]; }
  /// The joint's velocity bound [rad/s or m/s]: max_velocity times velocity_scale.
  double velocity_bound(std::size_t joint) const { return v_max_[static_cast<Eigen::Index>(joint)]; }
  const JogOptions& options() const { return options_; }
  double period() const { return h_; }
  const JointVector& q() const { return q_; }
  const JointVector& q_dot() const { return v_; }
  const JointVector& q_ddot() const { return a_; }

 private:
  struct Kinematics;  // the chain and its workspace (jog.cpp)

  void compute_targets();
  void step_joint(Eigen::Index j);
  void update_kinematics();

  JogOptions options_;
  double h_;
  Eigen::Index n_;
  std::size_t cycles_ = 0;
  JogCommand command_;
  JointVector q_, v_, a_, target_;
  JointVector v_max_, a_max_, j_max_;
  JointVector q_min_, q_max_;
  std::bitset<kMaxJoints> bounded_;        ///< has position limits (not continuous)
  std::array<int, kMaxJoints> limited_{};  ///< +1: braking for or at max, -1: min, 0: free
  std::unique_ptr<Kinematics> kin_;        ///< at q_ (the last sample's)
  double sigma_min_ = 0.0;
  double lambda_ = 0.0;
};

/// Every problem with a jog command for a robot of `dof` joints, the field paths under `field`
/// (e.g. "jog"): `jog` (both joints and twist given), `jog.joints` (not one per joint),
/// `jog.joints[2]` (not finite or outside [-1, 1]), `jog.twist[3]` (index into (vx, vy, vz,
/// wx, wy, wz): not finite or outside [-1, 1]). Each names the value and the rule.
Violations validate_jog_command(const JogCommand& command, std::size_t dof, std::string_view field);

/// Every problem with jog options, the field paths under `field` (e.g. "jog.options"):
/// `cycleRateHz` in (0, 1e5], `velocityScale` in (0, 1], `maxLinearSpeed`, `maxAngularSpeed`,
/// `singularThreshold` and `jerkRampS` finite and > 0, `damping` finite and >= 0.
Violations validate_jog_options(const JogOptions& options, std::string_view field);

/// Every problem with jogging `model` (valid) with `options` (valid): the bounds the jogger
/// derives per joint must stay usable, `velocityScale` (maxVelocity times it at least
/// kMinJointLimit: a scale of 5e-324 gives 0) and `jerkRampS` (maxAcceleration over it, for a
/// joint without maxJerk, finite and at most kMaxJointLimit / kMinJointLimit). The first joint
/// that breaks each is named, with the value and the bound.
Violations validate_jog_limits(const RobotModel& model, const JogOptions& options, std::string_view field);

}  // namespace geotraj::core
