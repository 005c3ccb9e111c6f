// A Jog call's robot and options admitted (jog.hpp).
#include "planner/jog.hpp"

#include <utility>

namespace geotraj::planner {

core::Expected<Jog> admit(JogInput input, const RobotCatalog& catalog) {
  core::Violations violations = std::move(input.violations);
  std::optional<Robot> robot;
  if (!input.robot) {
    violations.push_back({"start.robot", "is required: the robot to jog (a built-in name, a model or a URDF)"});
  } else if (auto resolved = resolve_robot(*input.robot, catalog, /*motion=*/true)) {
    robot = std::move(*resolved);
  } else {
    for (auto& v : resolved.error()) violations.push_back({"start." + v.field, std::move(v.description), v.kind});
  }
  if (robot && robot->tool_axis_free) {
    violations.push_back({"start.robot.toolAxisFree", "frees the tool's roll along a planned motion; a jog moves the "
                                                      "tool as the operator says: drop it"});
  }
  if (violations.empty() && robot) {  // the per-joint bounds the jogger derives (velocityScale x maxVelocity, ...)
    violations = core::validate_jog_limits(robot->model, input.options, "start");
  }
  if (!violations.empty() || !robot) return tl::unexpected(std::move(violations));
  return Jog{std::move(*robot), std::move(input.options)};
}

}  // namespace geotraj::planner
