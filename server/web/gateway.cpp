#include "server/web/gateway.hpp"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "google/rpc/status.pb.h"
#include "server/ops/runtime.hpp"
#include "server/ops/socket.hpp"
#include "server/wire/status.hpp"
#include "server/wire/text.hpp"

// After Eigen (through status.hpp): httplib.h brings <resolv.h>, whose `_res` macro breaks
// Eigen's parameters of that name.
#include <httplib.h>

namespace geotraj::server {
namespace {

namespace v1 = geotraj::v1;
namespace pbu = google::protobuf::util;
using Stub = v1::TrajectoryService::Stub;

// With a charset: cpp-httplib (Debian's is built with brotli) compresses a body whose type
// is exactly application/json, or text/*, for every client that accepts br or gzip, and
// brotli at its default quality takes 0.3-0.8 s for a 200 kB analysis on this machine,
// against 8 ms to send it as it is. The page is served on loopback or a LAN: no
// compression of the API's answers or the page's bundle.
constexpr const char* kJson = "application/json; charset=utf-8";
constexpr const char* kNdjson = "application/x-ndjson";
// What a parse error of the body may add to its status message.
constexpr std::size_t kMaxParseErrorBytes = 512;

// Proto3 JSON: lowerCamelCase names, enums by name, fields at their default left out (as
// grpcurl and the other proto3 JSON printers write them), 64-bit integers as strings.
std::string to_json(const google::protobuf::Message& message) {
  std::string out;
  (void)pbu::MessageToJsonString(message, &out, pbu::JsonPrintOptions{});
  return out;
}

void reply_status(httplib::Response& res, const grpc::Status& status) {
  res.status = http_status(status.error_code());
  res.set_content(status_json(status), kJson);
}

// The request in `body`, or INVALID_ARGUMENT naming what is wrong with it. Unknown fields
// are refused (a misspelt field would otherwise be a silent default).
template <class Message>
std::optional<grpc::Status> parse_body(const std::string& body, Message& message) {
  const std::string name = Message::descriptor()->full_name();
  if (body.find_first_not_of(" \t\r\n") == std::string::npos) {
    return invalid_argument(core::Violations{{"", "the request body is empty: send a " + name + " in proto JSON"}});
  }
  // JSON is UTF-8 (RFC 8259), and protobuf's JSON parser lets invalid bytes through into
  // string fields (its binary parser refuses them): a robot name of such bytes would come
  // back in an error message no client could decode.
  for (std::size_t i = 0; i < body.size();) {
    const std::size_t n = utf8_sequence(body, i);
    if (n == 0) {
      return invalid_argument(core::Violations{
          {"", "the request body is not valid UTF-8 (byte " + std::to_string(i) + "): JSON text is UTF-8"}});
    }
    i += n;
  }
  pbu::JsonParseOptions options;
  options.ignore_unknown_fields = false;
  if (const auto parsed = pbu::JsonStringToMessage(body, &message, options); !parsed.ok()) {
    return invalid_argument(core::Violations{
        {"", "the request body is not a " + name + " in proto JSON: " +
                 truncated(std::string(parsed.message()), kMaxParseErrorBytes)}});
  }
  return std::nullopt;
}

// The HTTP request's bearer token and request id become the call's metadata, checked and
// logged by the service as a gRPC client's would be; the HTTP client's address is logged
// as the call's peer (the service honours it on in-process calls only).
void pass_on(const httplib::Request& req, grpc::ClientContext& context) {
  if (req.has_header("Authorization")) context.AddMetadata("authorization", req.get_header_value("Authorization"));
  if (req.has_header("X-Request-Id")) context.AddMetadata("x-request-id", req.get_header_value("X-Request-Id"));
  context.AddMetadata(std::string(kWebPeerMetadata), req.remote_addr + ":" + std::to_string(req.remote_port));
}

// The call's request id (in its initial metadata, or its trailers when it was refused) as
// the X-Request-Id header of the answer.
void pass_back(const grpc::ClientContext& context, httplib::Response& res) {
  for (const auto* metadata : {&context.GetServerInitialMetadata(), &context.GetServerTrailingMetadata()}) {
    if (const auto id = metadata->find("x-request-id"); id != metadata->end()) {
      res.set_header("X-Request-Id", std::string(id->second.data(), id->second.size()));
      return;
    }
  }
}

template <class Request, class Response>
using UnaryMethod = grpc::Status (Stub::*)(grpc::ClientContext*, const Request&, Response*);

template <class Request, class Response>
void unary(Stub& stub, UnaryMethod<Request, Response> method, const httplib::Request& req, httplib::Response& res) {
  Request request;
  if (auto bad = parse_body(req.body, request)) return reply_status(res, *bad);
  grpc::ClientContext context;
  pass_on(req, context);
  Response response;
  const auto status = (stub.*method)(&context, request, &response);
  pass_back(context, res);
  if (!status.ok()) return reply_status(res, status);
  res.set_content(to_json(response), kJson);
}

// One StreamSamples call that a chunked response reads from, owned by the response's
// content provider and released when the response ends (or its client goes away).
struct StreamCall {
  grpc::ClientContext context;
  std::unique_ptr<grpc::ClientReader<v1::SampleBatch>> reader;
  std::string pending;  // the first batch's line, read before the status was chosen
  bool finished = false;

  // Ends the call when the HTTP client left before its end: cancel, then read what is
  // left so that Finish() does not wait on the server.
  void abandon() {
    if (finished) return;
    context.TryCancel();
    v1::SampleBatch rest;
    while (reader->Read(&rest)) {
    }
    (void)reader->Finish();
    finished = true;
  }
};

// POST /v1/stream: the status is chosen after the first batch (or the failure before it),
// so a refused request gets its HTTP status and JSON error like a unary call; then one
// line per batch.
void stream(Stub& stub, const httplib::Request& req, httplib::Response& res) {
  v1::PlanRequest request;
  if (auto bad = parse_body(req.body, request)) return reply_status(res, *bad);
  auto call = std::make_shared<StreamCall>();
  pass_on(req, call->context);
  call->reader = stub.StreamSamples(&call->context, request);
  v1::SampleBatch first;
  if (!call->reader->Read(&first)) {
    call->finished = true;
    const auto status = call->reader->Finish();
    pass_back(call->context, res);
    if (!status.ok()) return reply_status(res, status);
    res.set_content("", kNdjson);  // a motion without samples
    return;
  }
  pass_back(call->context, res);
  call->pending = to_json(first) + "\n";
  res.set_chunked_content_provider(
      kNdjson,
      [call](std::size_t, httplib::DataSink& sink) {
        if (!call->pending.empty()) {
          const std::string line = std::exchange(call->pending, {});
          return sink.write(line.data(), line.size());
        }
        v1::SampleBatch batch;
        if (call->reader->Read(&batch)) {
          const std::string line = to_json(batch) + "\n";
          return sink.write(line.data(), line.size());
        }
        call->finished = true;
        if (const auto status = call->reader->Finish(); !status.ok()) {
          const std::string line = "{\"error\":" + status_json(status) + "}\n";
          if (!sink.write(line.data(), line.size())) return false;
        }
        sink.done();
        return true;
      },
      [call](bool) { call->abandon(); });
}

// A route's wrong method: 405 with the methods it takes.
void wrong_method(httplib::Response& res, const char* allow) {
  res.set_header("Allow", allow);
  res.status = 405;
  res.set_content(status_json(grpc::Status(grpc::StatusCode::UNIMPLEMENTED,
                                           std::string("this route takes ") + allow + " only")),
                  kJson);
}

// cpp-httplib's task queue with a bound: `threads` serve connections, at most `queued` wait
// for one, and a connection beyond them is served on the accepting thread itself, which
// accepts nothing meanwhile (cpp-httplib 0.11's ThreadPool queues without end, one open
// descriptor each, taken from the descriptors the gRPC port needs too).
class BoundedPool : public httplib::TaskQueue {
 public:
  BoundedPool(std::size_t threads, std::size_t queued) : queued_(queued) {
    for (std::size_t k = 0; k < threads; ++k) threads_.emplace_back([this] { work(); });
  }
  ~BoundedPool() override { shutdown(); }

  void enqueue(std::function<void()> fn) override {
    {
      const std::lock_guard lock(mutex_);
      if (!stopping_ && jobs_.size() < queued_) {
        jobs_.push_back(std::move(fn));
        ready_.notify_one();
        return;
      }
    }
    fn();  // backpressure: the accepting thread serves this one
  }

  void shutdown() override {
    {
      const std::lock_guard lock(mutex_);
      if (stopping_ && threads_.empty()) return;
      stopping_ = true;
    }
    ready_.notify_all();
    for (auto& t : threads_) t.join();
    threads_.clear();
  }

 private:
  void work() {
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock lock(mutex_);
        ready_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
        if (jobs_.empty()) return;  // stopping, and nothing left to serve
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      job();
    }
  }

  const std::size_t queued_;
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> jobs_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

bool is_api(const std::string& path) { return path.rfind("/v1/", 0) == 0 || path == "/v1"; }

}  // namespace

int http_status(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return 200;
    case grpc::StatusCode::CANCELLED: return 499;
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::OUT_OF_RANGE: return 400;
    case grpc::StatusCode::DEADLINE_EXCEEDED: return 504;
    case grpc::StatusCode::NOT_FOUND: return 404;
    case grpc::StatusCode::ALREADY_EXISTS:
    case grpc::StatusCode::ABORTED: return 409;
    case grpc::StatusCode::PERMISSION_DENIED: return 403;
    case grpc::StatusCode::UNAUTHENTICATED: return 401;
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return 429;
    case grpc::StatusCode::UNIMPLEMENTED: return 501;
    case grpc::StatusCode::UNAVAILABLE: return 503;
    default: return 500;  // UNKNOWN, INTERNAL, DATA_LOSS
  }
}

std::string status_json(const grpc::Status& status) {
  google::rpc::Status out;
  if (status.error_details().empty() || !out.ParseFromString(status.error_details())) out.Clear();
  out.set_code(static_cast<int>(status.error_code()));
  out.set_message(status.error_message());
  std::string json;
  if (!pbu::MessageToJsonString(out, &json).ok()) {  // details of a type this binary does not know
    out.clear_details();
    json.clear();
    (void)pbu::MessageToJsonString(out, &json);
  }
  return json;
}

struct WebGateway::State {
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<Stub> stub;
  std::unique_ptr<httplib::Server> http;
  std::thread thread;
  int port = 0;
  std::mutex stop_mutex;
};

WebGateway::WebGateway(std::unique_ptr<State> state) : state_(std::move(state)) {}
WebGateway::~WebGateway() { stop(); }
int WebGateway::port() const { return state_->port; }

void WebGateway::stop() {
  const std::lock_guard lock(state_->stop_mutex);
  if (!state_->thread.joinable()) return;
  state_->http->stop();
  state_->thread.join();
}

tl::expected<std::unique_ptr<WebGateway>, std::string> WebGateway::start(const WebOptions& options,
                                                                         std::shared_ptr<grpc::Channel> channel) {
  const auto address = split_host_port(options.address, "the web address \"" + options.address + "\"");
  if (!address) return tl::make_unexpected(address.error());
  auto state = std::make_unique<State>();
  state->channel = std::move(channel);
  state->stub = v1::TrajectoryService::NewStub(state->channel);
  if (options.tls.enabled()) {
    // The files were read and checked for the gRPC port already (start_server).
    auto https = std::make_unique<httplib::SSLServer>(
        options.tls.cert_file.c_str(), options.tls.key_file.c_str(),
        options.tls.client_ca_file.empty() ? nullptr : options.tls.client_ca_file.c_str());
    if (!https->is_valid()) {
      return tl::make_unexpected("cannot serve HTTPS on the web address \"" + options.address +
                                 "\" with the certificate \"" + options.tls.cert_file + "\" and key \"" +
                                 options.tls.key_file + "\"");
    }
    state->http = std::move(https);
  } else {
    state->http = std::make_unique<httplib::Server>();
  }
  httplib::Server& http = *state->http;
  const auto threads = static_cast<std::size_t>(std::max(1, options.threads));
  const auto queued = options.max_queued_connections;
  http.new_task_queue = [threads, queued] { return new BoundedPool(threads, queued); };
  // An answer's head and body go out as separate writes: with Nagle's algorithm the body
  // would wait for the client's delayed ACK of the head (40 ms on Linux) on every call.
  http.set_tcp_nodelay(true);
  http.set_payload_max_length(options.max_request_bytes);
  const auto idle_ms = std::max<std::chrono::milliseconds::rep>(1, options.idle_timeout.count());
  http.set_read_timeout(idle_ms / 1000, (idle_ms % 1000) * 1000);
  http.set_write_timeout(idle_ms / 1000, (idle_ms % 1000) * 1000);
  http.set_keep_alive_timeout((idle_ms + 999) / 1000);
  http.set_default_headers({
      {"X-Content-Type-Options", "nosniff"},
      {"Referrer-Policy", "no-referrer"},
      // The page loads its own files only and talks to this server only.
      {"Content-Security-Policy",
       "default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "
       "connect-src 'self'; worker-src 'self' blob:; frame-ancestors 'none'; base-uri 'none'; form-action 'none'"},
  });

  Stub& stub = *state->stub;
  http.Post("/v1/convert", [&stub](const httplib::Request& req, httplib::Response& res) {
    unary<v1::ConvertRequest, v1::ConvertResponse>(stub, &Stub::ConvertConstraints, req, res);
  });
  http.Post("/v1/plan", [&stub](const httplib::Request& req, httplib::Response& res) {
    unary<v1::PlanRequest, v1::PlanResponse>(stub, &Stub::PlanTrajectory, req, res);
  });
  http.Post("/v1/analyze", [&stub](const httplib::Request& req, httplib::Response& res) {
    unary<v1::PlanRequest, v1::PathProfile>(stub, &Stub::AnalyzePath, req, res);
  });
  http.Post("/v1/fk", [&stub](const httplib::Request& req, httplib::Response& res) {
    unary<v1::ForwardKinematicsRequest, v1::ForwardKinematicsResponse>(stub, &Stub::ComputeForwardKinematics, req, res);
  });
  http.Post("/v1/ik", [&stub](const httplib::Request& req, httplib::Response& res) {
    unary<v1::InverseKinematicsRequest, v1::InverseKinematicsResponse>(stub, &Stub::ComputeInverseKinematics, req,
                                                                       res);
  });
  http.Get("/v1/robots", [&stub](const httplib::Request& req, httplib::Response& res) {
    grpc::ClientContext context;
    pass_on(req, context);
    v1::ListRobotsResponse response;
    const auto status = stub.ListRobots(&context, v1::ListRobotsRequest{}, &response);
    pass_back(context, res);
    if (!status.ok()) return reply_status(res, status);
    res.set_content(to_json(response), kJson);
  });
  http.Post("/v1/stream", [&stub](const httplib::Request& req, httplib::Response& res) { stream(stub, req, res); });
  for (const char* route : {"/v1/convert", "/v1/plan", "/v1/analyze", "/v1/fk", "/v1/ik", "/v1/stream"}) {
    http.Get(route, [](const httplib::Request&, httplib::Response& res) { wrong_method(res, "POST"); });
  }
  http.Post("/v1/robots", [](const httplib::Request&, httplib::Response& res) { wrong_method(res, "GET"); });

  const std::filesystem::path root(options.root);
  std::error_code ignored;
  if (!options.root.empty() && std::filesystem::is_regular_file(root / "index.html", ignored)) {
    http.set_mount_point("/", options.root);
    http.set_file_extension_and_mimetype_mapping("js", "application/javascript; charset=utf-8");
    http.set_file_extension_and_mimetype_mapping("mjs", "application/javascript; charset=utf-8");
    http.set_file_extension_and_mimetype_mapping("map", "application/json");
  } else {
    const std::string where = options.root.empty() ? std::string("no web root was given (--web-root)")
                                                   : "\"" + options.root + "\" has no index.html";
    http.Get("/", [where](const httplib::Request&, httplib::Response& res) {
      res.status = 503;
      res.set_content("The operator's page is not installed: " + where +
                          ". The JSON API under /v1/ is served; build with node and npm to install the page.\n",
                      "text/plain; charset=utf-8");
    });
  }
  // Errors of the API (unknown route, oversized body, an exception) as google.rpc.Status
  // JSON; those of the page as text.
  http.set_error_handler(httplib::Server::HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
    if (!is_api(req.path) || !res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
    grpc::StatusCode code = grpc::StatusCode::INTERNAL;
    std::string message = "the request failed (HTTP " + std::to_string(res.status) + ")";
    if (res.status == 404) {
      code = grpc::StatusCode::NOT_FOUND;
      message = "no API route " + truncated(req.path, 256) +
                ": POST /v1/convert, /v1/plan, /v1/analyze, /v1/fk, /v1/ik, /v1/stream; GET /v1/robots";
    } else if (res.status == 413) {
      code = grpc::StatusCode::RESOURCE_EXHAUSTED;
      message = "the request body is larger than the largest request (--max-request-bytes)";
    } else if (res.status == 400) {
      code = grpc::StatusCode::INVALID_ARGUMENT;
      message = "the HTTP request is malformed";
    }
    res.set_content(status_json(grpc::Status(code, message)), kJson);
    return httplib::Server::HandlerResponse::Handled;
  }));
  http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
    res.status = 500;
    res.set_content(status_json(grpc::Status(grpc::StatusCode::INTERNAL, "the web gateway failed on this request")),
                    kJson);
  });

  const std::string host = address->host.empty() ? "0.0.0.0" : address->host;  // empty: every IPv4 address
  const int port = std::stoi(address->port);
  state->port = port == 0 ? http.bind_to_any_port(host) : (http.bind_to_port(host, port) ? port : -1);
  if (state->port <= 0) {
    return tl::make_unexpected("cannot listen on the web address \"" + options.address +
                               "\" (in use, or not an address of this machine)");
  }
  state->thread = std::thread([&http] { http.listen_after_bind(); });
  return std::unique_ptr<WebGateway>(new WebGateway(std::move(state)));
}

}  // namespace geotraj::server
