// Whole-path redundancy resolution: the joint trajectory of an arm along a timed tool
// motion chosen as one sparse nonlinear least-squares problem (Ceres Solver), instead of
// sample by sample. Where the arm has more joints than the pose needs (the PA-10's seventh),
// the self-motion is a free choice at every sample; chosen per sample (joint_motion.hpp's
// null-space term) it is blind to what the next samples need, chosen over the whole motion
// it can spread what the joints must do.
//
// Problem. Unknowns: the joints q_k [rad or m] at the samples t_k = k dt, k = 1 .. K (q_0,
// where the robot stands, is held), each on the manifold of the joints that hold its pose:
// a step moves along J(q_k)'s null space (n - 6 coordinates per sample) and the IK's Newton
// projection brings it back onto the pose, within the position limits; so every iterate
// holds every pose, and the optimum is polished by the IK to 1e-12. Residuals, each scaled to
// be dimensionless (rests beyond both ends: the motion starts and ends at rest):
//   velocity   w_v (q_{k+1} - q_k) / (dt v_max)                (per joint)
//   accel.     w_a (q_{k+1} - 2 q_k + q_{k-1}) / (dt^2 a_max)
//   jerk       w_j (q_{k+2} - 3 q_{k+1} + 3 q_k - q_{k-1}) / (dt^3 j_max)
//   range      w_r (q_k - mid) / range                         (the distance to the limits)
//   manip.     w_m m_0 / m(q_k)                                (Yoshikawa's m = sqrt(det J J^T),
//              m_0 the first sample's: larger is better)
//   goal       w_g (q_K - q_goal) / range                      (closeness to given joints)
// Weights are the user's (RedundancyWeights); the
// objective reported is 1/2 the sum of the squared criteria residuals.
// The joints' velocity, acceleration and jerk limits are constraints: a least-squares optimum
// spreads the usage but keeps peaks, so where the joints break a limit (the usage u of a
// derivative, measured on the C2 spline the samples follow, above 0.98), every difference of
// a derivative used beyond 0.8 gets the term lambda (u / 0.93)^8 (nothing well below 0.93,
// steep above): from the first solve where the given joints break a limit by less than 2x,
// else on the least-squares optimum that does, solved again from the lower peak of the optimum and the
// start. lambda x4 a round, until every usage is within 0.98, or 8 rounds, or a round that
// lowers the peak by less than 0.5 % (limits the motion's timing puts beyond the self-motion's
// reach: the report's message says so); the rounds' lowest peak is kept. An optimum is taken
// over the start when it breaks the limits by less, or as little with a lower objective
// (without the limits as constraints: when its objective is lower).
// Solved by Levenberg-Marquardt with a sparse normal-equations Cholesky: the Jacobian is
// banded (a sample couples with its three neighbours at most).
#pragma once

#include <algorithm>
#include <functional>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/robot/robot.hpp"
#include "optim/common/report.hpp"

namespace geotraj::optim {

/// The largest weight: the criteria are dimensionless and weigh against each other, so
/// only ratios matter; beyond it the residuals of a long motion would overflow.
inline constexpr double kMaxRedundancyWeight = 1e6;

/// What the free choices serve (each in [0, kMaxRedundancyWeight], at least one > 0).
struct RedundancyWeights {
  double joint_range = 0.0;     ///< away from the position limits
  double velocity = 0.0;        ///< joint velocity per its limit
  double acceleration = 0.0;    ///< joint acceleration per its limit
  double jerk = 0.0;            ///< joint jerk per its limit (joints with one)
  double manipulability = 0.0;  ///< away from singularities
};

struct RedundancyOptions {
  RedundancyWeights weights;
  /// Joints the motion should end near (closeness weighted by goal_weight), or none.
  std::optional<core::JointVector> goal;
  double goal_weight = 1.0;
  /// The motion ends at `goal` exactly (it must reach the last pose): the last sample is held
  /// there like the first, and the start's self-motion is ramped towards it (a straight line
  /// to goal joints on a redundant arm). Its initial joints may end elsewhere on that pose;
  /// the optimum is taken whenever it reaches every pose.
  bool hold_goal = false;
  /// The joints' velocity, acceleration and jerk limits as constraints (the penalty
  /// rounds above; an optimum that breaks them more than the start is not taken); false: the
  /// least-squares optimum alone, taken when its objective is lower (for a caller that times
  /// the motion again along it).
  bool within_limits = true;
  /// The limits held, in (0, 1]: velocity x c, acceleration x c^2, jerk x c^3 (the limits of
  /// the same path 1 / c times faster: a caller that times the motion again along the joints
  /// chosen asks for room to speed up). The peaks reported are usages of these.
  double limit_scale = 1.0;
  /// The optimum is taken whenever it reaches every pose (a caller that judges it itself:
  /// the planner times the motion again along it and keeps the faster).
  bool take_optimum = false;
  int max_iterations = 400;
  double time_budget_s = 10.0;
  /// Asked between iterations: true ends the solve there (deadline, cancellation).
  std::function<bool()> stopped;
};

/// The largest usage of the joints' limits (1 at the limit) by differences of the joints at
/// the step dt, with rests beyond both ends; 0 for jerk when no joint has a jerk limit.
struct Peaks {
  double velocity = 0.0;
  double acceleration = 0.0;
  double jerk = 0.0;
  double worst() const { return std::max({velocity, acceleration, jerk}); }
};

struct RedundancyResult {
  std::vector<core::JointVector> q;  ///< one per pose, q[0] the start's
  OptimizerReport report;            ///< objective: 1/2 sum of squared criteria residuals
  Peaks peaks;                       ///< of q
  int rounds = 0;                    ///< penalty rounds that weighed the peaks beyond the limits
  double worst_position_error = 0.0;     ///< after the IK's polish [m]
  double worst_orientation_error = 0.0;  ///< [rad]
};

/// The joints along `poses` (X_WT at t_k = k dt [s], at least 2) from `initial` (one per
/// pose, within the limits, each reaching its pose: the sample-by-sample solution), q_0 held.
/// Errors name the field: `weights` (negative, or all 0), `dt`, `initial` (size, joints
/// not reaching their pose), `goal` (size; held but absent or not reaching the last pose),
/// `robot` (6 joints or fewer: no self-motion).
core::Expected<RedundancyResult> optimize_redundancy(const core::ValidRobot& robot,
                                                     const std::vector<Eigen::Isometry3d>& poses, double dt,
                                                     const std::vector<core::JointVector>& initial,
                                                     const RedundancyOptions& options);

/// The criteria objective of a joint trajectory (what RedundancyResult::report compares):
/// 1/2 the sum of the squared criteria residuals above, without the pose's.
double redundancy_objective(const core::RobotModel& model, const std::vector<core::JointVector>& q, double dt,
                            const RedundancyOptions& options);

}  // namespace geotraj::optim
