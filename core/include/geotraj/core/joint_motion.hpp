// The joint-space motion of an arm that follows a Cartesian motion (thesis 6.4), one sample
// at a time: joint positions by warm-started IK (ik.hpp), joint velocities and
// accelerations from the Cartesian ones through the Jacobian and the second-order term
// (Eqs. 1.8-1.11, never finite differences), and the certificates a user needs before
// streaming to a controller: IK residuals, the deviation of joint interpolation between
// samples, manipulability, joint-limit margins.
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geotraj/core/ik.hpp"
#include "geotraj/core/robot.hpp"

namespace geotraj::core {

/// The tool's Cartesian state at one sample, in W: pose X_WT, velocity and acceleration of
/// its origin [m/s, m/s^2], angular velocity and acceleration [rad/s, rad/s^2].
struct CartesianState {
  double t = 0.0;  ///< [s]
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_WT = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_WT = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_WT = Eigen::Vector3d::Zero();
  Eigen::Vector3d alpha_WT = Eigen::Vector3d::Zero();
};

/// One joint-space sample.
struct JointSample {
  JointVector q;      ///< [rad or m]
  JointVector q_dot;  ///< [rad/s or m/s]
  JointVector q_ddot; ///< [rad/s^2 or m/s^2]
  bool converged = false;
  int iterations = 0;
  double position_error = 0.0;     ///< IK residual [m]
  double orientation_error = 0.0;  ///< IK residual [rad]
  double manipulability = 0.0;     ///< sqrt(det(J J^T)) at q
  /// |p_WT((q_prev + q) / 2) - (p_prev + p) / 2| [m]: how far linear joint interpolation
  /// between the previous sample and this one strays from the Cartesian chord (0 for the
  /// first sample). Large values mean a branch change or a singularity.
  double midpoint_deviation = 0.0;
};

/// Follows a Cartesian motion sample by sample (a reusable workspace: no heap allocation per
/// sample). The first call solves from `q_seed` (the branch seed, e.g. the request's
/// initialJoints or the model's home) with IkOptions::restarts allowed; later calls
/// warm-start from the previous sample and stay on its branch.
/// Redundant arms: documented null-space choice (docs/kinematics.md), the same in positions
/// and in velocities/accelerations, so q_dot matches finite differences of q.
/// Joint velocities: J q_dot = [v; omega]; accelerations: J q_ddot = [a; alpha] - J_dot q_dot
/// (1.8-1.11), minimum-norm plus the null-space term.
class JointTracker {
 public:
  /// `model` must outlive the tracker and be valid (validate_robot); q_seed.size() == dof.
  JointTracker(const RobotModel& model, const JointVector& q_seed, const IkOptions& options = {});
  /// Computes the joint sample for `x` (the next sample in time order) into `out`;
  /// returns out.converged. After a failure the tracker keeps the last good configuration.
  bool track(const CartesianState& x, JointSample& out);
  /// Starts again from a new seed (the next track() is a first call).
  void reset(const JointVector& q_seed);

 private:
  const RobotModel* model_;
  IkOptions options_;
  JointVector seed_;
  JointVector q_prev_;
  Eigen::Vector3d p_prev_ = Eigen::Vector3d::Zero();
  bool first_ = true;
};

/// Which limit an event is about.
enum class LimitKind {
  kPosition,      ///< joint position outside [minPosition, maxPosition]
  kVelocity,      ///< |q_dot| > maxVelocity
  kAcceleration,  ///< |q_ddot| > maxAcceleration
  kIk,            ///< the IK did not converge (value: position error [m])
  kBranch,        ///< midpoint deviation above the tolerance (a branch change or singularity)
};

/// One joint-limit event of a motion: where a limit is broken, or how close it comes.
struct LimitEvent {
  LimitKind kind = LimitKind::kPosition;
  std::size_t joint = 0;   ///< zero-based joint (0 for kIk / kBranch)
  std::size_t sample = 0;  ///< zero-based sample index
  double t = 0.0;          ///< [s]
  double value = 0.0;      ///< the joint value / |velocity| / |acceleration| (or the error)
  double limit = 0.0;      ///< the limit it is compared with
  /// kPosition: distance to the nearer position limit [rad or m] (negative outside);
  /// kVelocity, kAcceleration: limit - |value|; kIk, kBranch: tolerance - value.
  double margin = 0.0;
};

/// How one joint is used over a motion.
struct JointUsage {
  double min_position = std::numeric_limits<double>::infinity();
  double max_position = -std::numeric_limits<double>::infinity();
  double peak_velocity = 0.0;      ///< max |q_dot| [rad/s or m/s]
  double peak_acceleration = 0.0;  ///< max |q_ddot| [rad/s^2 or m/s^2]
  double velocity_usage = 0.0;     ///< peak_velocity / maxVelocity
  double acceleration_usage = 0.0; ///< peak_acceleration / maxAcceleration
  double position_margin = std::numeric_limits<double>::infinity();  ///< smallest distance to a position limit
};

/// The joint-space report of a whole motion (what PlanTrajectory returns with a robot).
struct JointMotionReport {
  std::size_t samples = 0;
  std::vector<JointUsage> joints;
  LimitEvent tightest_position;      ///< smallest position margin, its joint and time
  LimitEvent tightest_velocity;      ///< smallest velocity margin
  LimitEvent tightest_acceleration;  ///< smallest acceleration margin
  double max_position_error = 0.0;     ///< worst IK residual [m]
  double max_orientation_error = 0.0;  ///< worst IK residual [rad]
  double max_midpoint_deviation = 0.0; ///< worst JointSample::midpoint_deviation [m]
  double max_midpoint_deviation_t = 0.0;
  double min_manipulability = std::numeric_limits<double>::infinity();
  double min_manipulability_t = 0.0;
  /// Every broken limit, the first sample of each (joint, kind) run only, in time order
  /// (bounded: at most one event per joint and kind).
  std::vector<LimitEvent> violations;
  bool feasible() const { return violations.empty(); }
};

/// Accumulates a JointMotionReport sample by sample (O(joints) memory, whatever the
/// motion's length). `branch_tolerance` [m] bounds midpoint_deviation.
class JointReportBuilder {
 public:
  explicit JointReportBuilder(const RobotModel& model, double branch_tolerance = 1e-3);
  void add(std::size_t sample, double t, const JointSample& s);
  const JointMotionReport& report() const { return report_; }

 private:
  const RobotModel* model_;
  double branch_tolerance_;
  JointMotionReport report_;
};

}  // namespace geotraj::core
