// PlanRequest.jointMove, linearMove and jointPath as given (planner::JointMoveInput,
// LinearMoveInput, core::JointPathSpec: core checks the joint path's values).
#include <utility>

#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

planner::JointMoveInput wire_detail::joint_move_input(const v1::JointMove& move, const std::string& prefix,
                                                      core::Violations& out) {
  planner::JointMoveInput in;
  in.start.assign(move.start().begin(), move.start().end());
  in.goal.assign(move.goal().begin(), move.goal().end());
  if (move.has_goal_pose()) in.goal_pose = pose_from_proto(move.goal_pose(), prefix + "jointMove.goalPose", out);
  return in;
}

core::JointPathSpec wire_detail::joint_path_input(const v1::JointPath& path) {
  core::JointPathSpec spec;
  spec.blend_tolerance = path.blend_tolerance();
  spec.waypoints.reserve(static_cast<std::size_t>(path.waypoints_size()));
  for (const v1::JointWaypoint& w : path.waypoints()) {
    core::JointWaypoint waypoint;
    waypoint.positions.assign(w.positions().begin(), w.positions().end());
    waypoint.stop = w.stop();
    spec.waypoints.push_back(std::move(waypoint));
  }
  return spec;
}

planner::LinearMoveInput wire_detail::linear_move_input(const v1::LinearMove& move) {
  const auto tool_pose = [](const v1::Pose& pose) {
    core::ToolPose p;
    p.p_WT = to_core(pose.position());
    if (pose.has_orientation()) {
      const auto& q = pose.orientation();
      p.q_WT = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z());  // by name; core checks its norm
    }
    return p;
  };
  planner::LinearMoveInput in;
  if (move.has_start()) in.start = tool_pose(move.start());
  if (move.has_goal()) in.goal = tool_pose(move.goal());
  in.goal_joints.assign(move.goal_joints().begin(), move.goal_joints().end());
  return in;
}

}  // namespace geotraj::server
