// The robots the service knows: the built-in arms (core's DH models and the URDF files in
// planner/models/, compiled in) and arms described in URDF by the user (RobotSpec.urdf,
// `geotrajd --robot-model arm.urdf`). docs/kinematics.md, "Bring your own URDF".
//
// A URDF document becomes a core::RobotModel (core/robot/robot.hpp) through urdfdom:
//  - the chain runs from the base link (default: the root) to the tip link (default: the
//    leaf below the base reached through the most moving joints, a maker's tool0 beside its
//    `base` frame; several such leaves, a hand's fingers, are an error that lists them);
//    links and joints off that chain are ignored;
//  - each revolute, continuous or prismatic joint on it is one joint of the model: its
//    <origin> (xyz [m], rpy [rad], roll-pitch-yaw about fixed x, y, z) with the fixed joints
//    since the previous moving joint folded in, and its <axis> (normalised; default x, as
//    URDF says); fixed joints after the last moving joint make the flange;
//  - position and velocity limits come from <limit> (a continuous joint's position is
//    unbounded); floating and planar joints and mimic joints on the chain are refused,
//    naming the joint;
//  - URDF has no acceleration or jerk limits and no home pose: a <geotraj> element beside
//    the links gives them, one <joint name=".." max_acceleration=".." max_jerk=".." home=".."/>
//    per moving joint (max_jerk optional; home default 0, or the middle of the range when 0 is
//    outside it), and optional description="..", base_link="..", tip_link="..". A joint
//    without max_acceleration loads all the same (LimitSources::acceleration_known false):
//    the kinematics need none, and a motion is refused until the request's jointLimits or a
//    MoveIt joint_limits.yaml gives one (resolve_robot);
//  - the model records where each limit came from (RobotModel::limit_sources).
// Every error names the element and its line ("line 12, joint 'elbow': ...").
#pragma once

#include <chrono>
#include <optional>
#include <stop_token>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::planner {

/// Limits given beside a model (a request's RobotSpec.jointLimits, a MoveIt joint_limits.yaml),
/// by joint name; they take precedence over the model's own.
struct NamedLimits {
  std::string joint;
  std::optional<double> max_velocity, max_acceleration, max_jerk;
  std::optional<double> max_torque{};  ///< [N m or N] (a model with mass properties)
  std::string source{};  ///< where they were given, for LimitSources ("robot.jointLimits[0]")
};

/// Sets the limits of `limits` in order (later over earlier) on the joints of `model` they name,
/// recording `source` in model.limit_sources (filled with the model's own where empty); a
/// maxTorque only on a model with mass properties (core::has_dynamics). Whether each entry
/// named a joint of the model. Values are the caller's to check.
std::vector<bool> apply_named_limits(const std::vector<NamedLimits>& limits, core::RobotModel& model);

/// The joints of `model` that have no known acceleration limit (LimitSources), and what to do
/// about it: empty when every joint has one.
std::string missing_accelerations(const core::RobotModel& model);

/// When work on a request gives up: once `deadline` passes or `stop` is requested (the
/// call's deadline and cancellation).
struct StopAt {
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  std::stop_token stop;
  bool reached() const { return stop.stop_requested() || std::chrono::steady_clock::now() >= deadline; }
};

struct UrdfOptions {
  std::string base_link;  ///< empty: the <geotraj> block's base_link, else the root
  std::string tip_link;   ///< empty: the block's tip_link, else the leaf through the most moving joints
  /// Over the <geotraj> block's, by apply_named_limits (the caller checks their values).
  std::vector<NamedLimits> limits;
  /// Checked before each stage of the parse (each linear in the document's size, at most about
  /// 0.2 s at the 16 MiB limit): once reached, the parse ends with a violation of `urdf` that
  /// says so (the caller reports its deadline or cancellation instead).
  StopAt stop_at;
};

/// What a joint without an acceleration limit carries (LimitSources::acceleration_known false):
/// finite and positive and within core::kMaxJointLimit (the model validates), never read by the
/// kinematics, and no motion is planned with it (resolve_robot).
inline constexpr double kUnknownAcceleration = core::kMaxJointLimit;

/// The model of the chain from the base link to the tip link of the URDF document `urdf`.
/// Violations name `urdf` (the document: the message says the line and element), `baseLink`
/// or `tipLink`. Thread-safe.
core::Expected<core::RobotModel> robot_from_urdf(std::string_view urdf, const UrdfOptions& options = {});

/// The built-in models, in a fixed order: core's "pa10" and "ur5" (DH), then "panda"
/// (Franka Emika Panda), "iiwa14" (KUKA LBR iiwa 14 R820) and "ur5e" (Universal Robots
/// UR5e), written as URDF by the project (planner/models/*.urdf, sources cited there); each
/// checked once, when they are first asked for.
const std::vector<core::ValidRobot>& builtin_robots();

/// The built-in model called `name`, or nullptr.
const core::RobotModel* find_builtin_robot(std::string_view name);

/// The URDF text of a built-in model written as URDF, or empty (pa10, ur5: DH tables).
std::string_view builtin_urdf(std::string_view name);

}  // namespace geotraj::planner
