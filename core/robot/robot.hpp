// Serial manipulators described by Denavit-Hartenberg parameters (thesis 1.1.2, Eq. 1.3;
// Table 6.1's manipulator parameters): the immutable model that kinematics.hpp, ik.hpp and
// joint_motion.hpp work on. Units: metres and radians (a prismatic joint's value is in
// metres); limits per joint in [rad] or [m], per second, per second squared.
//
// With joint values q the tool pose in the world frame W is
//   X_WT = base * A_1(q_1) * ... * A_n(q_n) * tool,
// where each link transform A_i is
//   modified DH (Craig; the thesis's Eq. 1.3): A_i = RotX(alpha_i) TransX(a_i) RotZ(theta_i*) TransZ(d_i*)
//     (row i holds alpha_{i-1}, a_{i-1} of Eq. 1.3: the twist and length BEFORE joint i),
//   standard DH:                               A_i = RotZ(theta_i*) TransZ(d_i*) TransX(a_i) RotX(alpha_i),
// with theta_i* = theta_i + offset_i + q_i and d_i* = d_i for a revolute joint, and
// theta_i* = theta_i, d_i* = d_i + offset_i + q_i for a prismatic one.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"

namespace geotraj::core {

/// Most joints a model may have: joint-space values are fixed-capacity Eigen vectors, so
/// the sampling loop never allocates.
inline constexpr std::size_t kMaxJoints = 12;

/// Joint values, velocities or accelerations [rad or m, per s, per s^2], one per joint.
using JointVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, static_cast<int>(kMaxJoints), 1>;
/// A 6 x n matrix whose rows are (linear [m], angular [rad]) and columns joints.
using JointJacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::ColMajor, 6, static_cast<int>(kMaxJoints)>;
/// A spatial vector: linear part (rows 0-2) then angular part (rows 3-5), in W.
using Vector6d = Eigen::Matrix<double, 6, 1>;

enum class DhConvention {
  kModified,  ///< Craig's convention, the thesis's Eq. (1.3)
  kStandard,  ///< the classic (distal) convention
};

enum class JointType { kRevolute, kPrismatic };

/// One row of the DH table (proto DhLink). Lengths [m], angles [rad].
struct DhLink {
  double a = 0.0;
  double alpha = 0.0;
  double d = 0.0;
  double theta = 0.0;
  JointType type = JointType::kRevolute;
  double offset = 0.0;  ///< added to theta (revolute) [rad] or d (prismatic) [m] with q
  /// The joint's name for people ("S1", "shoulder_pan"); joints are numbered from 0 at the
  /// base everywhere, the name says which one that is. Empty: none. At most kMaxJointName bytes.
  std::string name{};
};

/// The longest joint name [bytes].
inline constexpr std::size_t kMaxJointName = 64;

/// The largest |length| of a model (a, d, offset [m]) and |joint value| (position limits,
/// joint values given to the kinematics [rad or m]): far beyond any arm, and small enough
/// that no pose, Jacobian or manipulability of 12 joints overflows.
inline constexpr double kMaxModelMagnitude = 1e6;

/// One joint's limits (proto JointLimits).
struct JointLimits {
  double min_position = 0.0;   ///< [rad or m]
  double max_position = 0.0;   ///< [rad or m], >= min_position
  double max_velocity = 0.0;   ///< [rad/s or m/s], > 0
  double max_acceleration = 0.0;  ///< [rad/s^2 or m/s^2], > 0
  std::optional<double> max_jerk;  ///< [rad/s^3 or m/s^3], > 0; absent: unlimited
};

/// A serial arm. A value: copy it to change it (base and tool of a request replace the
/// model's own).
struct RobotModel {
  std::string name;
  std::string description;  ///< manufacturer, source of the parameters
  DhConvention convention = DhConvention::kModified;
  std::vector<DhLink> links;        ///< one per joint, base outwards
  std::vector<JointLimits> limits;  ///< one per joint
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();  ///< X_W,base: robot base in W
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();  ///< X_n,T: tool in the last link's frame
  /// The home configuration [rad or m] (the IK seed of a request without initialJoints);
  /// within the limits. Empty means all zeros.
  std::vector<double> home;

  std::size_t dof() const { return links.size(); }
};

/// Every problem with `model` (field paths relative to the model, proto JSON names):
/// `links` (none, or more than kMaxJoints), `limits` (not one per link), `links[i].a` ...
/// not finite, `limits[i].minPosition` > maxPosition, `limits[i].maxVelocity` <= 0 or not
/// finite, `limits[i].maxAcceleration`, `limits[i].maxJerk`, `base.orientation` /
/// `tool.orientation` not a rotation, `home` of the wrong size or outside the limits.
/// Empty when the model is usable.
Violations validate_robot(const RobotModel& model);

/// The built-in models, in a fixed order: "pa10" (Mitsubishi PA-10, 7 DOF, the thesis's
/// demonstration arm, modified DH) and "ur5" (Universal Robots UR5, 6 DOF, standard DH).
/// Each model's `description` cites where its parameters come from.
const std::vector<RobotModel>& builtin_robots();

/// The built-in model called `name`, or nullptr.
const RobotModel* find_builtin_robot(std::string_view name);

/// The model's home configuration as a JointVector (zeros when `home` is empty).
JointVector home_configuration(const RobotModel& model);

/// The model with its joint limits overridden for one motion (the thesis's SpeedScale, Table
/// 6.2, per limit; MoveIt's velocity and acceleration scaling factors): every maxVelocity
/// times `velocity`, every maxAcceleration and maxJerk times `acceleration`, both in (0, 1]
/// (checked by the caller). Position limits are unchanged.
RobotModel with_scaled_limits(RobotModel model, double velocity, double acceleration);

}  // namespace geotraj::core
