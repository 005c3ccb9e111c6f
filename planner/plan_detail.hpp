// What planner.cpp (one path, move or line), moves.cpp (the moves' goals, a line as a path)
// and sequence.cpp (steps, the approach move) share: the steps of planning one trajectory and
// its passes. Not the planner's interface (planner.hpp).
#pragma once

#include <chrono>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "core/geometry/path.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/moves.hpp"
#include "core/planning/trajectory.hpp"
#include "planner/planner.hpp"

namespace geotraj::planner::detail {

using Clock = std::chrono::steady_clock;

// Samples between two checks of the budget in the joint-space pass: an IK sample costs about
// a microsecond when the pose is within reach and milliseconds when the solver fails on one
// out of reach, so a check every 16 keeps an abandoned call's overrun to tens of
// milliseconds at a cost below 0.5 %. Without IK a sample costs about a microsecond: every
// 1,024.
inline constexpr std::size_t kSamplesPerCheck = 16;
inline constexpr std::size_t kToolSamplesPerCheck = 1024;

/// The largest |s''| of the timing of a path or a line [m/s^2]; 0 for a joint move (and a
/// sequence, whose steps are asked one by one).
template <class Motion>
double tangential_peak(const Motion& motion) {
  if (const auto* path = std::get_if<core::PathMotion>(&motion)) return path->timing.peak_acceleration;
  if (const auto* line = std::get_if<core::LinearMovePlan>(&motion)) return line->peak_acceleration;
  return 0.0;
}

/// A jerk-limited timing's binding stretches: those measured on the plan's samples.
inline void measured_binding(OptimizerReports& reports, const std::vector<core::BindingStretch>& measured) {
  if (reports.timing && reports.timing->jerk_limited) reports.timing->binding = measured;
}

/// Violations as an error: kUnattainable when every one is (core::ViolationKind: the request
/// is well-formed and cannot be carried out), kInvalidArgument otherwise (fields to change).
Error invalid(core::Violations violations);

/// The deadline every optimiser of the request shares: the earlier of the budget's and
/// optimize.timeBudgetS from now.
Clock::time_point optimizer_deadline(const Request& request, const Budget& budget);

/// core::build_path, its violations under `path.`.
Expected<core::Path> build(const core::PathSpec& spec);

/// A joint move to a pose: its goal joints, and which branch was chosen, in words.
struct ChosenGoal {
  core::JointMoveSpec spec;
  std::string choice;
};
Expected<ChosenGoal> resolve(const JointMoveToPose& move, const Robot& robot, const Budget& budget);
/// A line to joint values: its goal pose.
Expected<core::LinearMoveSpec> resolve(const LinearMoveToJoints& move, const Robot& robot);

/// A linear move's poses checked as core::plan_linear_move checks them.
std::optional<Error> pose_errors(const core::LinearMoveSpec& move, const core::MotionSpec& motion);

/// A straight-line move as a path, and the tool's orientation along it.
struct StraightPath {
  core::Path path;
  core::OrientationPlan orientation;
};
Expected<StraightPath> straight_path(const core::LinearMoveSpec& move);

/// The request's geometry as a timed trajectory (its optimisers, path, orientation, timing).
Expected<core::Trajectory> plan_trajectory(const Request& request, const Budget& budget, Clock::time_point deadline,
                                           OptimizerReports& reports, std::optional<DefaultJerk>& default_jerk);

/// `sample`'s tool speed, acceleration and angular speed into `peaks`.
void add(ToolPeaks& peaks, const core::TrajectorySample& sample);

/// A path's first tool pose against the robot's at its initial joints (robot.*Tolerance).
std::optional<Error> starts_at_robot(const core::Trajectory& trajectory, const Robot& robot);

/// The motion's Cartesian limits, for the binding report of a tool path (none otherwise).
core::CartesianLimits cartesian_limits(const core::MotionSpec& motion, bool tool_path);

/// A joint move (to joints or to a pose).
bool joint_geometry(const Geometry& geometry);

/// A redundant arm's joints along a path motion or a straight line chosen for the whole
/// motion (optim/redundancy) and attached to it; `goal`: joints the motion ends at, held.
/// The report in `reports.redundancy`; an error only for a request the optimiser refuses.
/// A path timed by the limits (`request`'s motion and optimize) is timed again along the
/// choices (the tool's roll, a redundant arm's joints as a function of the arc length), kept
/// when faster.
std::optional<Error> choose_joints(core::Trajectory& trajectory, const Request& request,
                                   const optim::RedundancyWeights& weights, const std::vector<double>* goal,
                                   const Budget& budget, Clock::time_point deadline, OptimizerReports& reports);

/// A line to joint values ends at them (the tracked branch is the goal's).
std::optional<Error> ends_at_goal(const Geometry& geometry, const core::JointVector& last);

/// The geometry part of a plan's answer for a path.
PathReport report_of(const core::Path& path);

/// PlanRequest.sequence (sequence.cpp).
Expected<Plan> plan_sequence(const Request& request, const Budget& budget, const Limits& limits, Use use);

/// A path with a robot that starts away from the tool pose of the robot's initial joints, and
/// robot.approach set: the request as a sequence of the approach move (minimum time) and the
/// path. nullopt: plan the request as it is (sequence.cpp).
std::optional<Expected<Request>> with_approach(const Request& request);

/// Whether a violation of a sequence step, named as in a request of its own
/// (`path.frames[0]`, `motion.maxSpeed`, `robot.name`), is the step's own field: its path or
/// move, or a motion field its own motion gives (`own_motion_fields`, API names; nullptr: the
/// step has no motion of its own, "motion" alone: it has one). The others are the request's
/// (admit.cpp, sequence.cpp).
bool step_owns(std::string_view field, const std::vector<std::string>* own_motion_fields);

}  // namespace geotraj::planner::detail
