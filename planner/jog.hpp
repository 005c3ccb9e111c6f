// A Jog call's robot and options (JogStart) admitted: the robot resolved against the server's
// catalogue as a plan's is (planner/robot_spec.hpp), and the jogger's per-joint bounds checked
// against it (core::validate_jog_limits). The wire reads JogStart into a JogInput.
#pragma once

#include <optional>

#include "core/error.hpp"
#include "core/live/jog.hpp"
#include "planner/planner.hpp"
#include "planner/robot_spec.hpp"

namespace geotraj::planner {

/// JogStart as given: the robot, and the jogger's options already read within their ranges
/// (the wire names those), with what the wire could not read. Field paths from the message's
/// root (`start.cycleRateHz`).
struct JogInput {
  std::optional<RobotSpec> robot;
  core::JogOptions options;
  core::Violations violations;
};

/// A jog's robot, resolved, and its options, valid for it.
struct Jog {
  Robot robot;
  core::JogOptions options;
};

/// `input` admitted, or every violation together (the wire's first): `start.robot` (required,
/// resolved against `catalog`: `start.robot.name`, ...), and the bounds the jogger derives per
/// joint (`start.velocityScale`, ...).
core::Expected<Jog> admit(JogInput input, const RobotCatalog& catalog);

}  // namespace geotraj::planner
