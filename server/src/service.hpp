// The TrajectoryService on the gRPC callback API: one thin reactor per RPC.
#pragma once

#include <memory>

#include <grpcpp/support/server_callback.h>

#include "convert.hpp"
#include "geotraj/v1/geotraj.grpc.pb.h"

namespace geotraj::server {

/// Creates the service with the robot models it knows by name. Stateless: every call stands
/// alone, so any replica (with the same models) serves any call.
std::unique_ptr<v1::TrajectoryService::CallbackService> make_trajectory_service(RobotCatalog robots);

}  // namespace geotraj::server
