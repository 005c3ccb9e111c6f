// The operator's page and a JSON API over HTTP (geotrajd --web-address). Each API route is
// one RPC of the TrajectoryService in the proto3 JSON mapping, called through the server's
// in-process channel: the page and the scripts that use the API meet the same bearer
// tokens, limits, admission, deadlines, drain, metrics and logs as gRPC clients, and an
// answer is the gRPC answer to the same request, written as JSON. HTTP (and TLS) by
// Boost.Beast and Asio, with a deadline and a size limit on every part of a request
// (docs/web-api.md); the JSON mapping by protobuf's util/json_util.
//
//   POST /v1/convert  ConvertRequest           -> ConvertResponse
//   POST /v1/plan     PlanRequest              -> PlanResponse
//   POST /v1/analyze  PlanRequest              -> PathProfile
//   POST /v1/fk       ForwardKinematicsRequest -> ForwardKinematicsResponse
//   POST /v1/ik       InverseKinematicsRequest -> InverseKinematicsResponse
//   GET  /v1/robots                            -> ListRobotsResponse
//   POST /v1/stream   PlanRequest              -> SampleBatch, one JSON object per line
//                                                 (application/x-ndjson)
//   GET  /            the page (index.html and its files from the web root)
//
// A refused call answers the HTTP status of its gRPC code (400 INVALID_ARGUMENT, 401
// UNAUTHENTICATED, 403 PERMISSION_DENIED, 429 RESOURCE_EXHAUSTED, 503 UNAVAILABLE, 504
// DEADLINE_EXCEEDED, ...) with the google.rpc.Status as JSON, its BadRequest field
// violations included. A stream that fails after its first batch has sent its 200: its last
// line is then {"error": <google.rpc.Status>}. `Authorization: Bearer <token>` is passed on
// as the call's `authorization` metadata, `X-Request-Id` as its `x-request-id` (and the
// call's id comes back in the answer's X-Request-Id).
#pragma once

#include <chrono>
#include <cstddef>
#include <memory>
#include <string>

#include <grpcpp/channel.h>
#include <grpcpp/support/status.h>
#include <tl/expected.hpp>

#include "server/server.hpp"

namespace geotraj::server {

/// Where and how the web side listens, and what it lets one client take. start_server
/// fills the first four from ServerOptions; the rest keep their defaults there.
struct WebOptions {
  /// HOST:PORT or [IPV6]:PORT; port 0 picks a free port; an empty host means every address.
  std::string address;
  /// The page's files (index.html, app.js, ...). Empty or without index.html: the API
  /// only, and GET / says where the page was looked for.
  std::string root;
  /// The gRPC port's certificates: with them the web side speaks HTTPS (and with a client
  /// CA, asks for client certificates).
  TlsOptions tls;
  /// Largest request body [bytes] (the JSON of one request, chunked or not); beyond, 413.
  std::size_t max_request_bytes = 4 * 1024 * 1024;
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

/// The web side of a running server.
class WebGateway {
 public:
  /// Listens on options.address and serves, calling the service through `channel` (the
  /// server's in-process channel). The error names the address or the certificate file.
  static tl::expected<std::unique_ptr<WebGateway>, std::string> start(const WebOptions& options,
                                                                      std::shared_ptr<grpc::Channel> channel);
  ~WebGateway();
  WebGateway(const WebGateway&) = delete;
  WebGateway& operator=(const WebGateway&) = delete;

  /// The bound port (the chosen one when started with port 0).
  int port() const;
  /// Stops listening, closes the connections (cancelling their streams; the calls in
  /// progress end first, the queued ones are dropped); idempotent.
  void stop();

 private:
  struct State;
  explicit WebGateway(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

/// The HTTP status of a gRPC status code (google/rpc/code.proto's mapping).
int http_status(grpc::StatusCode code);

/// The google.rpc.Status of `status` in proto JSON: its code, message and details (the
/// BadRequest field violations) when the server gave them.
std::string status_json(const grpc::Status& status);

}  // namespace geotraj::server
