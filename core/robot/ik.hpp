// Inverse kinematics of a serial arm (thesis 6.4: every Cartesian sample goes through the
// arm's IK) and the joint-space motion that follows a Cartesian one, sample by sample.
//
// Method (docs/kinematics.md): Newton-Raphson on the 6-D pose error in W,
//   e = [p_target - p_WT(q); r(R_target R_WT(q)^T)]   ([m; rad]),
// r(R) the rotation vector (angle in [0, pi] times the unit axis), with the geometric
// Jacobian J of kinematics.hpp (Eqs. 1.8-1.9) and minimum-norm steps
//   dq = J^T (J J^T + lambda^2 I)^-1 e,
// J J^T a fixed-size 6 x 6 matrix factored by Cholesky (no heap allocation). lambda = 0 away
// from singularities; only where the smallest Cholesky pivot of J J^T falls below 1e-8
// (sigma_min ~ 1e-4 on a ~1 m arm) is the step damped, lambda^2 = 1e-8 (1 - p_min / 1e-8)^2,
// continuous at the threshold. Each step is scaled so that no joint moves more than
// IkOptions::max_step, then projected onto the position limits; a joint at a limit whose
// step points outwards is held there for that step (its column is dropped from J J^T), so
// the others, through the remaining freedom, finish the solve. A step that increases
// |e|^2 (m^2 + rad^2) is halved, up to 4 times, then taken anyway (far from the solution,
// where the linearisation fails; never while tracking). Converged when
// |position error| <= 1e-9 m and |orientation error| <= 1e-9 rad (defaults). Near the
// solution the convergence is quadratic: one or two steps from a good predictor.
//
// For a redundant arm (n > 6) the self-motion while tracking is chosen in joint_motion.hpp
// (a null-space term that keeps joints away from their limits); a cold solve returns the
// solution that the minimum-norm Newton steps reach from the seed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/robot/robot.hpp"

namespace geotraj::core {

/// Tolerances and budgets of the IK (Ceres-style options value).
struct IkOptions {
  double position_tolerance = 1e-9;     ///< [m], on |p_target - p_WT|
  double orientation_tolerance = 1e-9;  ///< [rad], on the angle of R_target R_WT^T
  int max_iterations = 100;             ///< Newton iterations per solve (per restart)
  /// Restarts from random configurations within the limits when a cold solve (solve_ik,
  /// or JointTracker's first sample) fails from the seed; 0 = none. Deterministic: uniform
  /// in the limits from a SplitMix64 stream seeded with restart_seed, the same on every
  /// platform and call.
  int restarts = 0;
  std::uint64_t restart_seed = 0x6765'6f74'7261'6a00ULL;
  /// Largest change of one joint in one Newton step [rad or m]: a trust region for cold
  /// solves from far seeds (the linearisation holds for a fraction of a radian); never
  /// binding while tracking, where the corrections are ~1e-7.
  double max_step = 0.5;
  /// JointTracker, redundant arms (n > 6): gain k [rad^2/m] of the joint-limit avoidance in
  /// the null space, z = -k |v_WT| grad H(q) with H = sum_i ((q_i - mid_i) / range_i)^2
  /// (joint_motion.hpp). 0: pure minimum-norm (q_dot = J^+ [v; omega]).
  double limit_avoidance_gain = 1.0;
};

/// The outcome of one IK solve (a report, not an exception).
struct IkResult {
  JointVector q;                  ///< the joint values [rad or m]
  bool converged = false;         ///< both tolerances met
  int iterations = 0;
  double position_error = 0.0;     ///< |p_WT(q) - p_target| [m]
  double orientation_error = 0.0;  ///< angle of R_WT(q)^T R_target [rad]
  bool within_limits = false;      ///< every joint within its position limits
};

/// Solves X_WT(q) = X_WT_target from `seed` (position and orientation) by the projected
/// Newton iteration above; with options.restarts > 0 and a failure from the seed, restarts
/// from random configurations within the limits (the best attempt is returned when none
/// converges). The result is always within the position limits (the seed is first
/// clamped into them; a revolute joint whose range spans 2 pi or more is moved by 2 pi
/// back inside when it leaves it, any other is held at the limit).
/// Needs n >= 6 joints: with fewer, a general pose has no solution and the result is
/// `converged = false` at the seed, with the seed's errors (no iteration).
/// Precondition (checked): seed.size() == model.dof(), the model is valid (validate_robot).
IkResult solve_ik(const RobotModel& model, const Eigen::Isometry3d& X_WT_target, const JointVector& seed,
                  const IkOptions& options = {});

/// A search of the whole joint range for the joints of a tool pose (the kinematics call,
/// the goal of a move): Newton attempts from the seed, then from configurations uniform
/// within the position limits (SplitMix64 from newton.restart_seed: the same on every
/// platform and call). docs/kinematics.md has the measured success rates and times.
struct IkSearchOptions {
  /// Tolerances and trust region of every attempt; newton.max_iterations bounds one attempt
  /// (newton.restarts is not read: max_attempts counts them).
  IkOptions newton = [] {
    IkOptions o;
    o.max_iterations = 20;
    return o;
  }();
  /// Attempts in all, the seed's included (>= 1): 1 is a seeded solve.
  int max_attempts = 256;
  /// Go on after the first solution, through every attempt, and collect the distinct ones
  /// (the branches: the UR5's eight, the PA-10's elbow and wrist flips and its self-motion).
  bool all_solutions = false;
  /// The most solutions kept (all_solutions), the nearest the seed.
  std::size_t max_solutions = 16;
  /// Two solutions are one when every joint differs by less than this [rad or m], modulo
  /// 2 pi on a revolute joint whose range spans 2 pi (both are the same arm pose then).
  double distinct_tolerance = 1e-3;
  /// Asked every 64 attempts: true ends the search there (a caller's deadline or
  /// cancellation; IkSearchResult::stopped says so).
  std::function<bool()> stopped;
};

/// What an IK search found.
struct IkSearchResult {
  /// Converged within the limits, distinct, nearest the seed first (the distance is the
  /// Euclidean norm of q - seed, each joint whose range spans 2 pi at its representative
  /// nearest the seed). Empty when the pose is out of reach.
  std::vector<IkResult> solutions;
  /// With no solution: the joints whose pose comes closest to the target, a local minimum
  /// of |e|^2 = |p error|^2 + |orientation error|^2 (m^2 + rad^2: 1 rad of the tool's turn
  /// weighs as 1 m) within the limits, refined from the best attempts by Levenberg-Marquardt.
  /// With a solution: the first one.
  IkResult closest;
  int attempts = 0;    ///< attempts made
  int iterations = 0;  ///< Newton (and refinement) iterations in all
  bool stopped = false;  ///< options.stopped ended the search
};

/// Searches for X_WT(q) = X_WT_target (see IkSearchOptions). Stops at the first solution
/// unless options.all_solutions. Needs n >= 6 joints (with fewer the search reports the
/// closest pose only). Preconditions (checked): seed.size() == model.dof(), a valid model,
/// max_attempts >= 1, max_solutions >= 1.
IkSearchResult search_ik(const RobotModel& model, const Eigen::Isometry3d& X_WT_target, const JointVector& seed,
                         const IkSearchOptions& options = {});

/// The closest pose to `X_WT_target` from `start` (within the limits, clamped there): the
/// Levenberg-Marquardt refinement search_ik ends with when nothing converges, alone: a local
/// minimum of |e|^2 = |p error|^2 + |orientation error|^2 [m^2 + rad^2], steps
/// dq = J^T (J J^T + mu I)^-1 e projected onto the limits, mu x4 on a rejected step and / 3 on
/// an accepted one, at most max_iterations (>= 1). converged: within options' tolerances.
/// Preconditions (checked): start.size() == model.dof(), a valid model.
IkResult closest_pose(const RobotModel& model, const Eigen::Isometry3d& X_WT_target, const JointVector& start,
                      int max_iterations = 200, const IkOptions& options = {});

}  // namespace geotraj::core
