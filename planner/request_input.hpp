// A plan request as the client wrote it, before anything is checked against the domain, and
// its admission into the planner's Request (planner::admit). The wire layer reads a
// PlanRequest into a RequestInput and records there only what it could not read (unknown
// enum values, poses that are not rotations, key frames, the server's size limits); admit
// decides the rest: what the call needs of the request, the motion's values, the robot, the
// moves, the sequence's rules, each step's inheritance of the request's motion. Every
// violation of both is answered together, named from the request's root in proto JSON names.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/motion/motion.hpp"
#include "core/planning/moves.hpp"
#include "planner/planner.hpp"
#include "planner/robot_spec.hpp"
#include "planner/robots.hpp"

namespace geotraj::planner {

/// A MotionSpec as given: each field present only where the request sets it (proto3's
/// presence: a plain number or enum is present when it is not 0), so that a sequence step's
/// motion can take every field it lacks from the request's.
struct MotionInput {
  std::optional<double> duration_s;  ///< [s]
  std::optional<core::ProfileShape> profile;
  std::optional<double> ramp_fraction;
  std::optional<double> ramp_time_s;    ///< [s]
  std::optional<double> cycle_rate_hz;  ///< [Hz]
  std::optional<core::TimeParameterization> time_parameterization;
  std::optional<double> speed_scale;
  std::optional<double> acceleration_scale;
  std::optional<double> max_speed;                 ///< [m/s]
  std::optional<double> max_acceleration;          ///< [m/s^2]
  std::optional<double> max_jerk;                  ///< [m/s^3]
  std::optional<double> max_angular_speed;         ///< [rad/s]
  std::optional<double> max_angular_acceleration;  ///< [rad/s^2]
};

/// The fields `motion` gives, by their API names ("durationS", "maxSpeed", ...).
std::vector<std::string> given_fields(const MotionInput& motion);

/// `base` with every field `over` gives replaced by it.
MotionInput merged(MotionInput base, const MotionInput& over);

/// The motion with the documented defaults where a field is absent.
core::MotionSpec motion_spec(const MotionInput& motion);

/// PlanRequest.jointMove as given.
struct JointMoveInput {
  std::vector<double> start;  ///< [rad or m]; empty: the robot's initial joints
  std::vector<double> goal;   ///< [rad or m]
  std::optional<Eigen::Isometry3d> goal_pose;  ///< X_WT, present when given (read or not)
};

/// PlanRequest.linearMove as given.
struct LinearMoveInput {
  std::optional<core::ToolPose> start;  ///< absent: the pose of the robot's initial joints
  std::optional<core::ToolPose> goal;
  std::vector<double> goal_joints;      ///< [rad or m]
};

/// What a request (or a sequence step) plans: the kinds it gives, each as read.
struct GeometryInput {
  bool path_given = false;
  std::optional<core::PathSpec> path;  ///< absent when not given or not readable (the wire said why)
  std::optional<JointMoveInput> joint_move;
  std::optional<LinearMoveInput> linear_move;

  int kinds() const { return int(path_given) + int(joint_move.has_value()) + int(linear_move.has_value()); }
};

/// PlanRequest.optimize as given: the optimisers' options (their values checked by the
/// optimisers) and the budget (checked against the server's limit by the wire).
struct OptimizeInput {
  Optimize values;
  bool tangent_scales = false;  ///< optimize.tangentScales was given
  bool breakpoints = false;     ///< optimize.breakpoints was given
};

/// One step of PlanRequest.sequence as given.
struct StepInput {
  GeometryInput geometry;
  std::optional<MotionInput> motion;       ///< sequence[i].motion
  std::optional<double> blend_tolerance;   ///< [m]
};

/// A PlanRequest as given, with what the wire could not read.
struct RequestInput {
  GeometryInput geometry;
  std::optional<MotionInput> motion;
  std::optional<RobotSpec> robot;
  std::optional<OptimizeInput> optimize;
  /// PlanRequest.sequence: at most kMaxSequenceSteps of them read.
  std::vector<StepInput> sequence;
  std::size_t sequence_given = 0;  ///< how many steps the request gives
  /// What the wire could not read, named from the root; admit lists them first.
  core::Violations violations;
};

/// The most steps one sequence plans.
inline constexpr int kMaxSequenceSteps = 64;

/// `input` admitted for `use`: the robot resolved against `catalog` (once, for every step;
/// a URDF's parse gives up at `stop_at`), the motion checked, each step's motion merged over
/// the request's, or every violation of the request together (the wire's first).
core::Expected<Request> admit(RequestInput input, const RobotCatalog& catalog, Use use, const StopAt& stop_at = {});

}  // namespace geotraj::planner
