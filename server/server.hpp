// Starting and stopping the geotraj gRPC server: the TrajectoryService, the standard health
// service (liveness, and readiness once warm) and server reflection, configured by
// ServerOptions (server/options.hpp: TLS, bearer tokens, the caps on calls in flight and the
// limits of one call). Used by geotrajd, by the CLI (in process) and by the tests.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stop_token>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <grpcpp/impl/service_type.h>
#include <grpcpp/server.h>
#include <tl/expected.hpp>

#include "server/options.hpp"

namespace geotraj::server {

class Runtime;
class HttpExporter;
class WebGateway;
class Acceptor;
class HealthState;

/// A started server. Destroying it shuts the server down (immediately, cancelling calls in
/// flight); use stop_server() for a graceful shutdown.
struct RunningServer {
  RunningServer();
  RunningServer(RunningServer&&) noexcept;
  RunningServer& operator=(RunningServer&&) noexcept;
  ~RunningServer();

  std::shared_ptr<Runtime> runtime;        ///< limits, tokens, counts, metrics, log
  std::unique_ptr<grpc::Service> service;  ///< outlives `server`, which refers to it
  std::unique_ptr<grpc::Server> server;
  std::unique_ptr<grpc::Server> health_server;  ///< on ServerOptions::health_address
  std::unique_ptr<HttpExporter> metrics;       ///< on ServerOptions::metrics_address
  std::shared_ptr<HealthState> health;         ///< what both health services answer
  std::unique_ptr<grpc::Service> health_service;         ///< grpc.health.v1.Health on `server`
  std::unique_ptr<grpc::Service> health_only_service;    ///< the same on `health_server`
  std::unique_ptr<Acceptor> acceptor;          ///< accepts the gRPC port's TCP connections
  std::unique_ptr<Acceptor> health_acceptor;   ///< the same for the health port
  /// On ServerOptions::web_address; calls `server` in process (declared after it, so
  /// destroyed before it).
  std::unique_ptr<WebGateway> web;
  int port = 0;          ///< the bound TCP port; 0 without a listening address
  int health_port = 0;   ///< the health-only port; 0 without one
  int metrics_port = 0;  ///< the metrics HTTP port; 0 without one
  int web_port = 0;      ///< the web port; 0 without one
};

/// Builds and starts the server, then warms it up (one plan, one analysis, in process) and
/// reports SERVING on the health service for "" and "geotraj.v1.TrajectoryService" as soon
/// as it listens, and for kReadinessService once warm. Error: a sentence saying why the
/// server could not start (the address is in use, a certificate or tokens file is
/// unreadable, plaintext was not asked for on a public address, a robot model file is
/// invalid: the file and the field are named).
tl::expected<RunningServer, std::string> start_server(const ServerOptions& options);

/// The first step of stop_server alone (idempotent): health turns NOT_SERVING and new calls
/// are refused with UNAVAILABLE from its return on. geotrajd calls it before it announces
/// the drain, so that a client that reads the announcement is refused.
void begin_drain(RunningServer& running);

/// Graceful shutdown: health turns NOT_SERVING on every name, new calls are refused with
/// UNAVAILABLE (trailers only, so clients retry them elsewhere), and calls in flight may
/// finish until `drain` has passed; new calls are refused for `lame_duck` at least (at most
/// `drain`), so that clients and load balancers move away before the server closes its
/// connections. Then the server shuts down, cancelling what is left.
///
/// `now`: when requested (a second SIGTERM), the drain ends at once and what is left is
/// cancelled.
void stop_server(RunningServer& running, std::chrono::milliseconds drain,
                 std::chrono::milliseconds lame_duck = std::chrono::milliseconds(0), std::stop_token now = {});

/// The Prometheus text exposition of the server's metrics.
std::string metrics_exposition(const RunningServer& running);

/// Logs one line through the server's logger (start-up and shutdown messages of geotrajd).
void log_info(const RunningServer& running, std::string_view message,
              const std::vector<std::pair<std::string, std::string>>& fields = {});

}  // namespace geotraj::server
