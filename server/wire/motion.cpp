// PlanRequest.motion on the wire (convert.hpp).
#include <cstdlib>
#include <utility>

#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

planner::MotionInput wire_detail::motion_input(const v1::MotionSpec& m, const std::string& prefix,
                                               core::Violations& out) {
  WireCheck check;
  check_enum(check, prefix + ".profile", m.profile(), v1::MotionProfile_descriptor());
  check_enum(check, prefix + ".timeParameterization", m.time_parameterization(), v1::TimeParameterization_descriptor());
  out.insert(out.end(), check.violations.begin(), check.violations.end());
  planner::MotionInput in;
  if (m.duration_s() != 0.0) in.duration_s = m.duration_s();
  switch (m.profile()) {
    case v1::MOTION_PROFILE_S_CURVE: in.profile = core::ProfileShape::kSCurve; break;
    case v1::MOTION_PROFILE_TRAPEZOIDAL: in.profile = core::ProfileShape::kTrapezoidal; break;
    default: break;  // UNSPECIFIED (the default) or unknown (refused above)
  }
  switch (m.time_parameterization()) {
    case v1::TIME_PARAMETERIZATION_ARC_LENGTH:
      in.time_parameterization = core::TimeParameterization::kArcLength;
      break;
    case v1::TIME_PARAMETERIZATION_TAYLOR_SECOND_ORDER:
      in.time_parameterization = core::TimeParameterization::kTaylorSecondOrder;
      break;
    case v1::TIME_PARAMETERIZATION_TAYLOR_FIRST_ORDER:
      in.time_parameterization = core::TimeParameterization::kTaylorFirstOrder;
      break;
    case v1::TIME_PARAMETERIZATION_LINEAR: in.time_parameterization = core::TimeParameterization::kLinear; break;
    case v1::TIME_PARAMETERIZATION_SMOOTH: in.time_parameterization = core::TimeParameterization::kSmooth; break;
    default: break;
  }
  const auto read = [](bool has, double value, std::optional<double>& to) {
    if (has) to = value;
  };
  read(m.has_ramp_fraction(), m.ramp_fraction(), in.ramp_fraction);
  read(m.has_ramp_time_s(), m.ramp_time_s(), in.ramp_time_s);
  read(m.has_cycle_rate_hz(), m.cycle_rate_hz(), in.cycle_rate_hz);
  read(m.has_speed_scale(), m.speed_scale(), in.speed_scale);
  read(m.has_acceleration_scale(), m.acceleration_scale(), in.acceleration_scale);
  read(m.has_max_speed(), m.max_speed(), in.max_speed);
  read(m.has_max_acceleration(), m.max_acceleration(), in.max_acceleration);
  read(m.has_max_jerk(), m.max_jerk(), in.max_jerk);
  read(m.has_max_angular_speed(), m.max_angular_speed(), in.max_angular_speed);
  read(m.has_max_angular_acceleration(), m.max_angular_acceleration(), in.max_angular_acceleration);
  return in;
}

std::size_t samples_per_batch(const v1::PlanRequest& request) {
  return request.has_samples_per_batch() ? request.samples_per_batch() : kDefaultSamplesPerBatch;
}

}  // namespace geotraj::server
