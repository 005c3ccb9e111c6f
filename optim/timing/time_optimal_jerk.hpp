// Jerk-limited (or smoothness-weighted) time-optimal timing along a path: a nonlinear
// programme solved by a purpose-built banded primal-dual interior point method (falling back
// to Ipopt when it does not converge), warm-started from the exact sweep of
// core/planning/time_optimal.hpp.
//
// Formulation: the exact problem's, plus jerk. On the grid s_0 = 0 < ... < s_N of one
// portion (ds_i = s_{i+1} - s_i [m]) the unknowns are b_i = s_dot^2(s_i) [m^2/s^2] at the
// interior points (rest to rest: b_0 = b_N = 0 are constants). As in the sweep, b is linear
// in s on each interval and the acceleration constant:
//   u_i = (b_{i+1} - b_i) / (2 ds_i)                      [m/s^2]
//   t_i = 2 ds_i / (sqrt(b_i) + sqrt(b_{i+1}))            [s]
// and the sweep's limits, in the same places, are linear in b:
//   joint velocity, maxSpeed, centripetal  bounds on b_i (the sweep's point caps)
//   joint acceleration  |q_s,j(s_k) u_i + q_ss,j(s_k) b_k| <= a_max,j at BOTH ends k = i, i + 1
//   tangential          |u_i| <= maxAcceleration
// so the sweep's b is feasible, and without jerk limits the programme is convex (T is
// convex in b) with the sweep's b as its minimum.
// Jerk. The acceleration steps from u_{i-1} to u_i at s_i; the profile returned ramps each
// step linearly over a window centred on it (core::continuous_acceleration_profile: the
// speed at the window's ends is kept), of width min(t_{i-1}, t_i) inside and t_0 / 2,
// t_{N-1} / 2 at the rests, giving the jerk at each grid point (u_{-1} = u_N = 0: the rests)
//   j_i = (u_i - u_{i-1}) / w_i                                            [m/s^3]
// with w_i the smooth lower bound of min(t_{i-1}, t_i) (halves h_a = t_{i-1} / 2, h_b = t_i / 2)
//   w_i = h_a + h_b - sqrt((h_a - h_b)^2 + c h_a h_b),  c = kJerkWindowSmoothing = 0.0025,
// within 2.5 % of the window and never above it (so the modelled jerk bounds the
// profile's), and w_0 = t_0 / 2, w_N = t_{N-1} / 2 exactly;
// and the joint jerk q_dddot = q_s s_dddot + 3 q_ss s_dot s_ddot + q_sss s_dot^3 with
// s_dot = sqrt(b_i), q_sss by central differences of q_ss and s_ddot at either end of the
// ramp (the jerk is linear in s_ddot, so these are its extremes over the ramp):
//   joint jerk   |q_s,j j_i + 3 q_ss,j sqrt(b_i) u + q_sss,j b_i^(3/2)| <= j_max,j,  u = u_{i-1}, u_i
//   Cartesian    |j_i| <= maxJerk
// at every grid point, and, for the stretches of constant acceleration between two ramps
// (where the path's jerk is 0, and the joints' is not where the joint path curves),
//   joint jerk   |3 q_ss,j sqrt(b_i) u + q_sss,j b_i^(3/2)| <= j_max,j,  u = u_{i-1}, u_i. Between the grid points
// the profile's joint jerk is not modelled (q_sss is estimated, the windows' edges are
// not grid points): the sample check (plan_time_optimal_jerk) measures it and tightens the
// jerk limits around any excess. With tau_i = (t_{i-1} + t_i) / 2 (t_{-1} = t_N = 0):
// Objective: T + w sum_i j_i^2 tau_i (T = sum_i t_i = sum_i tau_i; w = smoothness_weight
// [s^5/m^2] times the integral of the squared jerk [m^2/s^5]). Exact first and second
// derivatives; Jacobian and Hessian are banded (each jerk couples b_{i-1}, b_i, b_{i+1}).
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <stop_token>
#include <vector>

#include "core/error.hpp"
#include "core/planning/time_optimal.hpp"
#include "optim/common/report.hpp"

namespace geotraj::optim {

/// c of the ramp width w_i above: with equal halves the width is (2 - sqrt(c)) h, 2.5 % below
/// the ramp's.
inline constexpr double kJerkWindowSmoothing = 0.0025;

/// The largest grid on which kAuto falls back to Ipopt: MUMPS factors the whole KKT system,
/// and one of its factorisations cannot be interrupted (858 ms for the whole solve at 1,000
/// points; a 200-waypoint joint path's portion of 6,900 points held a call 70 s past its
/// deadline). Above it, the banded method's result or failure stands.
inline constexpr std::size_t kIpoptFallbackMaxPoints = 1500;

/// Which solver runs the NLP.
enum class JerkSolver {
  /// The banded interior point method, then Ipopt from the same start with the budget left
  /// when it does not converge (neither converged nor out of time) on a grid of at most
  /// kIpoptFallbackMaxPoints.
  kAuto,
  kBanded,  ///< the banded interior point method only
  kIpopt,   ///< Ipopt (MUMPS) only
};

/// Options of the jerk-limited timing (Ceres-style value).
struct JerkTimingOptions {
  /// Joint jerk limits [rad/s^3 or m/s^3] per joint (+infinity: none); empty: none.
  core::JointVector joint_jerk;
  std::optional<double> max_jerk;   ///< Cartesian tangential jerk [m/s^3]
  double smoothness_weight = 0.0;   ///< w [s^5/m^2] of the objective above, >= 0
  /// Time budget [s]: the banded method's wall-clock deadline, checked every iteration, and
  /// Ipopt's max_cpu_time (the budget left, after a banded attempt).
  double time_budget_s = 1.0;
  /// Cancellation (the RPC was cancelled): both solvers stop as at the budget's end.
  std::stop_token stop;
  /// Per solver (after a banded attempt that did not converge Ipopt gets as many).
  int max_iterations = 500;
  /// Per grid point, sigma in (0, 1]: that point's joint velocity limits are multiplied by
  /// sigma, its joint and centripetal acceleration limits by sigma^2 (the sample check's
  /// tightening, as in plan_time_optimal); empty: 1 everywhere, else one per grid point.
  std::vector<double> limit_scale;
  /// Per grid point, in (0, 1]: that point's jerk limits (joint and Cartesian) are
  /// multiplied by it (the sample check's tightening of the jerk); empty: 1 everywhere.
  std::vector<double> jerk_scale;
  /// The solver starts from the start's b times this, in (0, 1]: the same motion slower
  /// (velocities x sqrt, accelerations x, jerks x ^(3/2)), strictly inside the limits the
  /// start meets. An interior point method started on the sweep's many active limits takes
  /// several times the iterations.
  double start_scale = 0.5;
  /// Both solvers' tol (Ipopt's scaled KKT error; the objective is in [s]).
  double tolerance = 1e-8;
  /// Leave out the jerk rows that the kept ones and the velocity and acceleration limits
  /// imply (they cannot bind, so the feasible set and the optimum are unchanged; each
  /// solver's system shrinks by two rows each). Off: every row, for comparison.
  bool drop_implied_jerk_rows = true;
  /// plan_time_optimal_jerk: the re-solves after a sample check that found a limit broken
  /// (from round `uniform_refinement_from` on, every grid point also tightens:
  /// core::tighten_limits); still broken after the last, the result is slowed uniformly.
  int max_refinements = 8;
  int uniform_refinement_from = 4;
  /// Run Ipopt's second-order derivative checker at the start point and print its report
  /// (and Ipopt's iteration log) on stdout: a debug aid, slow (Ipopt runs, whatever `solver`).
  bool derivative_test = false;
  /// The solver (kAuto: the banded interior point method, Ipopt when it does not converge).
  /// OptimizerReport::message names the solver whose result is returned.
  JerkSolver solver = JerkSolver::kAuto;
};

/// The outcome for one portion.
struct JerkTiming {
  /// The grid profile with its acceleration steps ramped (core::continuous_acceleration_profile):
  /// continuous acceleration, zero at both rests, constant jerk pieces; it lasts dt_0 / 4 +
  /// dt_{N-1} / 4 longer than the grid's sum of dt.
  core::SpeedProfile profile;
  std::vector<double> b;       ///< s_dot^2 at the grid points [m^2/s^2] (b.front() = b.back() = 0)
  std::vector<double> u;       ///< acceleration on each interval [m/s^2]
  std::vector<double> dt;      ///< time of each interval [s]
  std::vector<double> jerk;    ///< j_i at each grid point [m/s^3] (above)
  double duration = 0.0;       ///< [s]
  /// Largest excess over a limit at the returned point, in the limit's unit (0: feasible);
  /// every row, the left-out implied jerk rows included.
  double max_constraint_violation = 0.0;
  std::size_t jerk_rows = 0;          ///< jerk rows of the programme ((N + 1) x limited quantities)
  std::size_t implied_jerk_rows = 0;  ///< of them left out as implied (drop_implied_jerk_rows)
  /// Objective T + w sum j^2 tau [s] before (the exact sweep's b) and after.
  OptimizerReport report;
};

/// Solves one portion's NLP from the exact solution `start` of the same grid and limits
/// (core::solve_time_optimal). The status is honest: kConverged only when the solver that
/// ran last converged (to its tolerance, or Ipopt's acceptable level); kTimeLimit when
/// time_budget_s ran out, kIterationLimit at max_iterations (the last iterate is returned,
/// with its max_constraint_violation); kFailed otherwise (the start's profile is returned).
/// report.iterations sums both solvers' iterations when Ipopt ran after the banded method.
/// Preconditions: grid.size() >= 3, `start` solved on `grid`.
JerkTiming optimise_jerk_timing(const std::vector<core::GridPoint>& grid, const core::TimeOptimalLimits& limits,
                                const core::TimeOptimalSolution& start, const JerkTimingOptions& options);

/// A whole plan: the exact plan (core::plan_time_optimal) re-timed portion by portion.
/// Relative margin inside every velocity, acceleration and jerk limit that plan_time_optimal_jerk
/// keeps at its grid points (the solvers meet the constraints to their tolerance only).
inline constexpr double kJerkLimitMargin = 1e-6;

struct JerkLimitedPlan {
  core::MotionPlan motion;
  core::TimeOptimalPlan exact;           ///< the warm start and its binding report
  std::vector<JerkTiming> portions;
  OptimizerReport report;                ///< summed iterations, the worst status, wall time [s]
  int refinements = 0;                   ///< re-solves after the sample check
  /// > 1 when the refinements did not settle and the last result was slowed uniformly by
  /// this factor to bring every sample within its limits (core::time_scaled); else 1.
  double slowed_by = 1.0;
  double worst_sample_usage = 0.0;       ///< largest value / limit over every sample checked
  double check_rate_hz = 0.0;            ///< the rate of the last sample check [Hz]
  /// |T(N) - T(N / 2)| [s]: the duration against that of the same programme (limits and
  /// tightenings) on every second grid point, an estimate of its error from the grid.
  double duration_grid_error = 0.0;
};

/// What the rounds of a jerk-limited timing ask of the motion they time.
struct JerkRoundHooks {
  /// Makes (and keeps) the motion of the portions' profiles, in order.
  std::function<core::Expected<void>(const std::vector<core::SpeedProfile>&)> assemble;
  /// Checks the samples of the motion last assembled against `limits` (the real ones,
  /// jerk included); the factors refer to the grids the rounds were given.
  std::function<core::Expected<core::SampleCheck>(const core::TimeOptimalLimits& limits)> check;
};

/// The outcome of jerk_limited_rounds (the fields of JerkLimitedPlan but the motion).
struct JerkRounds {
  std::vector<JerkTiming> portions;
  OptimizerReport report;
  int refinements = 0;
  double slowed_by = 1.0;
  double worst_sample_usage = 0.0;
  double check_rate_hz = 0.0;
  double duration_grid_error = 0.0;
};

/// The jerk-limited timing of any motion along a parameterised path, portion by portion,
/// from its exact sweep (`grids`, `exact` solutions under `exact_limits`): the NLP on every
/// portion within the limits shrunk by kJerkLimitMargin (options.joint_jerk, max_jerk: the
/// real jerk limits, speedScale applied), the motion assembled and its samples checked
/// (hooks), the grid points around any excess tightened (core::tighten_limits) and the NLP
/// run again from its last result, at most options.max_refinements times; still broken,
/// the last result slowed uniformly by the worst usage (at most three times). What
/// plan_time_optimal_jerk does for a Cartesian path and the joint paths' timing for theirs.
/// Errors: the hooks'; `motion` when the samples still break a limit after the slow-down,
/// or once options.stop or `exact_stop` is requested.
core::Expected<JerkRounds> jerk_limited_rounds(const std::vector<std::vector<core::GridPoint>>& grids,
                                               const std::vector<core::TimeOptimalSolution>& exact,
                                               const core::TimeOptimalLimits& exact_limits, JerkTimingOptions options,
                                               const std::stop_token& exact_stop, const JerkRoundHooks& hooks);

/// The exact plan's options under a jerk-limited one: 200 grid intervals per portion (the
/// NLP's cost grows with the grid: 4 ms at 100 points, 62 ms at 1,000), the rest as
/// core::TimeOptimalOptions.
inline core::TimeOptimalOptions jerk_exact_options() {
  core::TimeOptimalOptions options;
  options.grid_intervals = 200;
  return options;
}

/// plan_time_optimal, then optimise_jerk_timing on every portion with the robot's
/// JointLimits::max_jerk (where given) and spec.max_jerk, scaled by speedScale^3, each
/// portion's profile smoothed (JerkTiming::profile: zero acceleration at the rests, finite
/// jerk); then, as plan_time_optimal does for the sweep, every sample at the cycle rate and
/// at the check rate (exact_options.check_rate_hz) is checked against the joint velocity,
/// acceleration and jerk limits, the centripetal limit and maxJerk
/// (core::check_time_optimal_samples: the jerk as the difference of successive
/// accelerations over the period) and, where one breaks a limit, the limits at that
/// interval's grid points are tightened (JerkTimingOptions::limit_scale, jerk_scale) and the
/// NLP runs again from its last result, at most options.max_refinements times; if a sample
/// still breaks a limit by the ratio r, the last result is slowed uniformly r times
/// (core::time_scaled: velocities 1 / r, accelerations 1 / r^2, jerks 1 / r^3), checked
/// again, and JerkLimitedPlan::slowed_by and the report's message say so.
/// Guarantee: every sample at the cycle rate and at the check rate within every limit to
/// exact_options.sample_tolerance, the jerk included (so a controller differentiating the
/// accelerations at any rate dividing the check rate sees at most the limit: the mean of
/// the jerk over a period is a mean of the checked ones); maxSpeed everywhere.
/// Errors: plan_time_optimal's; `motion` when the samples still break a limit after the
/// slow-down, or the IK fails at a sample; `motion` "stopped" once options.stop (or
/// exact_options.stop) is requested: checked between the steps and every 256 samples of the
/// sample check, so a degenerate limit (maxJerk 1e-10 m/s^3: a motion of hours) ends at the
/// call's deadline or cancellation.
core::Expected<JerkLimitedPlan> plan_time_optimal_jerk(const core::Path& path,
                                                       const core::OrientationPlan& orientation,
                                                       const core::MotionSpec& spec, const core::RobotModel* robot,
                                                       const core::JointVector& seed,
                                                       const core::TimeOptimalOptions& exact_options = jerk_exact_options(),
                                                       JerkTimingOptions options = {});

}  // namespace geotraj::optim
