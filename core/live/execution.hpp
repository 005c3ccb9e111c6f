// Live execution of a planned trajectory: speed override, pause, resume and stop, all on the
// planned path, within the robot's and the Cartesian limits.
//
// Time scaling. The planned trajectory is a function of its own time tau in [0, T] (the plan
// time): tool pose x(tau), joints q(tau). Live execution keeps that function and moves tau
// at a rate r = d tau / dt in [0, 1] (the speed factor; 1 is the plan as planned). Every
// set point is the plan's own point at tau (its IK solution on the path: pausing and
// stopping never leave the path), and the chain rule gives the live derivatives exactly
// (' = d/d tau, a dot = d/dt):
//   q_dot   = q' r
//   q_ddot  = q'' r^2 + q' r_dot
//   q_dddot = q''' r^3 + 3 q'' r r_dot + q' r_ddot
// and the same for the tool's path speed s_dot (tangential acceleration, path jerk) and its
// angular velocity. So the path is fixed and the problem is one-dimensional in (tau, r): a
// speed change is a jerk-limited change of r (rate_profile.hpp).
//
// Limits. Let V, A, J be a quantity's largest |q'|, |q''|, |q'''| over the plan (measured
// on the plan at the check rate, V plus the growth possible between check samples) and a_max,
// j_max its limits. While r stays at or below r_h, with |r_dot| <= rd and |r_ddot| <= rdd,
//   |q_ddot|  <= A r_h^2 + V rd                          <= a_max
//   |q_dddot| <= J r_h^3 + 3 A r_h rd + V rdd             <= j_max
// so each quantity bounds the speed factor's rates:
//   rd  <= (a_max - A r_h^2) / V,    rd <= (j_max - J r_h^3) / (6 A r_h)   (half the jerk room)
//   rdd <= (j_max - J r_h^3 - 3 A r_h rd) / V
// and the smallest over the joints, the tool's tangential and angular quantities are the
// speed factor's limits (factor_bounds). Velocities need nothing: |q_dot| = |q'| r <= V.
// A plan that uses a limit fully at r = 1 leaves no room to change speed there: the bounds
// are taken at r_h = the largest r of the change, and re-taken every cycle of a change (a
// slowing change gets faster as r falls: the room grows as 1 - r^2).
//
// Stopping. From the state (r, r_dot = 0) with the bounds rd, rdd at r_h = r, a stop takes
//   T_stop   = r / rd + rd / rdd         when r >= rd^2 / rdd,   else 2 sqrt(r / rdd)
// and covers the plan time dtau = r T_stop / 2 (the profile is symmetric about its middle);
// the path distance is s(tau + dtau) - s(tau). These are upper bounds of what live execution
// takes: its cycles re-take the bounds as r falls.
#pragma once

#include <cstddef>
#include <limits>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/live/rate_profile.hpp"
#include "core/motion/motion.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/trajectory.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The joint limits live execution keeps. A limit at +infinity is not imposed. The
/// Cartesian limits are each step's own (LiveExecution::start): a path's and a straight
/// line's maxAcceleration, maxJerk and maxAngularAcceleration hold on that step; a joint
/// move (a robot.approach's included) keeps none, as its plan does.
struct LiveLimits {
  JointVector acceleration;  ///< per joint [rad/s^2 or m/s^2]; empty without a robot
  JointVector jerk;          ///< per joint [rad/s^3 or m/s^3]; +infinity where not given
};

/// The robot's own limits (unscaled: speedScale slows the plan, not the robot); empty
/// without a robot.
LiveLimits live_limits(const RobotModel* robot);

/// One limited quantity of the plan: its peaks per unit of plan time and its limits.
struct LiveRow {
  /// "joint 1 (panda_joint2)" (from 0), "tool tangential", "tool angular" (in a sequence
  /// "tool tangential in step 1": the step's index in the request, from 0)
  std::string name;
  std::string unit;  ///< of the quantity: "rad", "m"
  double peak_rate = 0.0;          ///< V = max |x'|
  double peak_acceleration = 0.0;  ///< A = max |x''|
  double peak_jerk = 0.0;          ///< J = max |x'''| (finite differences at the check rate)
  double max_acceleration = std::numeric_limits<double>::infinity();
  double max_jerk = std::numeric_limits<double>::infinity();
};

/// The speed factor's limits at r_h, and the quantity that sets each.
struct FactorBounds {
  double acceleration = 0.0;  ///< |r_dot| <= [1/s]
  double jerk = 0.0;          ///< |r_ddot| <= [1/s^2]
  std::size_t acceleration_row = 0;  ///< index into the rows of the binding quantity
  std::size_t jerk_row = 0;
  /// No moving quantity has an acceleration limit (a path without a robot or Cartesian
  /// limits): acceleration = 1 / ramp, and acceleration_row names nothing.
  bool acceleration_from_ramp = false;
  bool jerk_from_ramp = false;  ///< no quantity has a jerk limit: jerk = acceleration / ramp
};

/// See the file comment. `ramp_s` > 0: without any jerk limit, r_ddot <= rd / ramp_s.
FactorBounds factor_bounds(const std::vector<LiveRow>& rows, double r_high, double ramp_s);

/// The time [s] and plan time [s] a stop takes from (r, r_dot) with `bounds`.
struct StopPrediction {
  double time_s = 0.0;
  double plan_time_s = 0.0;
};
StopPrediction predict_stop(double r, double r_dot, const FactorBounds& bounds);

/// Options of live execution.
struct LiveOptions {
  /// The plan's peaks are measured at the smallest multiple of the cycle rate at or above
  /// this rate [Hz] (at most max_check_samples samples), as the time-optimal check does.
  double check_rate_hz = 2'000.0;
  std::size_t max_check_samples = 200'000;
  /// Without any jerk limit the speed factor's acceleration ramps over this time [s].
  double ramp_s = 0.05;
  /// A plan from whose full speed a stop would take longer than this [s] is refused (it
  /// uses some limit fully: there is no room to slow down on the path).
  double max_stop_time_s = 30.0;
  /// A plan whose own jerk passes a limit by more than this fraction is refused: a joint's
  /// measured as the planner's joint report does (differences of the accelerations at the
  /// cycle rate, kStepTolerance), the tool's path jerk at the check rate.
  double jerk_tolerance = kStepTolerance;
  /// The pass over the plan stops when this is requested (a cancelled call).
  std::stop_token stop;
  IkOptions ik;
};

/// Where live execution stands.
enum class LiveState {
  kRunning,   ///< moving at (or toward) the override
  kPausing,   ///< slowing to rest on the path
  kPaused,    ///< at rest on the path, holding
  kStopping,  ///< slowing to rest; the call ends there
  kStopped,   ///< the final sample (at rest) has been written after a stop
  kCompleted, ///< the final sample of the plan has been written
};

/// One live set point.
struct LiveSample {
  /// The plan's sample at plan_time with the live time t and the live derivatives (tool
  /// velocity, acceleration, angular velocity and acceleration, speed, joint velocities and
  /// accelerations); u, s, segment and step say where on the plan it stands.
  TrajectorySample sample;
  double plan_time = 0.0;          ///< tau [s]
  double speed_factor = 0.0;       ///< r = d tau / dt
  double speed_factor_rate = 0.0;  ///< r_dot [1/s]
  LiveState state = LiveState::kRunning;
};

/// A trajectory executed live (see the file comment): one per call, stepping one cycle at a
/// time. `trajectory` and `robot` must outlive it.
class LiveExecution {
 public:
  /// Measures the plan's peaks (one pass of the sampler at the check rate) and the speed
  /// factor's bounds. Errors (field `motion`): the pass was stopped (options.stop), the IK
  /// fails on the pass, the plan's own jerk
  /// passes a jerk limit, or a stop from full speed would take longer than
  /// options.max_stop_time_s (the quantity named in each).
  static Expected<LiveExecution> start(const Trajectory& trajectory, const RobotModel* robot, const JointVector& seed,
                                       const LiveLimits& limits, double cycle_rate_hz, const LiveOptions& options = {});

  /// Commands, effective from the next sample. The override is a fraction in [0, 1].
  void set_override(double fraction);
  void pause();
  void resume();
  void stop();

  /// Writes the next set point; false once the final one has been written.
  bool next(LiveSample& out);

  LiveState state() const { return state_; }
  double override_fraction() const { return override_; }
  /// The speed factor now (after the last sample written) and its rate.
  double speed_factor() const { return r_; }
  double speed_factor_rate() const { return r_dot_; }
  double plan_time() const { return tau_; }
  double plan_duration() const { return duration_; }
  /// A stop from the current state, with the bounds at the current speed factor.
  StopPrediction stopping() const;
  /// The bounds at r_h (e.g. 1: the worst case of the plan).
  FactorBounds bounds(double r_high) const;
  const std::vector<LiveRow>& rows() const { return rows_; }

  LiveExecution(LiveExecution&&) noexcept = default;
  LiveExecution& operator=(LiveExecution&&) noexcept = default;

 private:
  LiveExecution(const Trajectory& trajectory, const RobotModel* robot, const JointVector& seed, const IkOptions& ik);
  void retarget(double target);
  void write(LiveSample& out);

  const Trajectory* trajectory_;
  /// The model whose torques each sample carries at its speed factor (has_dynamics); null
  /// otherwise.
  const RobotModel* dynamics_ = nullptr;
  TrajectorySampler sampler_;
  std::vector<LiveRow> rows_;
  double ramp_s_ = 0.05;
  double period_ = 0.01;
  double duration_ = 0.0;
  std::size_t k_ = 0;        // index of the next sample
  double t_ = 0.0;           // time of the last sample written [s]
  double tau_ = 0.0;         // its plan time
  double r_ = 1.0;           // its speed factor
  double r_dot_ = 0.0;
  double target_ = 1.0;      // what r moves to
  double override_ = 1.0;
  LiveState state_ = LiveState::kRunning;
  TrajectorySample plan_;    // the plan's sample at tau_
  bool have_plan_ = false;
};

}  // namespace geotraj::core
