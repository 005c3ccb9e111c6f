// Starting and stopping the geotraj gRPC server: the TrajectoryService, the standard health
// service (SERVING once ready) and server reflection. Used by geotrajd, by the CLI (in
// process) and by the tests.
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/impl/service_type.h>
#include <grpcpp/server.h>
#include <tl/expected.hpp>

namespace geotraj::server {

/// What the server listens on and accepts.
struct ServerOptions {
  /// Plaintext listening address HOST:PORT; port 0 picks a free port. Empty: no listening
  /// port, in-process channels only (RunningServer::server->InProcessChannel).
  std::string address = "127.0.0.1:50051";
  /// Largest request message [bytes].
  int max_receive_message_bytes = 64 * 1024 * 1024;
  /// Robot model files (proto3 JSON of geotraj.v1.RobotModel) served beside the built-in
  /// models, by their `name`.
  std::vector<std::string> robot_model_files;
};

/// A started server. Destroying it shuts the server down (immediately, cancelling calls in
/// flight); use stop() for a graceful shutdown with a deadline.
struct RunningServer {
  std::unique_ptr<grpc::Service> service;  ///< outlives `server`, which refers to it
  std::unique_ptr<grpc::Server> server;
  int port = 0;  ///< the bound TCP port; 0 without a listening address
};

/// Builds and starts the server; the health service reports SERVING for "" and for
/// "geotraj.v1.TrajectoryService" when it returns. Error: a sentence saying why the server
/// could not start (for example, the address is in use, or a robot model file is unreadable
/// or invalid: the file and the field are named).
tl::expected<RunningServer, std::string> start_server(const ServerOptions& options);

/// Reports NOT_SERVING on the health service, then shuts down: calls in flight may finish
/// until `grace` has passed, then they are cancelled.
void stop_server(RunningServer& running, std::chrono::milliseconds grace);

/// Name of the service on the health service and in reflection.
inline constexpr const char* kServiceName = "geotraj.v1.TrajectoryService";

}  // namespace geotraj::server
