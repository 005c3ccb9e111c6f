// The kinematics calls of the application layer: the forward kinematics of a configuration
// and the inverse kinematics of a pose (core/robot/kinematics.hpp, core/robot/ik.hpp), on
// the request's robot (a catalog model or an inline one, with its base and tool), under the
// call's budget. The wire layer converts and checks the requests (server/wire/convert.hpp).
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "planner/planner.hpp"
#include "planner/robot_spec.hpp"

namespace geotraj::planner {

/// ComputeForwardKinematics, converted.
struct ForwardRequest {
  std::shared_ptr<const Robot> robot;
  core::JointVector joints;  ///< one per joint [rad or m]
};

/// The forward kinematics of one configuration.
struct Forward {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< X_WT
  core::JointJacobian jacobian;  ///< 6 x n, rows [v; omega] in W (Eqs. 1.8-1.9)
  double manipulability = 0.0;   ///< sqrt(det(J J^T))
  double min_singular_value = 0.0;
  double max_singular_value = 0.0;
  std::vector<core::JointAxis> axes;  ///< joint 0 first
  bool within_limits = false;         ///< every joint within its position limits
};

/// ComputeInverseKinematics, converted: the robot (its seed: Robot::seed), the target and
/// the search's options.
struct InverseRequest {
  std::shared_ptr<const Robot> robot;
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();  ///< X_WT to reach
  core::IkSearchOptions search;
};

/// One configuration the IK found, with what a caller checks of it.
struct IkSolution {
  core::JointVector joints;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< FK of `joints`
  double position_error = 0.0;     ///< [m]
  double orientation_error = 0.0;  ///< [rad]
  double distance_from_seed = 0.0;
  double manipulability = 0.0;
};

/// The inverse kinematics of one pose.
struct Inverse {
  std::vector<IkSolution> solutions;  ///< nearest the seed first; empty: out of reach
  std::optional<IkSolution> closest;  ///< out of reach: the closest pose the arm reaches
  int attempts = 0;
  int iterations = 0;
  bool reachable() const { return !solutions.empty(); }
};

/// ComputeForwardKinematics as given, with what the wire could not read.
struct ForwardInput {
  std::optional<RobotSpec> robot;
  std::vector<double> joints;  ///< [rad or m]
  core::Violations violations;
};

/// ComputeInverseKinematics as given: the search's options already read within the server's
/// ranges; with what the wire could not read.
struct InverseInput {
  std::optional<RobotSpec> robot;
  std::optional<Eigen::Isometry3d> target;  ///< X_WT
  core::IkSearchOptions search;
  core::Violations violations;
};

/// The largest |coordinate| of an IK target [m], as for a key frame (core::PathLimits).
inline constexpr double kMaxTargetCoordinate = 1e6;

/// `input` admitted, or every violation together (the wire's first): `robot` (required;
/// resolved against `catalog` without acceleration limits, a URDF parsed within `stop_at`),
/// `joints` (one per joint, finite, magnitude at most core::kMaxModelMagnitude).
core::Expected<ForwardRequest> admit(ForwardInput input, const RobotCatalog& catalog, const StopAt& stop_at = {});

/// `input` admitted, or every violation together: `robot` as above, `target` (required, within
/// kMaxTargetCoordinate of the origin).
core::Expected<InverseRequest> admit(InverseInput input, const RobotCatalog& catalog, const StopAt& stop_at = {});

/// The forward kinematics of `request` (a valid robot, one value per joint).
Forward forward_kinematics(const ForwardRequest& request);

/// The inverse kinematics of `request` within `budget` (checked every 64 attempts): kStopped
/// or kDeadlineExceeded when it ran out.
Expected<Inverse> inverse_kinematics(const InverseRequest& request, const Budget& budget);

}  // namespace geotraj::planner
