// The moves of a request made plannable: the goal joints of a joint move to a pose (every IK
// branch searched, one chosen), the goal pose of a line to joint values, a line's poses
// checked, and a line as a path for the time-optimal sweep. See plan_detail.hpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "core/motion/orientation.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/plan_detail.hpp"

namespace geotraj::planner::detail {

// The smallest distance of q to a position limit [rad or m] and the joint it is at.
std::pair<double, std::size_t> limit_margin(const core::RobotModel& model, const core::JointVector& q) {
  std::pair<double, std::size_t> out{std::numeric_limits<double>::infinity(), 0};
  for (std::size_t j = 0; j < model.dof(); ++j) {
    const core::JointLimits& l = model.limits[j];
    const double qj = q(static_cast<Eigen::Index>(j));
    const double m = std::min(qj - l.min_position, l.max_position - qj);
    if (m < out.first) out = {m, j};
  }
  return out;
}

// The goal joints of a joint move to a pose, every branch searched, chosen as
// `move.choice` says, and the choice in words (StepReport::goal_choice); out of reach,
// kUnattainable on `jointMove.goalPose` with the distance.
Expected<ChosenGoal> resolve(const JointMoveToPose& move, const Robot& robot, const Budget& budget) {
  ChosenGoal out{core::JointMoveSpec{move.start, {}}, {}};
  const auto n = static_cast<Eigen::Index>(robot.model->dof());
  if (static_cast<Eigen::Index>(move.start.size()) != n) return out;  // plan_joint_move names it
  const core::JointVector start = Eigen::Map<const Eigen::VectorXd>(move.start.data(), n);
  core::IkSearchOptions options;
  options.all_solutions = true;
  options.max_solutions = move.choice == GoalChoice::kNearest ? 1 : 64;  // nearest the start first
  options.stopped = [&budget] { return budget.stop_requested() || budget.expired(); };
  const core::IkSearchResult found = core::search_ik(robot.model, move.goal, start, options);
  if (found.stopped) {
    if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  }
  if (found.solutions.empty()) {
    return tl::unexpected(invalid(core::Violations{core::unattainable(
        "jointMove.goalPose", "is out of the robot's reach: the closest pose it reaches is " +
                                  core::number(found.closest.position_error, 6) + " m and " +
                                  core::number(found.closest.orientation_error, 6) + " rad away")}));
  }
  std::size_t best = 0;
  auto margin = limit_margin(robot.model, found.solutions.front().q);
  const auto nearest = margin;
  if (move.choice == GoalChoice::kLargestMargin) {
    // A larger margin by more than the search's distinct tolerance wins; among equals the
    // nearest the start (the solutions come nearest first).
    for (std::size_t i = 1; i < found.solutions.size(); ++i) {
      const auto m = limit_margin(robot.model, found.solutions[i].q);
      if (m.first > margin.first + options.distinct_tolerance) {
        best = i;
        margin = m;
      }
    }
  }
  const core::JointVector& goal = found.solutions[best].q;
  out.spec.goal.assign(goal.data(), goal.data() + goal.size());
  const auto joint = [&](std::size_t j) {
    return "joint " + std::to_string(j) + ", " + robot.model->joints[j].name;
  };
  const std::string branches = std::to_string(found.solutions.size()) +
                               (found.solutions.size() == 1 ? " IK solution found" : " IK solutions found");
  if (move.choice == GoalChoice::kNearest) {
    out.choice = "the IK solution nearest the start; its margin to the joint limits " +
                 core::number(margin.first, 4) + " (" + joint(margin.second) + ")";
  } else {
    out.choice = "the largest margin to the joint limits, " + core::number(margin.first, 4) + " (" +
                 joint(margin.second) + "), of " + branches +
                 (best == 0 ? " (also the nearest the start)"
                            : "; the nearest the start has " + core::number(nearest.first, 4) + " (" +
                                  joint(nearest.second) + ")");
  }
  return out;
}

// The straight line to joint values: from the start pose to their forward kinematics.
// Joint values of the wrong count or outside the limits are named on `linearMove.goalJoints`.
Expected<core::LinearMoveSpec> resolve(const LinearMoveToJoints& move, const Robot& robot) {
  const std::size_t n = robot.model->dof();
  core::Violations v;
  if (move.goal.size() != n) {
    v.push_back({"linearMove.goalJoints", "has " + std::to_string(move.goal.size()) + " values for a " +
                                              std::to_string(n) + "-joint robot: give one per joint"});
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      const auto& l = robot.model->limits[i];
      if (!std::isfinite(move.goal[i]) || !core::within_position_limits(robot.model->joints[i].type, l, move.goal[i])) {
        v.push_back({"linearMove.goalJoints[" + std::to_string(i) + "]",
                     core::number(move.goal[i]) + " is outside joint " + std::to_string(i) + "'s position limits [" +
                         core::number(l.min_position) + ", " + core::number(l.max_position) + "]"});
      }
    }
  }
  if (!v.empty()) return tl::unexpected(invalid(std::move(v)));
  const core::JointVector q = Eigen::Map<const Eigen::VectorXd>(move.goal.data(), static_cast<Eigen::Index>(n));
  const Eigen::Isometry3d X = core::forward_kinematics(robot.model, q);
  core::LinearMoveSpec spec;
  spec.start = move.start;
  spec.goal.p_WT = X.translation();
  spec.goal.q_WT = Eigen::Quaterniond(X.linear());
  return spec;
}

// The poses of a straight line that is not planned by core::plan_linear_move (a line on
// the time-optimal sweep, a line of a blended chain): its checks, named on linearMove.*,
// by planning it with a nominal duration.
std::optional<Error> pose_errors(const core::LinearMoveSpec& move, const core::MotionSpec& motion) {
  core::MotionSpec nominal = motion;
  nominal.duration_s = 1.0;
  auto checked = core::plan_linear_move(move, nominal);
  if (checked) return std::nullopt;
  return invalid(std::move(checked.error()));
}

// A straight-line move (thesis 6.2.2.2) as a path: two key frames on the line with its
// tangent and curvature 0 (the engine's segment is the straight segment, every derivative
// across it zero), the tool turned by SLERP from the start to the goal orientation over the
// arc length (Eq. 6.2 on the path's progress, ORIENTATION_MODE_CUSTOM).
Expected<StraightPath> straight_path(const core::LinearMoveSpec& move) {
  const Eigen::Vector3d d = (move.goal.p_WT - move.start.p_WT).normalized();
  core::KeyFrame a, b;
  a.p_W = move.start.p_WT;
  b.p_W = move.goal.p_WT;
  a.T_W = b.T_W = d;
  a.kappa = b.kappa = 0.0;
  a.orientation_mode = core::OrientationMode::kCustom;
  a.orientation = move.goal.q_WT.normalized();
  core::PathSpec spec;
  spec.frames = {a, b};
  auto path = core::build_path(spec);
  if (!path) return tl::unexpected(invalid(core::prefixed(std::move(path.error()), "linearMove.")));
  auto orientation = core::plan_orientation(*path, move.start.q_WT.normalized());
  if (!orientation) return tl::unexpected(invalid(core::prefixed(std::move(orientation.error()), "linearMove.")));
  return StraightPath{std::move(*path), std::move(*orientation)};
}

}  // namespace geotraj::planner::detail
