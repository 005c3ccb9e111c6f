// A request's robot as the client gives it (RobotSpec in the API, already translated from its
// wire form), and its resolution into the planner's Robot: a model found by name in the
// server's catalogue, an inline model checked, or a URDF document read; then the request's
// joint limits by joint name, its base and tool, its limit scales, tolerances and initial
// joints, each checked. Every violation names the request's field (`robot.name`,
// `robot.jointLimits[1].maxVelocity`, `robot.model.limits[2].minPosition`, `robot.urdf`).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/robot/robot.hpp"
#include "planner/planner.hpp"
#include "planner/robots.hpp"

namespace geotraj::planner {

/// The robot models a server knows by name: the built-in ones and those loaded from files
/// (`geotrajd --robot-model`), each checked once where it entered. A request that names one
/// and changes nothing of it shares it as it is.
struct RobotCatalog {
  std::vector<core::ValidRobot> models;
  const core::ValidRobot* find(std::string_view name) const;
};

/// A model of the catalogue, by name (RobotSpec.name).
struct RobotByName {
  std::string name;
};

/// A model written in the request (RobotSpec.model), as read from its wire form and not yet
/// validated; nullopt when its wire form could not be read (the wire reported why), so that
/// the rest of the robot is still checked and every violation answered at once.
struct InlineRobot {
  std::optional<core::RobotModel> model;
  /// The field that wrote its chain (`robot.model.joints` or `robot.model.links`): where a
  /// rule about its joints points.
  std::string chain_field = "robot.model.joints";
};

/// A URDF document (RobotSpec.urdf), with RobotSpec.baseLink and tipLink.
struct UrdfRobot {
  std::string urdf;
};

/// Where the model comes from; std::monostate: the request gave none.
using RobotSource = std::variant<std::monostate, RobotByName, InlineRobot, UrdfRobot>;

/// RobotSpec as the request gives it. Values are unchecked: resolve_robot checks them.
struct RobotSpec {
  RobotSource source;
  std::string base_link, tip_link;                  ///< read with a URDF only
  std::vector<NamedLimits> joint_limits;            ///< over the model's, by joint name
  std::optional<Eigen::Isometry3d> base;            ///< X_WB over the model's
  std::optional<Eigen::Isometry3d> tool;            ///< X_FT over the model's
  bool report_only = false;
  /// The tool's roll about its z axis is a free choice (a tool symmetric about its axis).
  bool tool_axis_free = false;
  std::optional<double> branch_tolerance;           ///< [m]
  std::optional<double> start_position_tolerance;   ///< [m]
  std::optional<double> start_orientation_tolerance;  ///< [rad]
  Approach approach = Approach::kNone;
  std::optional<double> velocity_scale;             ///< a fraction in (0, 1] of every maxVelocity
  std::optional<double> acceleration_scale;         ///< of every maxAcceleration and maxJerk
  std::vector<double> initial_joints;               ///< [rad or m]; empty: the model's home
  std::optional<core::Payload> payload;             ///< on the tool; needs mass properties
  std::string joint_limits_yaml;                    ///< MoveIt's joint_limits.yaml; under joint_limits
};

/// `spec` resolved against `catalog`, or every violation of it together. `motion`: false for
/// the kinematics calls, which read no acceleration limit (a URDF without them is accepted
/// there). A URDF's parse gives up once `stop_at` is reached (UrdfOptions), with a violation
/// of `robot.urdf`. The model it makes is checked once, here (core::ValidRobot). An inline
/// model the wire could not read (InlineRobot without one) adds no violation of its own: the
/// wire named it. Thread-safe.
core::Expected<Robot> resolve_robot(const RobotSpec& spec, const RobotCatalog& catalog, bool motion = true,
                                    const StopAt& stop_at = {});

}  // namespace geotraj::planner
