#include "geotraj/server/server.hpp"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_builder.h>

#include <fstream>
#include <sstream>

#include "grpc/health/v1/health.pb.h"
#include "service.hpp"

namespace geotraj::server {

tl::expected<RunningServer, std::string> start_server(const ServerOptions& options) {
  // Both are process-wide switches that must be set before a ServerBuilder exists.
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  // Links the health protocol's descriptors into the process, so that reflection can
  // describe grpc.health.v1.Health too (its messages are otherwise unused by the server).
  (void)grpc::health::v1::HealthCheckRequest::descriptor();

  RobotCatalog robots{core::builtin_robots()};
  for (const auto& file : options.robot_model_files) {
    std::ifstream in(file);
    if (!in) return tl::unexpected("cannot read the robot model file \"" + file + "\"");
    std::ostringstream text;
    text << in.rdbuf();
    auto model = robot_model_from_json(text.str());
    if (!model) {
      std::string why;
      for (const auto& v : model.error()) why += (why.empty() ? "" : "; ") + (v.field.empty() ? "" : v.field + ": ") + v.description;
      return tl::unexpected("robot model file \"" + file + "\": " + why);
    }
    if (robots.find(model->name) != nullptr) {
      return tl::unexpected("robot model file \"" + file + "\": a model named \"" + model->name + "\" is already known");
    }
    robots.models.push_back(std::move(*model));
  }
  RunningServer running;
  running.service = make_trajectory_service(std::move(robots));
  grpc::ServerBuilder builder;
  if (!options.address.empty()) {
    builder.AddListeningPort(options.address, grpc::InsecureServerCredentials(), &running.port);
  }
  builder.SetMaxReceiveMessageSize(options.max_receive_message_bytes);
  builder.RegisterService(running.service.get());
  running.server = builder.BuildAndStart();
  if (!running.server) {
    return tl::unexpected("cannot start the gRPC server on \"" + options.address +
                          "\" (is the address valid, and the port free?)");
  }
  if (!options.address.empty() && running.port == 0) {
    running.server->Shutdown();
    return tl::unexpected("cannot listen on \"" + options.address + "\" (is the address valid, and the port free?)");
  }
  auto* health = running.server->GetHealthCheckService();
  health->SetServingStatus(kServiceName, true);
  health->SetServingStatus(true);
  return running;
}

void stop_server(RunningServer& running, std::chrono::milliseconds grace) {
  if (!running.server) return;
  running.server->GetHealthCheckService()->SetServingStatus(false);
  running.server->Shutdown(std::chrono::system_clock::now() + grace);
  running.server->Wait();
}

}  // namespace geotraj::server
