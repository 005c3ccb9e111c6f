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
#include <set>
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

/// A path as given (PlanRequest.path, a step's, ConvertRequest.path): its key frames as far as
/// they could be read, and what could not be, named from the path ("frames[2].tangent").
struct PathInput {
  core::PathSpec spec;
  /// What the wire could not read; the path is planned only when there is nothing here.
  core::Violations violations;
  /// core::validate_path's field paths that `violations` make noise (a normal checked
  /// against a tangent the frame does not give).
  std::set<std::string> unchecked;
  /// false: refused before any of it was read (more key frames than the server accepts), so
  /// that core does not check it either.
  bool read = true;

  bool usable() const { return read && violations.empty(); }
};

/// Every violation of a path the request is refused with: the wire's, and (unless the path
/// was not read at all) core::validate_path's of what could be read but `unchecked`, in key
/// frame order, named from the path. Empty for a path core accepts.
core::Violations path_violations(const PathInput& path);

/// A path alone (ConvertConstraints): its spec when the wire read all of it (core validates
/// it where it is built), else every violation of it named from the request's root.
core::Expected<core::PathSpec> admit_path(const std::optional<PathInput>& path);

/// What a request (or a sequence step) plans: the kinds it gives, each as read.
struct GeometryInput {
  std::optional<PathInput> path;  ///< present when given, readable or not
  std::optional<JointMoveInput> joint_move;
  std::optional<LinearMoveInput> linear_move;
  std::optional<core::JointPathSpec> joint_path;  ///< PlanRequest.jointPath as given

  int kinds() const {
    return int(path.has_value()) + int(joint_move.has_value()) + int(linear_move.has_value()) +
           int(joint_path.has_value());
  }
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
/// the request's, or every violation of the request together: the wire's and, for every path
/// given, path_violations, in the request's order (a step's after the request's own fields),
/// then the admission's.
core::Expected<Request> admit(RequestInput input, const RobotCatalog& catalog, Use use, const StopAt& stop_at = {});

}  // namespace geotraj::planner
