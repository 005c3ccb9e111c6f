// The kinematics calls' work (service_calls.hpp): ComputeForwardKinematics and
// ComputeInverseKinematics.
#include "server/rpc/service_calls.hpp"

#include "core/robot/kinematics.hpp"
#include "planner/planner.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/kinematics.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server::service_detail {

grpc::Status forward_kinematics(const Abandon& abandon, const Services& services,
                                const v1::ForwardKinematicsRequest& request, v1::ForwardKinematicsResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  auto input = planner::admit(forward_input_from_proto(request), services.robots, abandon.stop_at());
  if (!input) return not_converted(abandon, std::move(input.error()));
  to_proto(planner::forward_kinematics(*input), response);
  return grpc::Status::OK;
}

grpc::Status inverse_kinematics(const Abandon& abandon, const Services& services,
                                const v1::InverseKinematicsRequest& request, v1::InverseKinematicsResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  auto input = planner::admit(inverse_input_from_proto(request), services.robots, abandon.stop_at());
  if (!input) return not_converted(abandon, std::move(input.error()));
  auto answer = planner::inverse_kinematics(*input, budget_of(abandon, services));
  if (!answer) return to_status(answer.error(), abandon);
  to_proto(*answer, response);
  return grpc::Status::OK;
}

}  // namespace geotraj::server::service_detail
