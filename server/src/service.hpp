// The TrajectoryService on the gRPC callback API: one thin reactor per RPC.
#pragma once

#include <memory>

#include <grpcpp/support/server_callback.h>

#include "geotraj/v1/geotraj.grpc.pb.h"

namespace geotraj::server {

/// Creates the service. Stateless: every call stands alone, so any replica serves any call.
std::unique_ptr<v1::TrajectoryService::CallbackService> make_trajectory_service();

}  // namespace geotraj::server
