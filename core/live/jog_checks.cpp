// Jogging: the checks of a jog command, of jog options, and of a robot's limits for jogging.
// See jog.hpp.
#include "core/live/jog.hpp"

#include <cmath>
#include <cstddef>
#include <string>
#include <string_view>

#include "core/format.hpp"
#include "core/motion/motion.hpp"

namespace geotraj::core {
namespace {

std::string join(std::string_view field, std::string_view name) {
  std::string out(field);
  if (!out.empty()) out += '.';
  out += name;
  return out;
}

std::string indexed(std::string_view field, std::string_view name, std::size_t i) {
  return join(field, name) + "[" + std::to_string(i) + "]";
}

}  // namespace

Violations validate_jog_command(const JogCommand& command, std::size_t dof, std::string_view field) {
  Violations v;
  // (The path is written only for a violation: Jogger::command checks every command.)
  const auto fraction = [&](std::string_view name, Eigen::Index i, double x) {
    if (!(std::isfinite(x) && x >= -1.0 && x <= 1.0)) {
      v.push_back({indexed(field, name, static_cast<std::size_t>(i)),
                   "must be a fraction of the maximum speed in [-1, 1], got " + number(x)});
    }
  };
  if (command.joints.size() > 0 && command.twist) {
    v.push_back({std::string(field), "gives both joints and twist: a jog moves joints or the tool, give one"});
  }
  if (command.joints.size() > 0) {
    if (static_cast<std::size_t>(command.joints.size()) != dof) {
      v.push_back({join(field, "joints"), "has " + std::to_string(command.joints.size()) + " values for a robot of " +
                                              std::to_string(dof) + " joints: give one per joint"});
    }
    for (Eigen::Index i = 0; i < command.joints.size(); ++i) fraction("joints", i, command.joints(i));
  }
  if (command.twist) {
    for (Eigen::Index i = 0; i < 6; ++i) fraction("twist", i, (*command.twist)(i));
  }
  return v;
}

Violations validate_jog_limits(const RobotModel& model, const JogOptions& options, std::string_view field) {
  Violations v;
  const auto named = [&](std::size_t i) {
    return "joint " + std::to_string(i) + (i < model.joints.size() ? " (" + model.joints[i].name + ")" : "");
  };
  // The largest jerk bound a ramp may make: the widest ratio of two limits.
  constexpr double kMaxRampJerk = kMaxJointLimit / kMinJointLimit;
  for (std::size_t i = 0; i < model.limits.size(); ++i) {
    const JointLimits& l = model.limits[i];
    const double v_max = l.max_velocity * options.velocity_scale;
    if (!(v_max >= kMinJointLimit)) {
      v.push_back({join(field, "velocityScale"),
                   number(options.velocity_scale) + " makes " + named(i) + "'s jog speed (maxVelocity " +
                       number(l.max_velocity) + " times it) " + number(v_max) + ", below " + number(kMinJointLimit) +
                       ": give a larger scale"});
      break;
    }
  }
  for (std::size_t i = 0; i < model.limits.size(); ++i) {
    const JointLimits& l = model.limits[i];
    if (l.max_jerk) continue;
    const double j_max = l.max_acceleration / options.jerk_ramp_s;
    if (!(j_max > 0.0 && j_max <= kMaxRampJerk)) {
      v.push_back({join(field, "jerkRampS"), number(options.jerk_ramp_s) + " s makes " + named(i) +
                                                 "'s jerk bound (maxAcceleration over it) " + number(j_max) +
                                                 ", outside (0, " + number(kMaxRampJerk) + "]"});
      break;
    }
  }
  return v;
}

Violations validate_jog_options(const JogOptions& options, std::string_view field) {
  Violations v;
  const auto positive = [&](const char* name, double x, const char* unit) {
    if (!(std::isfinite(x) && x > 0.0)) {
      v.push_back({join(field, name), std::string("must be finite and > 0 ") + unit + ", got " + number(x)});
    }
  };
  if (!(std::isfinite(options.cycle_rate_hz) && options.cycle_rate_hz > 0.0 && options.cycle_rate_hz <= kMaxCycleRateHz)) {
    v.push_back({join(field, "cycleRateHz"),
                 "must be in (0, " + number(kMaxCycleRateHz) + "] Hz, got " + number(options.cycle_rate_hz)});
  }
  if (!(std::isfinite(options.velocity_scale) && options.velocity_scale > 0.0 && options.velocity_scale <= 1.0)) {
    v.push_back({join(field, "velocityScale"),
                 "must be a fraction of each joint's maxVelocity in (0, 1], got " + number(options.velocity_scale)});
  }
  positive("maxLinearSpeed", options.max_linear_speed, "[m/s]");
  positive("maxAngularSpeed", options.max_angular_speed, "[rad/s]");
  if (!(std::isfinite(options.damping) && options.damping >= 0.0)) {
    v.push_back({join(field, "damping"), "must be finite and >= 0, got " + number(options.damping)});
  }
  positive("singularThreshold", options.singular_threshold, "(a singular value of the Jacobian)");
  positive("jerkRampS", options.jerk_ramp_s, "[s]");
  return v;
}

}  // namespace geotraj::core
