// PlanRequest.motion on the wire (convert.hpp).
#include <cstdlib>
#include <set>
#include <utility>

#include "core/geometry/validate.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

core::Expected<core::MotionSpec> motion_from_request(const v1::PlanRequest& request) {
  const auto& m = request.motion();
  WireCheck check;
  check_enum(check, "motion.profile", m.profile(), v1::MotionProfile_descriptor());
  check_enum(check, "motion.timeParameterization", m.time_parameterization(), v1::TimeParameterization_descriptor());
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  core::MotionSpec spec;
  spec.duration_s = m.duration_s();
  spec.profile = m.profile() == v1::MOTION_PROFILE_S_CURVE ? core::ProfileShape::kSCurve
                                                           : core::ProfileShape::kTrapezoidal;
  if (m.has_ramp_fraction()) spec.ramp_fraction = m.ramp_fraction();
  if (m.has_ramp_time_s()) spec.ramp_time_s = m.ramp_time_s();
  spec.ramp_fraction_given = m.has_ramp_fraction();
  if (m.has_cycle_rate_hz()) spec.cycle_rate_hz = m.cycle_rate_hz();
  switch (m.time_parameterization()) {
    case v1::TIME_PARAMETERIZATION_TAYLOR_SECOND_ORDER:
      spec.time_parameterization = core::TimeParameterization::kTaylorSecondOrder;
      break;
    case v1::TIME_PARAMETERIZATION_TAYLOR_FIRST_ORDER:
      spec.time_parameterization = core::TimeParameterization::kTaylorFirstOrder;
      break;
    case v1::TIME_PARAMETERIZATION_LINEAR: spec.time_parameterization = core::TimeParameterization::kLinear; break;
    case v1::TIME_PARAMETERIZATION_SMOOTH: spec.time_parameterization = core::TimeParameterization::kSmooth; break;
    default: spec.time_parameterization = core::TimeParameterization::kArcLength; break;  // ARC_LENGTH, UNSPECIFIED
  }
  if (m.has_speed_scale()) spec.speed_scale = m.speed_scale();
  if (m.has_acceleration_scale()) {
    spec.acceleration_scale = m.acceleration_scale();
    // With a durationS it scales nothing, unless a robot.approach (timed by the limits)
    // comes first.
    const bool approach = request.has_path() && request.robot().approach() != v1::APPROACH_MOVE_UNSPECIFIED;
    if (m.duration_s() > 0.0 && !approach) {
      return tl::unexpected(core::Violations{
          {"motion.accelerationScale", "scales the limits of a timing by the limits (durationS 0, or a "
                                       "robot.approach): a motion with a durationS is timed by it instead"}});
    }
  }
  if (m.has_max_speed()) spec.max_speed = m.max_speed();
  if (m.has_max_acceleration()) spec.max_acceleration = m.max_acceleration();
  if (m.has_max_jerk()) spec.max_jerk = m.max_jerk();
  if (m.has_max_angular_speed()) spec.max_angular_speed = m.max_angular_speed();
  if (m.has_max_angular_acceleration()) spec.max_angular_acceleration = m.max_angular_acceleration();
  // A joint move's minimum time comes from the joint limits: core::plan_joint_move checks
  // the spec without asking for the Cartesian ones.
  if (request.has_joint_move()) return spec;
  // A minimum time that the time-optimal timing sets (planner::time_optimally_timed): the
  // limits given, and the joint ones with a robot, make it, so the Cartesian ones that the
  // other profiles need are optional here (the planner asks for maxAcceleration without a robot).
  core::MotionSpec checked = spec;
  const auto& timing = request.optimize().timing();
  if (spec.duration_s == 0.0 &&
      planner::time_optimally_timed(spec, request.has_robot(), timing.time_optimal(), timing.jerk_limited())) {
    checked.duration_s = 1.0;
    checked.profile = core::ProfileShape::kTrapezoidal;
  }
  auto violations = core::validate_motion(checked);
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return spec;
}

std::size_t samples_per_batch(const v1::PlanRequest& request) {
  return request.has_samples_per_batch() ? request.samples_per_batch() : kDefaultSamplesPerBatch;
}

}  // namespace geotraj::server
