// Starting and stopping the geotraj gRPC server: the TrajectoryService, the standard health
// service (liveness, and readiness once warm) and server reflection; TLS, bearer tokens,
// the caps on calls in flight and the limits of one call. Used by geotrajd, by the CLI (in
// process) and by the tests.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <grpcpp/impl/service_type.h>
#include <grpcpp/server.h>
#include <tl/expected.hpp>

namespace geotraj::server {

/// What one call may ask of the server. Each refusal names the limit and its flag.
struct ServiceLimits {
  /// Streams in flight; beyond, RESOURCE_EXHAUSTED (the callback API itself is unbounded).
  int max_streams = 256;
  /// Unary calls in flight (plans, analyses, conversions); beyond, RESOURCE_EXHAUSTED.
  int max_unary_calls = 64;
  /// Key frames in one path (ConvertRequest, PlanRequest).
  int max_frames = 1000;
  /// Samples in one motion that is streamed or followed by a robot (IK at every sample).
  std::uint64_t max_stream_samples = 10'000'000;
  /// Time one call may spend optimising [s]: the default optimize.timeBudgetS and its
  /// largest accepted value.
  double max_optimize_seconds = 30.0;
};

/// Server certificates for TLS (PEM files); with a client CA, clients must present a
/// certificate it signed (mutual TLS).
struct TlsOptions {
  std::string cert_file;
  std::string key_file;
  std::string client_ca_file;
  bool enabled() const { return !cert_file.empty() || !key_file.empty(); }
};

/// HTTP/2 connection management: keepalive pings find dead peers; a maximum connection age
/// makes clients reconnect (and so spread over new replicas) with a grace period in which
/// calls in flight may finish.
struct ConnectionOptions {
  double keepalive_s = 60.0;          ///< ping a connection idle this long [s]
  double keepalive_timeout_s = 20.0;  ///< close it when the ping is not answered in this [s]
  double max_connection_age_s = 0.0;  ///< 0: connections live as long as they are used [s]
  double max_connection_age_grace_s = 7200.0;  ///< calls in flight may finish within this [s]
};

/// What the server listens on and accepts.
struct ServerOptions {
  /// Listening address HOST:PORT; port 0 picks a free port. Empty: no listening port,
  /// in-process channels only (RunningServer::server->InProcessChannel).
  std::string address = "127.0.0.1:50051";
  /// Serve without TLS on a non-loopback address. Without TLS and without this, only
  /// loopback addresses (127.0.0.0/8, ::1, localhost) and unix sockets are served.
  bool plaintext = false;
  TlsOptions tls;
  /// A second, plaintext listening address that serves grpc.health.v1.Health only (for
  /// kubelet's gRPC probes, which do not speak TLS). Empty: none.
  std::string health_address;
  /// HTTP address of the Prometheus metrics (GET /metrics) and a plain /healthz. Empty: none.
  std::string metrics_address;
  /// Largest request message [bytes].
  int max_receive_message_bytes = 4 * 1024 * 1024;
  ServiceLimits limits;
  ConnectionOptions connections;
  /// Bearer tokens file (lines `TOKEN [plan,stream]`); empty: none.
  std::string auth_tokens_file;
  /// One more bearer token with every scope (from the environment); empty: none.
  std::string auth_token;
  /// Log format ("text" or "json") and level ("debug", "info", "warning", "error"); logs go
  /// to `log_output` (stderr when null).
  std::string log_format = "text";
  std::string log_level = "info";
  std::FILE* log_output = nullptr;
  /// Robot model files (proto3 JSON of geotraj.v1.RobotModel) served beside the built-in
  /// models, by their `name`.
  std::vector<std::string> robot_model_files;
};

class Runtime;
class HttpExporter;

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
  int port = 0;          ///< the bound TCP port; 0 without a listening address
  int health_port = 0;   ///< the health-only port; 0 without one
  int metrics_port = 0;  ///< the metrics HTTP port; 0 without one
};

/// Builds and starts the server, then warms it up (one plan, one analysis, in process) and
/// reports SERVING on the health service for "" and "geotraj.v1.TrajectoryService" as soon
/// as it listens, and for kReadinessService once warm. Error: a sentence saying why the
/// server could not start (the address is in use, a certificate or tokens file is
/// unreadable, plaintext was not asked for on a public address, a robot model file is
/// invalid: the file and the field are named).
tl::expected<RunningServer, std::string> start_server(const ServerOptions& options);

/// Graceful shutdown: health turns NOT_SERVING on every name, new calls are refused with
/// UNAVAILABLE (trailers only, so clients retry them elsewhere), and calls in flight may
/// finish until `drain` has passed; new calls are refused for `lame_duck` at least (at most
/// `drain`), so that clients and load balancers move away before the server closes its
/// connections. Then the server shuts down, cancelling what is left.
void stop_server(RunningServer& running, std::chrono::milliseconds drain,
                 std::chrono::milliseconds lame_duck = std::chrono::milliseconds(0));

/// The Prometheus text exposition of the server's metrics.
std::string metrics_exposition(const RunningServer& running);

/// Logs one line through the server's logger (start-up and shutdown messages of geotrajd).
void log_info(const RunningServer& running, std::string_view message,
              const std::vector<std::pair<std::string, std::string>>& fields = {});

/// Health service name that reports readiness: SERVING once warm, NOT_SERVING while draining.
inline constexpr const char* kReadinessService = "geotraj.readiness";

/// Name of the service on the health service and in reflection.
inline constexpr const char* kServiceName = "geotraj.v1.TrajectoryService";

}  // namespace geotraj::server
