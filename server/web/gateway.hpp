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

#include "server/options.hpp"

namespace geotraj::server {

/// Where and how the web side listens, and what it lets one client take (WebLimits, in
/// server/options.hpp). start_server fills it from ServerOptions.
struct WebOptions : WebLimits {
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
