// The server's configuration as values: what one call may ask (ServiceLimits), the ports,
// TLS, connections, the web side's limits, logging and robot model files (ServerOptions),
// and the names the health service answers for. A leaf: the wire, ops and web layers read
// these without knowing the running server (server/server.hpp).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace geotraj::server {

/// A live call takes one --max-streams slot per this many Hz of its cycle rate (or part of
/// it): a 10 kHz Jog takes 10, a 100 Hz one 1.
inline constexpr double kLiveRateUnitHz = 1000.0;

/// What one call may ask of the server. Each refusal names the limit and its flag.
struct ServiceLimits {
  /// Streams in flight, health watches included; beyond, RESOURCE_EXHAUSTED (the callback
  /// API itself is unbounded).
  int max_streams = 256;
  /// grpc.health.v1.Health/Watch streams in flight (they need no token, so they may take
  /// only this many of max_streams); beyond, RESOURCE_EXHAUSTED.
  int max_health_watches = 16;
  /// Unary calls in flight (plans, analyses, conversions); beyond, RESOURCE_EXHAUSTED.
  int max_unary_calls = 64;
  /// Set points per second of all live calls (Execute, Jog) together [Hz]: a live call is
  /// admitted at its cycle rate while the sum of the rates in flight stays within this;
  /// beyond, RESOURCE_EXHAUSTED naming --max-live-rate-hz. (A live call also takes one
  /// --max-streams slot per kLiveRateUnitHz of its rate or part of it, at least one.)
  double max_live_rate_hz = 50'000.0;
  /// Samples of one Execute plan (its duration times its cycle rate), checked before it is
  /// planned when the request gives the duration, and before its live pass; beyond,
  /// INVALID_ARGUMENT naming --max-live-samples. The smaller of it and max_stream_samples holds.
  std::uint64_t max_live_samples = 1'000'000;
  /// Threads that make the live calls' set points (off gRPC's threads, at normal priority,
  /// one batch at a time in the order they fall due).
  int pacing_threads = 1;
  /// Key frames in one path (ConvertRequest, PlanRequest).
  int max_frames = 1000;
  /// Samples in one motion that is streamed or followed by a robot (IK at every sample).
  std::uint64_t max_stream_samples = 10'000'000;
  /// Time one call may spend optimising [s]: the default optimize.timeBudgetS and its
  /// largest accepted value.
  double max_optimize_seconds = 30.0;
  /// Points of one AnalyzePath answer (analysisPoints); beyond, INVALID_ARGUMENT.
  std::uint64_t max_analysis_points = 100'001;
  /// Largest answer of a unary call [bytes]; beyond, RESOURCE_EXHAUSTED naming the flag.
  std::uint64_t max_response_bytes = 32ull * 1024 * 1024;
  /// The deadline of a call whose client gives none (and the longest planning of a stream)
  /// [s]; a client's earlier deadline wins. A stream's samples are not bounded by it.
  double default_deadline_s = 120.0;
  /// Threads that run plans, optimisations, analyses and the planning of streams, off
  /// gRPC's threads; 0: one per CPU core. One more thread plans streams only, so a stream
  /// never waits behind unary plans. Calls beyond them wait in the admission queue, whose
  /// length max_unary_calls (and max_streams) bound.
  int workers = 0;
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
  /// A connection that has not sent the HTTP/2 preface and settings (and, with TLS, finished
  /// its handshake) within this is closed [s].
  double handshake_timeout_s = 10.0;
  /// A connection with no call for this long is closed (GOAWAY) [s]; 0: never.
  double max_connection_idle_s = 600.0;
  /// TCP connections open at once on the gRPC port (and on the health port); beyond, a new
  /// connection is closed at once. Lowered at start-up to fit the descriptor limit (which is
  /// raised to its hard limit first).
  int max_connections = 4096;
};

/// What the web port (ServerOptions::web_address) lets its clients take: threads,
/// connections, streams, time and memory. Each has a geotrajd flag (--web-...).
struct WebLimits {
  /// Threads that make the unary routes' calls (blocking gRPC calls, off the I/O threads)
  /// and print their answers as JSON; a stream takes one only to start. Few, and at the
  /// workers' CPU priority: sixteen large analyses at once wait here rather than fill the
  /// server's workers ahead of every gRPC call, or starve them printing JSON.
  int threads = 2;
  /// Calls that wait for one of those threads; one beyond them is refused with 503 and
  /// Retry-After.
  std::size_t max_queued_calls = 64;
  /// Threads that read and write the connections (non-blocking).
  int io_threads = 2;
  /// Connections open at once; a new one beyond them closes the oldest that is reading a
  /// request (idle or slow), or is closed itself when every one is busy.
  std::size_t max_connections = 256;
  /// A connection that sends nothing for this long within a request, takes nothing for this
  /// long within a streamed answer, or sends no request for this long after the last, is
  /// closed.
  std::chrono::milliseconds idle_timeout{5000};
  /// A request's head (request line and headers) must have arrived within this long of the
  /// connection (or of the end of the answer before).
  std::chrono::milliseconds header_timeout{10000};
  /// A request's head and body must have arrived within this long; an answer of a unary
  /// route or a file must have been taken within this long.
  std::chrono::milliseconds request_timeout{30000};
  /// Largest request head [bytes]; beyond, 431.
  std::size_t max_header_bytes = 16 * 1024;
  /// /v1/stream calls in flight from the web port (each counts against the server's
  /// --max-streams too); beyond, 429.
  int max_streams = 32;
  /// Bytes of unary answers made and not yet taken by their clients; while beyond, new
  /// calls are refused with 503 and Retry-After.
  std::size_t max_answer_bytes = 256 * 1024 * 1024;
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
  /// HTTP address of the operator's page and its JSON API (server/web/gateway.hpp), with
  /// the gRPC port's TLS, tokens and limits; the same loopback rule without TLS. Empty: none.
  std::string web_address;
  /// The page's files (index.html, app.js, ...); empty: the API only.
  std::string web_root;
  /// What the web port lets its clients take.
  WebLimits web_limits;
  /// Largest request message [bytes].
  int max_receive_message_bytes = 4 * 1024 * 1024;
  ServiceLimits limits;
  ConnectionOptions connections;
  /// Bearer tokens file (lines `TOKEN [plan,stream,move]`); empty: none.
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
  /// MoveIt joint_limits.yaml files (planner/joint_limits_yaml.hpp): the limits of the robot
  /// model files' joints they name, over each file's own (the accelerations a URDF lacks).
  std::vector<std::string> joint_limits_files;
};

/// Health service name that reports readiness: SERVING once warm, NOT_SERVING while draining.
inline constexpr const char* kReadinessService = "geotraj.readiness";

/// Name of the service on the health service and in reflection.
inline constexpr const char* kServiceName = "geotraj.v1.TrajectoryService";

}  // namespace geotraj::server
