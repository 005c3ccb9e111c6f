// MoveIt's joint_limits.yaml (a MoveIt configuration's config/joint_limits.yaml, as its
// setup assistant writes it): the velocity, acceleration, jerk and effort limits of each
// joint by name, read as a request's jointLimits (RobotSpec.jointLimitsYaml):
//
//   joint_limits:
//     panda_joint1:
//       has_velocity_limits: true
//       max_velocity: 2.175
//       has_acceleration_limits: true
//       max_acceleration: 3.75
//       has_jerk_limits: false
//       has_effort_limits: true
//       max_effort: 87
//
// MoveIt's rule: a value counts only where its has_..._limits flag is true (a value without
// its flag, or with it false, is not a limit: MoveIt ignores it too). max_effort is the
// joint's maxTorque [N m or N]. Position limits (has_position_limits, min_position,
// max_position) and the file's default scaling factors are MoveIt's own and not read here:
// positions come from the model. Every problem is named by the field given and the key's
// path and line ("robot.jointLimitsYaml: line 4, joint_limits.panda_joint1.max_velocity:
// ...").
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"
#include "planner/robots.hpp"

namespace geotraj::planner {

/// The largest joint_limits.yaml read [bytes]: a setup assistant's file for a 12-joint arm is
/// about 3 kB.
inline constexpr std::size_t kMaxJointLimitsYamlBytes = 1u << 20;

/// The limits of `text`, one NamedLimits per joint under `joint_limits` (in the file's order),
/// each value checked as a request's (core::joint_limit_violation). Errors (every problem,
/// field `field`): not YAML (the parser's message and line), larger than
/// kMaxJointLimitsYamlBytes, no `joint_limits` mapping, a joint that is not a mapping, a flag
/// that is not a boolean, a value that is not a number or outside the range of limits, a
/// joint named twice.
core::Expected<std::vector<NamedLimits>> joint_limits_from_yaml(std::string_view text, const std::string& field);

}  // namespace geotraj::planner
