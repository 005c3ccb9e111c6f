// PlanRequest.sequence as given (planner::StepInput, convert.hpp): each step's path, move,
// motion and blend tolerance read, what cannot be read named from the request's root.
#include <algorithm>
#include <string>
#include <utility>

#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

void wire_detail::sequence_input(const v1::PlanRequest& request, const ServiceLimits& limits,
                                 planner::RequestInput& in) {
  in.sequence_given = static_cast<std::size_t>(request.sequence_size());
  // A sequence longer than the planner accepts is refused (planner::admit) before any step
  // is read.
  if (request.sequence_size() > planner::kMaxSequenceSteps) return;
  for (int i = 0; i < request.sequence_size(); ++i) {
    const auto& step = request.sequence(i);
    const std::string prefix = "sequence[" + std::to_string(i) + "].";
    planner::StepInput s;
    if (step.has_path()) s.geometry.path = path_input(step.path(), limits);
    if (step.has_joint_move()) s.geometry.joint_move = joint_move_input(step.joint_move(), prefix, in.violations);
    if (step.has_linear_move()) s.geometry.linear_move = linear_move_input(step.linear_move());
    if (step.has_joint_path()) s.geometry.joint_path = joint_path_input(step.joint_path());
    if (step.has_motion()) s.motion = motion_input(step.motion(), prefix + "motion", in.violations);
    if (step.has_blend_tolerance()) s.blend_tolerance = step.blend_tolerance();
    in.sequence.push_back(std::move(s));
  }
}

}  // namespace geotraj::server
