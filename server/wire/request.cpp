// A PlanRequest as given (planner::RequestInput, convert.hpp): every field read, and only
// what cannot be read refused here; planner::admit decides the rest. Sequences in
// sequence.cpp.
#include <string>
#include <utility>

#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

planner::RequestInput request_input_from_proto(const v1::PlanRequest& request, const ServiceLimits& limits) {
  planner::RequestInput in;
  core::Violations& out = in.violations;
  if (request.has_path()) in.geometry.path = path_input(request.path(), limits);
  WireCheck numbers;
  check_request_numbers(request, limits, numbers);
  out = joined(std::move(out), numbers.violations);
  if (!v1::StreamPacing_IsValid(request.pacing())) {
    out.push_back({"pacing", "unknown value " + std::to_string(request.pacing()) +
                                 "; use STREAM_PACING_AS_FAST_AS_POSSIBLE or STREAM_PACING_REAL_TIME"});
  }
  if (request.has_joint_move()) in.geometry.joint_move = joint_move_input(request.joint_move(), "", out);
  if (request.has_linear_move()) in.geometry.linear_move = linear_move_input(request.linear_move());
  if (request.has_joint_path()) in.geometry.joint_path = joint_path_input(request.joint_path());
  if (request.has_motion()) in.motion = motion_input(request.motion(), "motion", out);
  if (request.has_robot()) in.robot = robot_spec_from_proto(request.robot(), out);
  if (request.has_optimize()) in.optimize = optimize_input(request, limits, out);
  sequence_input(request, limits, in);
  return in;
}

}  // namespace geotraj::server
