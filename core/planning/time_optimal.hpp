// Time-optimal timing along a path under joint and Cartesian limits (time-optimal path
// parameterisation by reachability, Pham and Pham, "A new approach to time-optimal path
// parameterization based on reachability analysis", IEEE T-RO 34(3), 2018: TOPP-RA).
//
// Formulation. On one portion (rest to rest, motion.hpp) let s in [0, L] be the arc length
// from the portion's start [m], s_dot = ds/dt, s_ddot = d2s/dt2, and b = s_dot^2 [m^2/s^2].
// Then d b / ds = 2 s_ddot. With q(s) the joint path the tracker follows (joint_motion.hpp:
// its null-space term is per metre of travel, so q depends on s only),
//   q_dot  = q_s s_dot,                 q_ddot = q_s s_ddot + q_ss b,
// where q_s = dq/ds [rad/m] and q_ss = d2q/ds2 [rad/m^2]. Over a grid s_0 = 0 < ... < s_N = L
// the unknowns are b_i = b(s_i) and, on each interval, a constant u_i = s_ddot, so
// b_{i+1} = b_i + 2 (s_{i+1} - s_i) u_i and b is linear in s. Every limit is linear in
// (b, u) (the canonical form a u + c b in [lo, hi]):
//   joint velocity       |q_s,j| sqrt(b) <= v_max,j     ->  b <= (v_max,j / |q_s,j|)^2
//   joint acceleration   |q_s,j u + q_ss,j b| <= a_max,j
//   Cartesian speed      b <= maxSpeed^2
//   tangential           |u| <= maxAcceleration
//   centripetal          kappa b <= maxAcceleration
//   joint torque         -tau_max,j <= a_j u + b_j b + c_j <= tau_max,j
// where the joint torques of the motion (thesis Eq. 1.15, dynamics.hpp) along the path are
// tau = M(q) q_ddot + C(q, q_dot) q_dot + g(q) = a(s) s_ddot + b(s) s_dot^2 + c(s) with
//   a = M q_s (inverse dynamics at (q, 0, q_s) without gravity),
//   b = M q_ss + C(q, q_s) q_s (at (q, q_s, q_ss) without gravity),
//   c = g(q) with the payload (at (q, 0, 0) with gravity): three calls per grid point;
// and each is imposed at BOTH ends of each interval (at s_{i+1} with b_{i+1} and the same
// u_i), so the piecewise-constant acceleration is admissible on either side of every grid
// point. The problem is convex in (b, u); the time is sum_i 2 ds_i / (sqrt(b_i) +
// sqrt(b_{i+1})).
//
// Sweep (O(N x constraints), no solver): backward, the controllable sets K_N = {0} and
// K_i = {b : some admissible u_i takes b into K_{i+1}}, each an interval computed exactly by
// projecting the interval's 2-D polygon in (b, u) onto b (where max lower - min upper bound on
// u, convex in b, crosses zero: Newton's steps, exact on the piecewise-linear function);
// forward from b_0 = 0, the largest admissible u_i that stays in K_{i+1}.
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/binding.hpp"
#include "core/planning/joint_reference.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The path data the limits need at one grid point of a portion.
struct GridPoint {
  double s = 0.0;      ///< arc length from the portion's start [m]
  JointVector q_s;     ///< dq/ds [rad/m or m/m]; empty without a robot
  JointVector q_ss;    ///< d2q/ds2 [rad/m^2 or 1/m]; empty without a robot
  double kappa = 0.0;  ///< curvature [1/m]
  /// The tool's angular velocity per unit path speed, omega = omega_s s_dot [rad/m], and
  /// its derivative along the path: alpha = omega_s s_ddot + omega_ss s_dot^2 [rad/m^2].
  Eigen::Vector3d omega_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_ss = Eigen::Vector3d::Zero();
  /// Optional: q_s and q_ss at the middle of the interval that starts here (empty: none).
  /// Where given, the joint velocity and acceleration limits hold there too (b linear and u
  /// constant on the interval: b_mid = b_i + ds u), so that a joint path whose derivatives
  /// turn within an interval keeps its limits between the grid points with fewer
  /// refinements.
  JointVector q_s_mid, q_ss_mid;
  /// The joint torques along the path, tau = tau_a s_ddot + tau_b s_dot^2 + tau_c [N m or N]
  /// (set_torque_terms), where the limits have torques; empty otherwise.
  JointVector tau_a, tau_b, tau_c;
};

/// Writes g.tau_a, tau_b, tau_c at joints q [rad or m] from g.q_s and g.q_ss: three
/// inverse-dynamics calls with the model's payload (dynamics.hpp). Precondition:
/// has_dynamics(model). No heap allocation.
void set_torque_terms(const RobotModel& model, const JointVector& q, GridPoint& g);


/// The limits of a time-optimal timing. A limit at +infinity is not imposed.
struct TimeOptimalLimits {
  JointVector joint_velocity;      ///< v_max,j [rad/s or m/s], one per joint of GridPoint::q_s
  JointVector joint_acceleration;  ///< a_max,j [rad/s^2 or m/s^2]
  double speed = std::numeric_limits<double>::infinity();         ///< Cartesian maxSpeed [m/s]
  double tangential = std::numeric_limits<double>::infinity();    ///< |s_ddot| <= [m/s^2]
  double centripetal = std::numeric_limits<double>::infinity();   ///< kappa s_dot^2 <= [m/s^2]
  /// |omega| <= [rad/s] and |alpha| <= [rad/s^2] (maxAngularSpeed, maxAngularAcceleration).
  /// The acceleration's norm is imposed by kAngularDirections support rows in the plane of
  /// omega_s and omega_ss, each at limit cos(pi / kAngularDirections): sufficient for the norm,
  /// at most 1 - cos(pi / 16) = 1.9 % below it.
  double angular_speed = std::numeric_limits<double>::infinity();
  double angular_acceleration = std::numeric_limits<double>::infinity();
  /// Jerk limits, checked on the samples (check_time_optimal_samples) and imposed by the
  /// jerk-limited timing (optim/timing/time_optimal_jerk.hpp); the sweep has no jerk.
  JointVector joint_jerk;  ///< j_max,j [rad/s^3 or m/s^3] per joint; empty: none
  double jerk = std::numeric_limits<double>::infinity();  ///< |s_dddot| <= maxJerk [m/s^3]
  /// |tau_j| <= maxTorque [N m or N] per joint (GridPoint's tau terms; +infinity: none);
  /// empty: no torque limit. Not scaled by speedScale (a drive's limit); the part that moves
  /// the arm (the torque less the gravity's) keeps within `torque_dynamic_scale` of what the
  /// limit leaves it (the acceleration reserve of live execution, MotionSpec's
  /// acceleration_scale).
  JointVector joint_torque;
  double torque_dynamic_scale = 1.0;
};

/// The sample checks' screen of the torques: a sample's torques estimated from the grid's
/// terms (tau_a, tau_b, tau_c linear between the ends of its interval, at the sample's s_ddot
/// and s_dot^2: exact at grid points, off by O(h^2) between them, far below this margin);
/// where no estimate comes within this fraction of its limit the estimate is the sample's
/// usage, else the torques are computed exactly (inverse_dynamics, gravity_torques).
inline constexpr double kTorqueScreen = 0.95;

/// The screen's estimate: false when every joint's estimated torque is within kTorqueScreen of
/// its limit, with the largest estimated dynamic_torque_usage in `usage` and where it is (joint,
/// |tau|, limit); true: the sample needs the exact torques. `f` in [0, 1]: the sample's place
/// between g0 and g1; `s_ddot` [m/s^2], `b` = s_dot^2 [m^2/s^2].
struct TorqueEstimate {
  double usage = 0.0, value = 0.0, limit = 0.0;
  Eigen::Index joint = -1;
};
bool torques_near_limits(const GridPoint& g0, const GridPoint& g1, double f, double s_ddot, double b,
                         const TimeOptimalLimits& limits, TorqueEstimate& estimate);

/// The exact solution of one portion's grid.
struct TimeOptimalSolution {
  std::vector<double> b;  ///< s_dot^2 at each grid point [m^2/s^2], b.front() = b.back() = 0
  std::vector<double> u;  ///< s_ddot on each interval [m/s^2] (N values)
  std::vector<BindingStretch> binding;  ///< portion 0, s from the portion's start
  SpeedProfile profile;   ///< one constant-acceleration piece per interval (j = 0), exact times
  double duration = 0.0;  ///< [s]
};

/// The sweep over `grid` (s strictly increasing from 0, at least 2 points; q_s, q_ss of
/// the size of limits.joint_velocity). Rest to rest: b = 0 at both ends.
/// Errors (field `motion`): a grid point where only zero speed is admissible, or from
/// which the rest at the end cannot be reached; the description names s [m] (from the
/// portion's start) and the limit (joint and kind) that stops it.
Expected<TimeOptimalSolution> solve_time_optimal(const std::vector<GridPoint>& grid, const TimeOptimalLimits& limits);

/// The indices 0, 2, 4, ... of a grid of n points, and n - 1 (the end) when n is even: the
/// coarser grid of a duration's grid-error estimate.
std::vector<std::size_t> every_second_point(std::size_t n);

/// Options of plan_time_optimal.
struct TimeOptimalOptions {
  /// Grid intervals per portion. The duration converges about linearly in the grid
  /// spacing; measured on the PA-10 along demo path C (portions of about 1 m; 100 Hz):
  ///   intervals   100     200     400     800     1,000   1,600   3,200
  ///   T [s]       6.123   5.813   5.705   5.674   5.669   5.660   5.653
  ///   plan [ms]   31      46      48      58      61      76      104
  /// 1,000 intervals (1 mm apart) put the duration within 0.4 % of the limit for a third more
  /// time than 200 (5 mm apart, 3 % slower); TimeOptimalPlan::duration_grid_error reports
  /// the estimate for each plan.
  std::size_t grid_intervals = 1000;
  /// Stream the result through MotionSampler (and JointTracker with a robot) and check
  /// every sample; where one breaks a limit, tighten the limits at that interval by the
  /// ratio and solve again (at most `max_refinements` times; from round
  /// `uniform_refinement_from` on, every point's limits also tighten: see tighten_limits).
  bool verify_samples = true;
  int max_refinements = 8;
  int uniform_refinement_from = 4;
  /// Relative slack of the sample check: a sample passes when value <= limit (1 + slack)
  /// (the IK's rounding; 1e-9).
  double sample_tolerance = 1e-9;
  /// Limits hold between the samples too: once the samples at the cycle rate are within
  /// the limits, the motion is checked (and refined) at the smallest multiple of the cycle
  /// rate at or above this rate [Hz], so that every sample of a stream at the cycle rate, or
  /// at any rate dividing the check rate, is one of the samples checked. Between two checked
  /// samples h = 1 / f apart a joint velocity can pass the larger of its two checked values
  /// by at most a_max h / 2 (2.5e-4 rad/s for 1 rad/s^2 at 2 kHz), an acceleration by the
  /// jerk times h / 2; a jerk is checked as the mean over each period h (what a controller
  /// differentiating accelerations at any rate dividing f sees is a mean of those). The
  /// default, 2 kHz: a 10-second PA-10 motion is 20,000 IK solutions (about 25 ms).
  /// 0: the cycle rate only.
  double check_rate_hz = 2'000.0;
  /// The check rate is lowered (to a multiple of the cycle rate) so that a check takes at
  /// most this many samples: a minute of motion at 10 kHz is 600,000 IK solutions.
  std::size_t max_check_samples = 200'000;
  IkOptions ik;
  /// A redundant arm's joints chosen along the path (ReferenceParameter::kArcLength, the
  /// robot's joints; optim/redundancy's, planner): the grids' and the sample checks' tracker
  /// follows them as the streamed samples will (null: the self-motion chosen sample by sample).
  std::shared_ptr<const JointReference> joints = nullptr;
  /// Cancellation (a cancelled call, or its deadline): the sweeps and the sample checks stop
  /// at their next check (every 256 samples, every refinement) with a `motion` error.
  std::stop_token stop;
};

/// A time-optimal plan: the motion (sampled exactly by MotionSampler) and why it takes the
/// time it takes.
struct TimeOptimalPlan {
  MotionPlan motion;
  std::vector<BindingStretch> binding;   ///< in time order, over all portions
  /// The grid of each portion (what the optimiser of jerk-limited timing starts from).
  std::vector<std::vector<GridPoint>> grids;
  std::vector<TimeOptimalSolution> solutions;  ///< one per portion
  TimeOptimalLimits limits;                    ///< the limits used (speedScale applied)
  int refinements = 0;          ///< re-solves after the sample check
  double worst_sample_usage = 0.0;  ///< largest value / limit over every sample checked
  double check_rate_hz = 0.0;       ///< the rate of the last sample check [Hz]
  /// |T(N) - T(N / 2)| [s]: the duration on this grid against the duration on every second
  /// point of it (the same limits and refinements), an estimate of the duration's error
  /// from the grid (the time converges at least linearly in the grid spacing).
  double duration_grid_error = 0.0;
};

/// The joint path's derivatives along `path`: for each portion of `portions` (as
/// plan_motion makes them; their profiles are not used), grid_intervals + 1 points uniform
/// in arc length with q_s and q_ss from a JointTracker evaluated with s_dot = 1 [m/s],
/// s_ddot = 0 (then q_dot = q_s, q_ddot = q_ss), seeded with `seed`, and the curvature.
/// The tracker walks the path with the samples' continuation (JointTracker::follow), on one
/// branch, under kGridContinuation: a grid step that does not converge, strays from the
/// chord (midpoint deviation above 1 mm) or needs a Newton correction of its predictor above
/// 0.01 rad is not kept and the interval walked in halved steps (down to 1/4096 of it), so a
/// path that streams at a fixed duration times here too
/// (tests/core/planning/grid_ik_property_test.cpp). `robot` null: kappa only. `joints`
/// (optional, in arc length): the tracker follows them (JointTracker::set_reference).
/// Errors (field `motion`): the IK fails at a grid point (s and u named).
Expected<std::vector<std::vector<GridPoint>>> time_optimal_grids(const Path& path, const OrientationPlan& orientation,
                                                                 const std::vector<MotionPortion>& portions,
                                                                 const RobotModel* robot, const JointVector& seed,
                                                                 std::size_t grid_intervals,
                                                                 const IkOptions& ik = {},
                                                                 const JointReference* joints = nullptr);

/// The limits of `spec` (maxSpeed, maxAcceleration both tangential and centripetal, each
/// optional) and of `robot` (velocity, acceleration; may be null), scaled by speedScale
/// (v s, a s^2).
TimeOptimalLimits time_optimal_limits(const MotionSpec& spec, const RobotModel* robot);

/// The MotionPlan of per-portion profiles (durations, sample count and peaks by
/// plan_motion's rules). `portions` give u, s and lengths; their profiles are replaced.
Expected<MotionPlan> assemble_motion(const MotionSpec& spec, std::vector<MotionPortion> portions,
                                     const std::vector<SpeedProfile>& profiles);

/// The fastest motion along `path` within the limits of `spec` (durationS is ignored: the
/// time is the result) and of `robot` (joint velocities and accelerations; null: the
/// Cartesian limits only). Portions between rests as plan_motion; each portion is solved
/// by solve_time_optimal on a grid of options.grid_intervals intervals, then (by default)
/// every sample of the result is checked and the grid limits tightened until none breaks a
/// limit. Guarantee: at every grid point, on both sides, every limit holds to rounding;
/// Cartesian speed and tangential acceleration hold everywhere (b is linear and u constant
/// between grid points); with verify_samples every streamed sample (cycle rate) is within
/// every limit to sample_tolerance, or the call fails.
/// Errors: validate_motion's minus the durationS rule; `motion` when no limit is given, a
/// point admits no positive speed (s, u and the limit named), the IK fails, or the sample
/// check does not settle.
Expected<TimeOptimalPlan> plan_time_optimal(const Path& path, const OrientationPlan& orientation,
                                            const MotionSpec& spec, const RobotModel* robot,
                                            const JointVector& seed, const TimeOptimalOptions& options = {});

/// The outcome of check_time_optimal_samples.
struct SampleCheck {
  bool broken = false;        ///< some sample exceeds a limit by more than sample_tolerance
  /// Largest value / limit over every sample checked (a torque's: dynamic_torque_usage, its
  /// part beyond gravity's against what the limit leaves it, which scales as an acceleration).
  double worst_usage = 0.0;
  /// Per portion and grid point, the factor (in (0, 1]) by which to scale that point's
  /// limits (velocities by it, accelerations by its square) before solving again: for each
  /// sample with value / limit r > 1 + sample_tolerance on grid interval k, both ends k and
  /// k + 1 get at most (1 / r^2 of a velocity, 1 / r of an acceleration) (1 - 1e-6): twice the
  /// correction that removes the excess where it was measured, so the loop settles in fewer
  /// rounds.
  std::vector<std::vector<double>> shrink;
  /// The same for the jerk limits (1 / r^2 of a jerk, at the points k - 1 .. k + 2: a jerk
  /// comes from the acceleration's change across a point), where the limits have any.
  std::vector<std::vector<double>> jerk_shrink;
  /// Where the worst usage is: "joint 3 jerk 51.2 of 50 rad/s^3 at t = 1.25 s (s = 0.4 m)".
  std::string worst;
  double check_rate_hz = 0.0;  ///< the finest rate checked [Hz]

  /// Records an excess: usage r > 1 of a limit of `order` (1 velocity, 2 acceleration, 3 jerk,
  /// 4 torque, whose usage scales as an acceleration's) measured in grid interval k of
  /// `portion`: broken, and that interval's points shrunk as said above.
  void tighten(std::size_t portion, std::size_t k, double r, int order);
};

/// Streams `motion` through MotionSampler at its cycle rate, then, if every sample there
/// is within the limits, at the check rate (TimeOptimalOptions::check_rate_hz: a refinement
/// loop re-solves on the cheap check's findings first), each time (with a robot) through a JointTracker
/// seeded with `seed` and options.ik, and compares every sample with `limits`: joint
/// velocity |q_dot,j| [rad/s or m/s], joint acceleration |q_ddot,j| [rad/s^2 or m/s^2], the
/// centripetal acceleration |a_W - (a_W . T) T| [m/s^2] and, where `limits` has them, the
/// joint jerk |q_ddot,j(t_k) - q_ddot,j(t_{k-1})| / (t_k - t_{k-1}) [rad/s^3 or m/s^3] and
/// the path's |s_ddot(t_k) - s_ddot(t_{k-1})| / (t_k - t_{k-1}) [m/s^3] (the mean jerk over
/// each sample period: what a controller differentiating the set points sees; maxSpeed
/// and the tangential limit hold exactly between grid points and are not sampled). `grids` are the portions'
/// grids (uniform in s, as time_optimal_grids makes them); a sample belongs to the grid
/// interval of its arc length. Used by plan_time_optimal after each sweep; any timing on
/// the same grids may use it the same way.
/// Errors (field `motion`): the IK fails at a sample (t, s and u named).
Expected<SampleCheck> check_time_optimal_samples(const Path& path, const OrientationPlan& orientation,
                                                 const MotionPlan& motion,
                                                 const std::vector<std::vector<GridPoint>>& grids,
                                                 const TimeOptimalLimits& limits, const RobotModel* robot,
                                                 const JointVector& seed, const TimeOptimalOptions& options);

/// The limits' factors after a sample check that found the motion over a limit, in round
/// `round` of the refinements (from 0): each grid point's `sigma` (velocities scale by it,
/// accelerations by its square) times `check.shrink`, and each point's jerk factor (where
/// `jerk_sigma` is given) times `check.jerk_shrink`. From round `uniform_from` on, the local
/// tightening has not settled (the excess moved on to neighbouring samples or grid
/// intervals), so every point of every portion also takes the factor 1 / worst_usage (its
/// cube for the jerk factors): the same limits on the same grid with every sigma scaled by
/// 1 / c time the motion c times slower, velocities 1 / c, accelerations 1 / c^2, jerks
/// 1 / c^3 as fast, so the worst sample comes within its limit whatever its order, at the
/// cost of at most that factor in duration.
void tighten_limits(const SampleCheck& check, int round, int uniform_from, std::vector<std::vector<double>>& sigma,
                    std::vector<std::vector<double>>* jerk_sigma);

/// Where a torque limit comes from and how to change it, for the errors that name one.
inline constexpr const char* kTorqueLimitSource =
    " (the model's, a URDF's <limit effort>; robot.jointLimits[].maxTorque gives another)";

/// The error of a sample (at t [s], s [m or path parameter]) where joint `joint`'s gravity load
/// passes its maxTorque `limit` [N m or N] (field `motion`).
FieldViolation gravity_beyond(Eigen::Index joint, double gravity, double limit, double t, double s);

/// A one-line description of a stretch ("joint 3 velocity 1.99 of 1.99 rad/s on s 0.1-0.4 m").
std::string describe(const BindingStretch& stretch);

}  // namespace geotraj::core
