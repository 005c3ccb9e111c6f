// PlanRequest.jointMove and linearMove as the planner's geometry (convert.hpp).
#include <cmath>
#include <utility>

#include "core/format.hpp"
#include "core/geometry/validate.hpp"
#include "core/robot/kinematics.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

core::Expected<planner::Geometry> joint_move_from_request(const v1::PlanRequest& request,
                                                          const core::JointVector& seed) {
  const auto& move = request.joint_move();
  std::vector<double> start;
  if (move.start_size() == 0) {
    start.assign(seed.data(), seed.data() + seed.size());
  } else {
    start.assign(move.start().begin(), move.start().end());
  }
  const bool joints = move.goal_size() > 0;
  if (joints == move.has_goal_pose()) {
    return tl::unexpected(core::Violations{
        {"jointMove.goal", joints ? "give `goal` (joint values) or `goalPose` (a tool pose), not both"
                                  : "is required: the joint values at the goal, one per joint (or `goalPose`)"}});
  }
  if (joints) return planner::Geometry(core::JointMoveSpec{std::move(start), {move.goal().begin(), move.goal().end()}});
  core::Violations out;
  const Eigen::Isometry3d goal = pose_from_proto(move.goal_pose(), "jointMove.goalPose", out);
  if (goal.translation().allFinite() && goal.translation().cwiseAbs().maxCoeff() > core::PathLimits{}.max_coordinate) {
    out.push_back({"jointMove.goalPose.position",
                   "coordinates must lie within " + core::number(core::PathLimits{}.max_coordinate) + " m of the origin"});
  }
  if (!out.empty()) return tl::unexpected(std::move(out));
  return planner::Geometry(planner::JointMoveToPose{std::move(start), goal});
}

core::Expected<planner::Geometry> linear_move_from_request(const v1::PlanRequest& request,
                                                           const planner::Robot* robot) {
  const auto& move = request.linear_move();
  core::Violations out;
  core::LinearMoveSpec spec;
  auto tool_pose = [](const v1::Pose& pose) {
    core::ToolPose p;
    p.p_WT = to_core(pose.position());
    if (pose.has_orientation()) {
      const auto& q = pose.orientation();
      p.q_WT = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z());  // by name; core checks its norm
    }
    return p;
  };
  if (move.has_start()) {
    spec.start = tool_pose(move.start());
  } else if (robot != nullptr) {
    const Eigen::Isometry3d X = core::forward_kinematics(robot->model, robot->seed);
    spec.start.p_WT = X.translation();
    spec.start.q_WT = Eigen::Quaterniond(X.linear());
  } else {
    out.push_back({"linearMove.start", "is required without a robot (with one, the pose of its initialJoints)"});
  }
  const bool joints = move.goal_joints_size() > 0;
  if (joints && move.has_goal()) {
    out.push_back({"linearMove.goal", "give `goal` (a tool pose) or `goalJoints` (joint values), not both"});
  } else if (joints) {
    if (robot == nullptr) out.push_back({"linearMove.goalJoints", "needs `robot`: the joints belong to a robot model"});
    for (int i = 0; i < move.goal_joints_size(); ++i) {
      if (!std::isfinite(move.goal_joints(i))) {
        out.push_back({"linearMove.goalJoints[" + std::to_string(i) + "]",
                       "must be finite, got " + core::number(move.goal_joints(i))});
      }
    }
  } else if (move.has_goal()) {
    spec.goal = tool_pose(move.goal());
  } else {
    out.push_back({"linearMove.goal", "is required: the tool pose at the end of the move (or `goalJoints`)"});
  }
  if (!out.empty()) return tl::unexpected(std::move(out));
  if (joints) {
    return planner::Geometry(
        planner::LinearMoveToJoints{spec.start, {move.goal_joints().begin(), move.goal_joints().end()}});
  }
  return planner::Geometry(spec);
}

}  // namespace geotraj::server
