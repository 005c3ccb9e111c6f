// The live calls: Execute (a plan executed in real time under the client's speed override,
// pause, resume and stop) and Jog (joint and Cartesian jogging), each a bidirectional
// stream on gRPC's callback API. See docs/live.md.
#pragma once

#include <functional>
#include <memory>
#include <stop_token>

#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/server_callback.h>
#include <tl/expected.hpp>

#include "geotraj/v1/geotraj.pb.h"
#include "planner/planner.hpp"
#include "server/ops/runtime.hpp"
#include "server/options.hpp"
#include "server/wire/convert.hpp"

namespace geotraj::server {

/// Plans an Execute call's request on a worker, with `reserve` of every acceleration left
/// free for speed changes (planner::reserve_room): the plan, or the status to end with.
using ExecutePlanning = std::function<tl::expected<planner::Plan, grpc::Status>(
    const v1::PlanRequest& request, double reserve, std::stop_token stop)>;

/// The reactor of one Execute call (admitted or refused by `Call`).
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* execute_call(grpc::CallbackServerContext& context,
                                                                          Runtime& runtime, ExecutePlanning planning);

/// The reactor of one Jog call.
grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* jog_call(grpc::CallbackServerContext& context,
                                                                      Runtime& runtime, const RobotCatalog& robots);

}  // namespace geotraj::server
