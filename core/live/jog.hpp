// Jogging (teleoperation): the robot driven live by velocity commands, joint by joint or by a
// Cartesian twist of the tool in the world or the tool frame, each command a fraction in
// [-1, 1] of the maximum speed; one controller cycle at a time, within every joint's
// velocity, acceleration, jerk and position limits.
//
// Each cycle (period h = 1 / cycle_rate_hz):
//  1. Direction D: the joint velocities of the active command (the last one that moves; a
//     release keeps it) at full command, at the current q.
//     Joint jog:     D_j = c_j v_max_j s                      (c_j the command, s velocity_scale)
//     Cartesian jog: xi = (c_v v_lin; c_w w_ang) in W, or (R_WT c_v v_lin; R_WT c_w w_ang) in
//                    the tool frame (R_WT of the current pose: the axes turn with the tool);
//                    damped least squares (Nakamura & Hanafusa 1986; Chiaverini 1997), with
//                    J the 6 x n geometric Jacobian in W (kinematics.hpp, Eq. 1.9) at the
//                    current q and its thin SVD J = U S V^T,
//                      D = J^T (J J^T + lambda^2 I)^-1 xi = sum_i v_i s_i / (s_i^2 + lambda^2) u_i^T xi
//                      lambda^2 = (1 - (sigma_min / eps)^2) lambda_max^2 when sigma_min < eps, else 0,
//                    then scaled down uniformly (the direction kept) when some |D_j| exceeds
//                    v_max_j s.
//  2. One ramp for the whole command: the fraction s [1] of it applied (0 at rest, 1 at the
//     command) moves to its goal (1 while commanded; 0 after a release or stop, and while
//     the command pushes a joint at a position limit) by a jerk-limited rate change
//     (rate_profile.hpp), RateProfile::plan(s, ds/dt, goal, A_s, J_s), replanned every cycle.
//     Every joint's reference is s D: the joints speed up and slow down together, the ratios
//     of the joint command are kept, and a Cartesian jog's twist is s xi, on its line, at the
//     start, a release, a stop and the approach to a position limit. A command along the
//     same line (c = r c_last, the same frame) rescales s (s / r) so that the motion ramps
//     along the line (through rest when r < 0); another direction moves the reference to
//     s D of the new command. A_s and J_s are the largest that keep s D within every joint's
//     acceleration and jerk limits: A_s = min_j a_max_j / |D_j|, J_s = min_j j_max_j / |D_j|
//     for a joint jog. A Cartesian jog's D changes along its path (sigma = int s dt [s]) at
//     D_sigma = dD/dsigma, estimated from D's change over the last cycle: d(s D)/dt =
//     ds/dt D + s^2 D_sigma. Its drift g = s^2 D_sigma (and its rate g_dot = 2 s ds/dt
//     D_sigma) is fed forward, the reference s D + g t + g_dot t^2 / 2 reaching s D(q + h
//     q_dot) at the cycle's end to O(h^2), where its twist is s xi; A_s and J_s take 0.8 of
//     what the drift leaves of each joint's limits at the command's speed (jog.cpp,
//     ramp_limits). Slowing to rest, J_s is at least ds/dt^2 / (2 |s|): s comes to rest on 0,
//     never reversing.
//  3. Each joint follows its reference plus an error profile that brings it back to it,
//     RateProfile::plan(q_dot - s D, q_ddot - ds/dt D - g, 0, ...), within what the
//     reference leaves of its limits; where that cannot keep its limits (a new direction,
//     D changing beyond its estimate), its own profile to the reference at the cycle's end,
//     RateProfile::plan(q_dot, q_ddot, q_dot_ref(h), a_max, j_max). Integrated exactly over
//     h: |q_dot| <= v_max s, |q_ddot| <= a_max and |q_dddot| <= j_max at every instant
//     (j_max = max_jerk, or a_max / jerk_ramp_s for a joint without one).
//  4. Position limits (not for continuous joints). The whole command: if following the ramp
//     for this cycle and then braking s to 0 would carry a joint past a limit (its travel
//     D sigma + D_sigma sigma^2 / 2, for a Cartesian jog with a 2 % margin), s brakes from
//     the latest moment x in [0, h] (bisection) at which that stops the joint at or before
//     the limit: every joint slows with it, and that one comes to rest at the limit (a joint
//     jog: on it; a Cartesian jog: short of it by about 2 % of its braking travel). From then
//     on the command's goal is 0 while it pushes that joint at the limit (another command may
//     move away). Each joint, as the last guard: if following its motion for this cycle and
//     then braking (RateProfile::plan(q_dot, q_ddot, 0, a_max, j_max)) would carry it past a
//     limit, it brakes from the latest such moment itself. q is clamped into [min, max]
//     against rounding.
//
// One forward kinematics (pose, Jacobian) and one SVD per cycle, at the cycle's end: they give
// the sample's pose, twist and sigma_min and the next cycle's D.
//
// Measured (a 0.125 m/s jog along x from home, started and stopped): the tool leaves the line
// by 3e-9 m on the PA-10 and 5e-9 m on the UR5 at 1 kHz (3e-7 m and 5e-7 m at 100 Hz), and
// follows the twist to 7e-8 of it at 1 kHz (7e-6 at 100 Hz).
//
// Limitations:
//  - where the line itself asks more of a joint than its limits (near a singularity, fast:
//    s^2 |D_sigma_j| beyond a_max_j), that joint follows its own profile within its limits
//    and the tool leaves the line;
//  - a command in another direction (not a multiple of the last) is reached joint by joint:
//    between the two the tool is on neither line;
//  - a Cartesian jog's ramps use 0.8 of the joints' limits (less where D drifts), so they
//    take a little longer than a joint's own least time; its stopping_time() is an estimate
//    (A_s and J_s follow D as the arm moves: to 1 % in the tests);
//  - while the command is held at a position limit, a Cartesian jog that could slide along
//    it stops instead (nothing redistributes the held joint's share).
#pragma once

#include <array>
#include <bitset>
#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <string_view>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/live/rate_profile.hpp"
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
  double jerk_ramp_s = kDefaultJerkRampS;
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
  /// Bit j: joint j is braking for, or held at, a position limit (while the command pushes
  /// it there, the whole command's goal is 0). Cleared once neither the command nor the
  /// joint's velocity points at the limit.
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
  /// rest with no command.
  Jogger(const RobotModel& model, JointVector q0, JogOptions options);
  ~Jogger();
  Jogger(Jogger&&) noexcept;
  Jogger& operator=(Jogger&&) noexcept;

  /// The new command (replaces the previous one), effective from the next cycle: the ramp
  /// goes to it (along the line for a multiple of the last). A command of zeros, or neither
  /// joints nor twist, is a release, as stop(). Checked: a valid command
  /// (validate_jog_command with this model's dof).
  void command(const JogCommand& c);
  /// Release (deadman released, stop, drain): the whole command slows to rest, along its line.
  void stop();
  /// Advances one cycle (h = 1 / cycle_rate_hz) and writes its set point.
  void next(JogSample& out);
  /// Every joint's velocity and acceleration is exactly 0 (after the last next()).
  bool at_rest() const;

  /// The time [s] a stop from the current state takes: the ramp's slowing to rest,
  /// RateProfile::plan(s, ds/dt, 0, A_s, J_s).duration(), or the longest of the joints' own
  /// braking profiles, RateProfile::plan(q_dot_j, q_ddot_j, 0, a_max_j, j_max_j).duration(),
  /// if longer. Exact for a joint jog; for a Cartesian jog an estimate (A_s and J_s follow D
  /// as the arm moves).
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
  struct JointMotion;  // one joint over one cycle (jog.cpp)

  /// The fraction s over one cycle (t [s] from its start): `follow` toward `goal`, or, when a
  /// joint must brake for a position limit, `follow` until `brake_at` and then `brake` to 0.
  /// Pinned: past a profile's end s is its goal exactly, with ds/dt = 0.
  struct Ramp {
    RateProfile follow, brake;
    double goal = 0.0;
    double brake_at = std::numeric_limits<double>::infinity();
    double brake_x = 0.0;  ///< int s dt over [0, brake_at] [s]
    double accel = 0.0, jerk = 0.0;              ///< A_s [1/s^2], J_s [1/s^3] of `follow` (0: nothing to ramp)
    double brake_accel = 0.0, brake_jerk = 0.0;  ///< those of braking to 0
    double lo = 0.0, hi = 0.0;  ///< bounds on s over the cycle
    bool moving = false;   ///< s changes within the cycle
    RateState at(double t) const;
  };

  void ramp_limits(double d, double& accel, double& jerk) const;
  void plan_ramp();
  void step_joint(Eigen::Index j);
  void update_kinematics();

  JogOptions options_;
  double h_;
  Eigen::Index n_;
  std::size_t cycles_ = 0;
  JogCommand active_;        ///< the command jogged: the last one that moves (kept through a release)
  double goal_ = 0.0;        ///< s's goal: 1 while active_ is commanded, 0 after a release or stop
  double s_ = 0.0;           ///< the fraction of active_ applied [1] (negative: reversing along its line)
  double s_dot_ = 0.0;       ///< ds/dt [1/s]
  bool cartesian_ = false;   ///< active_ is a twist (and not at rest)
  Ramp ramp_;
  JointVector q_, v_, a_;
  JointVector dir_;     ///< D [rad/s or m/s]: the joint velocities of active_ at full command, at q
  JointVector slope_;       ///< D_sigma = dD/dsigma [rad/s^2 or m/s^2] (sigma = int s dt), over the last cycle
  JointVector drift_;       ///< g = s^2 D_sigma [rad/s^2 or m/s^2]
  JointVector drift_rate_;  ///< g_dot = 2 s ds/dt D_sigma [rad/s^3 or m/s^3]
  double step_ = 0.0;       ///< int s dt over the last cycle [s]
  bool dir_known_ = false;  ///< dir_ is D of the same command at the last cycle's q
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
