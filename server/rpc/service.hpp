// The TrajectoryService on the gRPC callback API: one thin reactor per RPC.
#pragma once

#include <memory>

#include <grpcpp/support/server_callback.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "server/wire/convert.hpp"

namespace geotraj::server {

class Runtime;

/// Creates the service with the robot models it knows by name and the runtime its calls
/// share (limits, tokens, admission, metrics, log). Every call stands alone, so any replica
/// (with the same models) serves any call.
std::unique_ptr<grpc::Service> make_trajectory_service(RobotCatalog robots,
                                                      std::shared_ptr<Runtime> runtime);

/// Runs one small plan and analysis through a service made by make_trajectory_service, as
/// a call would (no admission, no metrics of calls); not OK when it fails.
grpc::Status warm_up(grpc::Service& service);

}  // namespace geotraj::server
