// Joint waypoints from a file, for `--waypoints` (a PlanRequest's jointPath): what a sampling
// planner returns, as MoveIt gives it or as plain numbers.
#pragma once

#include <string>
#include <vector>

#include "geotraj/v1/geotraj.pb.h"

namespace geotraj::cli {

/// Waypoints as read: one row of joint values per waypoint, and the joints' names when the
/// file names them.
struct WaypointFile {
  std::vector<std::vector<double>> rows;
  std::vector<std::string> joint_names;
};

/// Reads `path` ("-": standard input) in one of these forms:
///  - MoveIt's trajectory_msgs/JointTrajectory in JSON (`{"joint_names": [...], "points":
///    [{"positions": [...], ...}, ...]}`, velocities and times ignored), bare or as the
///    `joint_trajectory` of a moveit_msgs/RobotTrajectory (a MotionPlanResponse's
///    `trajectory`);
///  - a JSON array of arrays of numbers;
///  - text, one waypoint per line, its values separated by spaces, tabs or commas (blank
///    lines and lines starting with '#' skipped; a first line of names is the joints').
/// false, with `error` naming the file and the line or point, when it cannot be read: every
/// value a finite number, every row as long as the first.
bool read_waypoints(const std::string& path, WaypointFile& out, std::string& error);

/// `file`'s waypoints as request.jointPath (replacing its path, move or sequence), in the
/// order of `model_joint_names` when the file names its joints and the model's names are
/// known (each of the model's joints must be in the file; the file's others are refused),
/// else in the file's order; `blend_tolerance` set when >= 0. false, with `error`, otherwise.
bool set_joint_path(const WaypointFile& file, const std::vector<std::string>& model_joint_names,
                    double blend_tolerance, v1::PlanRequest& request, std::string& error);

}  // namespace geotraj::cli
