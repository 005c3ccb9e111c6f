#include "server/web/gateway.hpp"

#include <malloc.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <list>
#include <mutex>
#include <optional>
#include <sstream>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>
#include <grpcpp/support/client_callback.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "google/rpc/status.pb.h"
#include "server/ops/log.hpp"
#include "server/ops/runtime.hpp"
#include "server/ops/socket.hpp"
#include "server/ops/worker_pool.hpp"
#include "server/ops/tsan.hpp"
#include "server/wire/status.hpp"
#include "server/wire/text.hpp"

namespace geotraj::server {
namespace {

namespace v1 = geotraj::v1;
namespace pbu = google::protobuf::util;
namespace net = boost::asio;
namespace ssl = boost::asio::ssl;
namespace beast = boost::beast;
namespace http = boost::beast::http;
using tcp = boost::asio::ip::tcp;
using Stub = v1::TrajectoryService::Stub;
using Clock = std::chrono::steady_clock;
using Request = http::request<http::string_body>;
using Response = http::response<http::string_body>;

// No compression of the API's answers or the page's files: the page is served on loopback
// or a LAN, where compressing a 200 kB analysis costs more than sending it.
constexpr const char* kJson = "application/json; charset=utf-8";
constexpr const char* kNdjson = "application/x-ndjson";
constexpr const char* kText = "text/plain; charset=utf-8";
// What a parse error of the body may add to its status message.
constexpr std::size_t kMaxParseErrorBytes = 512;
// The longest Authorization header passed on: a bearer token is far shorter.
constexpr std::size_t kMaxAuthorizationBytes = 4096;
// An answer body this large is followed, once sent and freed, by malloc_trim: glibc keeps
// freed memory of large blocks in the heap otherwise (1.1 GB after 16 large analyses).
constexpr std::size_t kTrimAfterBytes = 1 << 20;
// After an answer that ends a connection whose request was not read whole (413, 431, 400):
// what is still read (and thrown away) so that the client reads the answer before the
// close, rather than a reset that may discard it.
constexpr std::size_t kLingerBytes = 1 << 20;
// What the read buffer holds beyond the largest head: a chunk's size line with its
// extensions, or the trailer, must fit in it (Beast bounds neither, and its buffer would
// grow with them), and a body passes through it this much at a time.
constexpr std::size_t kFramingBytes = 64 * 1024;
constexpr std::chrono::milliseconds kLinger{1000};

const char* const kRoutes = "POST /v1/convert, /v1/plan, /v1/analyze, /v1/fk, /v1/ik, /v1/stream; GET /v1/robots";

// Proto3 JSON: lowerCamelCase names, enums by name, fields at their default left out (as
// grpcurl and the other proto3 JSON printers write them), 64-bit integers as strings.
std::string to_json(const google::protobuf::Message& message) {
  std::string out;
  (void)pbu::MessageToJsonString(message, &out, pbu::JsonPrintOptions{});
  return out;
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

// Whether gRPC can carry `value` as the value of an ASCII metadata key: printable ASCII
// only (0x20-0x7e). gRPC asserts, and the process aborts, on any other byte (a tab, a
// control byte, UTF-8), so nothing a client sends reaches metadata unchecked.
bool metadata_safe(std::string_view value) {
  return std::all_of(value.begin(), value.end(), [](char c) { return c >= 0x20 && c <= 0x7e; });
}

// The HTTP request's bearer token and request id become the call's metadata, checked and
// logged by the service as a gRPC client's would be; the HTTP client's address is logged
// as the call's peer (the service honours it on in-process calls only). A request id the
// service would not take (the rule of valid_request_id) is left out: the call gets its own,
// as a gRPC call with such an id does. An Authorization header gRPC cannot carry is
// refused (INVALID_ARGUMENT naming it).
std::optional<grpc::Status> pass_on(const Request& req, const std::string& peer, grpc::ClientContext& context) {
  if (const auto auth = req.find(http::field::authorization); auth != req.end()) {
    const std::string_view value(auth->value().data(), auth->value().size());
    if (value.size() > kMaxAuthorizationBytes) {
      return invalid_argument(core::Violations{
          {"", "the Authorization header has " + std::to_string(value.size()) + " bytes, more than " +
                   std::to_string(kMaxAuthorizationBytes) + ": send \"Bearer <token>\""}});
    }
    if (!metadata_safe(value)) {
      return invalid_argument(core::Violations{
          {"", "the Authorization header holds a byte that is not printable ASCII (a tab, a control byte or a "
               "non-ASCII byte): send \"Bearer <token>\""}});
    }
    context.AddMetadata("authorization", std::string(value));
  }
  if (const auto id = req.find("X-Request-Id"); id != req.end()) {
    const std::string_view value(id->value().data(), id->value().size());
    if (valid_request_id(value)) context.AddMetadata("x-request-id", std::string(value));
  }
  if (metadata_safe(peer)) context.AddMetadata(std::string(kWebPeerMetadata), peer);
  return std::nullopt;
}

// The call's request id (in its initial metadata, or its trailers when it was refused).
std::string request_id_of(const grpc::ClientContext& context, bool trailers_too) {
  const auto& initial = context.GetServerInitialMetadata();
  if (const auto id = initial.find("x-request-id"); id != initial.end()) {
    return std::string(id->second.data(), id->second.size());
  }
  if (trailers_too) {
    const auto& trailing = context.GetServerTrailingMetadata();
    if (const auto id = trailing.find("x-request-id"); id != trailing.end()) {
      return std::string(id->second.data(), id->second.size());
    }
  }
  return {};
}

// Headers of every answer.
template <class Fields>
void decorate(Fields& fields) {
  fields.set(http::field::server, "geotrajd");
  fields.set("X-Content-Type-Options", "nosniff");
  fields.set("Referrer-Policy", "no-referrer");
  // The page loads its own files only and talks to this server only.
  fields.set("Content-Security-Policy",
             "default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "
             "connect-src 'self'; worker-src 'self' blob:; frame-ancestors 'none'; base-uri 'none'; form-action "
             "'none'");
}

Response answer(unsigned status, std::string body, const char* type) {
  Response res{static_cast<http::status>(status), 11};
  decorate(res);
  res.set(http::field::content_type, type);
  res.body() = std::move(body);
  return res;
}

Response status_answer(const grpc::Status& status, const std::string& request_id = {}) {
  auto res = answer(static_cast<unsigned>(http_status(status.error_code())), status_json(status), kJson);
  if (!request_id.empty()) res.set("X-Request-Id", request_id);
  return res;
}

// A route's wrong method: 405 with the methods it takes.
Response wrong_method(const char* allow) {
  auto res = status_answer(
      grpc::Status(grpc::StatusCode::UNIMPLEMENTED, std::string("this route takes ") + allow + " only"));
  res.result(http::status::method_not_allowed);
  res.set(http::field::allow, allow);
  return res;
}

// The path of a request target: its query left out, %XX decoded. Empty when the target is
// not an origin form, an escape is malformed, or it holds a NUL (raw or %00): such a path
// names no file, and a NUL would cut it short where a C string is made of it.
std::optional<std::string> decoded_path(std::string_view target) {
  if (target.empty() || target.front() != '/') return std::nullopt;
  target = target.substr(0, target.find_first_of("?#"));
  std::string out;
  out.reserve(target.size());
  const auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (std::size_t i = 0; i < target.size(); ++i) {
    char c = target[i];
    if (c == '%') {
      if (i + 2 >= target.size()) return std::nullopt;
      const int hi = hex(target[i + 1]);
      const int lo = hex(target[i + 2]);
      if (hi < 0 || lo < 0) return std::nullopt;
      c = static_cast<char>(hi * 16 + lo);
      i += 2;
    }
    if (c == '\0') return std::nullopt;
    out.push_back(c);
  }
  return out;
}

bool is_api(std::string_view path) { return path.starts_with("/v1/") || path == "/v1"; }

// The content type of a file of the page, by its extension.
const char* content_type(const std::filesystem::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html" || ext == ".htm") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "application/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json" || ext == ".map") return "application/json";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".ico") return "image/x-icon";
  if (ext == ".wasm") return "application/wasm";
  if (ext == ".txt") return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

// The threads that make the blocking gRPC calls of the unary routes, off the I/O threads,
// with a bounded queue: a call beyond it is refused (503) rather than queued without end.
class CallPool {
 public:
  CallPool(std::size_t threads, std::size_t queued) : capacity_(threads + queued) {
    for (std::size_t k = 0; k < threads; ++k) threads_.emplace_back([this] { work(); });
  }
  ~CallPool() { shutdown(); }
  CallPool(const CallPool&) = delete;
  CallPool& operator=(const CallPool&) = delete;

  // False when every thread is busy and the queue is full, or the pool is stopping: the
  // caller refuses the call. A job handed to an idle thread that has not yet taken it
  // counts as that thread's, not the queue's.
  bool submit(std::function<void()> job) {
    {
      const std::lock_guard lock(mutex_);
      if (stopping_ || running_ + jobs_.size() >= capacity_) return false;
      jobs_.push_back(std::move(job));
    }
    ready_.notify_one();
    return true;
  }

  // Lets the running jobs end, drops the queued ones, joins.
  void shutdown() {
    std::deque<std::function<void()>> dropped;
    {
      const std::lock_guard lock(mutex_);
      stopping_ = true;
      dropped.swap(jobs_);
    }
    ready_.notify_all();
    for (auto& t : threads_) t.join();
    threads_.clear();
  }

 private:
  void work() {
    lower_priority(WorkerPool::kWorkerNice);  // below gRPC's threads, like the workers
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock lock(mutex_);
        ready_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
        if (stopping_) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
        ++running_;
      }
      job();
      const std::lock_guard lock(mutex_);
      --running_;
    }
  }

  const std::size_t capacity_;  // threads + queued calls
  std::size_t running_ = 0;     // jobs a thread has taken and not finished
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> jobs_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

// What a connection is doing, for the connection cap's choice of whom to close.
enum class Phase { reading, calling, writing };

class Connection {
 public:
  virtual ~Connection() = default;
  // Closes the connection from any thread (on its strand).
  virtual void close() = 0;
  std::atomic<Phase> phase{Phase::reading};
};

class StreamReactor;

// Where a stream's lines go: the connection it answers. Called from gRPC's threads; the
// connection takes them on its strand.
class StreamSink {
 public:
  virtual ~StreamSink() = default;
  virtual void stream_line(std::string line, std::string request_id) = 0;
  // The stream's end; the reactor (done) is the connection's to delete.
  virtual void stream_end(grpc::Status status, std::string request_id, StreamReactor* done) = 0;
};

struct Shared;

// One StreamSamples call read with gRPC's callback API: no thread waits on it between
// batches. One read at a time: the next starts once the connection has sent the last
// line (a client that reads slowly slows its stream, and holds no more than one batch).
// A hold keeps OnDone back until the connection is done with reads: the stream ends after
// its last read returned, or after its connection went away and the call was cancelled.
class StreamReactor final : public grpc::ClientReadReactor<v1::SampleBatch> {
 public:
  StreamReactor(Shared& shared, std::shared_ptr<StreamSink> sink) : shared_(shared), sink_(std::move(sink)) {}

  void start(Stub& stub, v1::PlanRequest request, const Request& req, const std::string& peer);
  // The connection sent the last line: the next batch.
  void next() {
    handoff_release(this);
    StartRead(&batch_);
  }
  // The connection will read no more (it went away, or a write failed).
  void abandon() {
    context_.TryCancel();
    handoff_release(this);
    RemoveHold();
  }
  void cancel() { context_.TryCancel(); }

  void OnReadDone(bool ok) override {
    handoff_acquire(this);
    if (!ok) {
      RemoveHold();
      return;
    }
    sink_->stream_line(to_json(batch_) + "\n", request_id_of(context_, false));
  }
  void OnDone(const grpc::Status& status) override;

 private:
  Shared& shared_;
  std::shared_ptr<StreamSink> sink_;
  grpc::ClientContext context_;
  v1::PlanRequest request_;
  v1::SampleBatch batch_;
};

// What every connection of a gateway shares.
struct Shared {
  WebOptions options;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<Stub> stub;
  std::optional<CallPool> pool;
  std::filesystem::path root;  // empty: no page installed
  std::string no_page;         // why, when so
  // Bytes of answers made and not yet sent (bounded by options.max_answer_bytes).
  std::atomic<std::size_t> answer_bytes{0};
  std::atomic<int> streams{0};
  // Streams whose OnDone has not run yet: stop() waits for them.
  std::mutex reactors_mutex;
  std::condition_variable reactors_done;
  int reactors = 0;
};

void StreamReactor::start(Stub& stub, v1::PlanRequest request, const Request& req, const std::string& peer) {
  request_ = std::move(request);
  (void)pass_on(req, peer, context_);  // checked by the caller
  {
    const std::lock_guard lock(shared_.reactors_mutex);
    ++shared_.reactors;
  }
  stub.async()->StreamSamples(&context_, &request_, this);
  AddHold();
  handoff_release(this);
  StartRead(&batch_);
  StartCall();
}

void StreamReactor::OnDone(const grpc::Status& status) {
  handoff_acquire(this);
  // The connection deletes the reactor on its strand: until then it may still refer to it.
  Shared& shared = shared_;
  shared.streams.fetch_sub(1);
  const auto sink = std::move(sink_);
  sink->stream_end(status, request_id_of(context_, true), this);
  const std::lock_guard lock(shared.reactors_mutex);
  if (--shared.reactors == 0) shared.reactors_done.notify_all();
}

// One connection, plain or TLS: reads one request at a time (a pipelined one waits in the
// buffer and is answered after the one before, in order), each within the deadlines of
// WebOptions, answers it, and reads the next while the client keeps the connection alive.
template <class Stream>
class Session final : public Connection,
                      public StreamSink,
                      public std::enable_shared_from_this<Session<Stream>> {
 public:
  Session(Shared& shared, Stream stream, std::string peer)
      : shared_(shared),
        stream_(std::move(stream)),
        peer_(std::move(peer)),
        buffer_(shared.options.max_header_bytes + kFramingBytes) {}

  // Starts serving on the connection's strand.
  void start() {
    net::dispatch(lowest().get_executor(), [self = this->shared_from_this()] { self->run(); });
  }

  void run() {
    if constexpr (std::is_same_v<Stream, beast::tcp_stream>) {
      start_request();
    } else {
      lowest().expires_after(shared_.options.header_timeout);
      stream_.async_handshake(ssl::stream_base::server, [self = this->shared_from_this()](beast::error_code ec) {
        if (ec) return self->shut();
        self->start_request();
      });
    }
  }

  void close() override {
    net::post(lowest().get_executor(), [self = this->shared_from_this()] { self->shut(); });
  }

  void stream_line(std::string line, std::string request_id) override {
    net::post(lowest().get_executor(), [self = this->shared_from_this(), line = std::move(line),
                                        id = std::move(request_id)]() mutable { self->send_line(std::move(line), id); });
  }

  void stream_end(grpc::Status status, std::string request_id, StreamReactor* done) override {
    net::post(lowest().get_executor(),
              [self = this->shared_from_this(), status = std::move(status), id = std::move(request_id),
               done = std::shared_ptr<StreamReactor>(done)] { self->end_stream(status, id); });
  }

 private:
  beast::tcp_stream& lowest() { return beast::get_lowest_layer(stream_); }

  // The connection is done: its stream (if any) cancelled, its socket closed.
  void shut() {
    if (closed_) return;
    closed_ = true;
    // A read outstanding: cancelled (its end removes the hold); a line being written: its
    // write fails and abandons the stream.
    if (reactor_ != nullptr && reading_stream_) reactor_->cancel();
    beast::error_code ignored;
    lowest().socket().shutdown(tcp::socket::shutdown_both, ignored);
    lowest().close();
  }

  void start_request() {
    if (closed_) return;
    phase.store(Phase::reading);
    head_ = false;
    http10_ = false;
    parser_.emplace();
    parser_->header_limit(static_cast<std::uint32_t>(shared_.options.max_header_bytes));
    parser_->body_limit(shared_.options.max_request_bytes);
    const auto now = Clock::now();
    head_deadline_ = now + shared_.options.header_timeout;
    request_deadline_ = now + shared_.options.request_timeout;
    read_head();
  }

  // The head: within header_timeout of the start, no silence over idle_timeout.
  void read_head() {
    lowest().expires_at(std::min(Clock::now() + shared_.options.idle_timeout, head_deadline_));
    http::async_read_some(stream_, buffer_, *parser_,
                          [self = this->shared_from_this()](beast::error_code ec, std::size_t) {
                            if (ec) return self->read_failed(ec);
                            if (!self->parser_->is_header_done()) return self->read_head();
                            self->head_read();
                          });
  }

  void head_read() {
    const auto& head = parser_->get();
    if (!parser_->is_done() && beast::iequals(head[http::field::expect], "100-continue")) {
      // The client waits for this before it sends its body.
      auto interim = std::make_shared<std::string>("HTTP/1.1 100 Continue\r\n\r\n");
      lowest().expires_after(shared_.options.idle_timeout);
      net::async_write(stream_, net::buffer(*interim),
                       [self = this->shared_from_this(), interim](beast::error_code ec, std::size_t) {
                         if (ec) return self->shut();
                         self->read_body();
                       });
      return;
    }
    read_body();
  }

  // The body (chunked or not, at most max_request_bytes): within request_timeout of the
  // start of the request, no silence over idle_timeout.
  void read_body() {
    if (parser_->is_done()) return dispatch();
    lowest().expires_at(std::min(Clock::now() + shared_.options.idle_timeout, request_deadline_));
    http::async_read_some(stream_, buffer_, *parser_,
                          [self = this->shared_from_this()](beast::error_code ec, std::size_t) {
                            if (ec) return self->read_failed(ec);
                            self->read_body();
                          });
  }

  void read_failed(beast::error_code ec) {
    if (ec == http::error::buffer_overflow && parser_ && parser_->is_header_done()) {
      // A chunk's size line (with its extensions) or the trailer, longer than the read buffer.
      auto res = status_answer(grpc::Status(
          grpc::StatusCode::RESOURCE_EXHAUSTED, "a chunk's size line or the trailer of the request body is longer than " +
                                                    std::to_string(kFramingBytes) + " bytes"));
      res.result(http::status::payload_too_large);
      return finish(std::move(res), true);
    }
    if (ec == http::error::body_limit) {
      auto res = status_answer(grpc::Status(
          grpc::StatusCode::RESOURCE_EXHAUSTED,
          "the request body is larger than the largest request, " + std::to_string(shared_.options.max_request_bytes) +
              " bytes (--max-request-bytes)"));
      res.result(http::status::payload_too_large);
      return finish(std::move(res), true);
    }
    if (ec == http::error::header_limit || ec == http::error::buffer_overflow) {
      auto res = status_answer(grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                            "the request's head is larger than " +
                                                std::to_string(shared_.options.max_header_bytes) + " bytes"));
      res.result(http::status::request_header_fields_too_large);
      return finish(std::move(res), true);
    }
    // The client left, or was silent too long: nothing to answer to (a client that is cut
    // within a request cannot be told so reliably, and a keep-alive one is not waited for).
    if (ec == http::error::end_of_stream || ec == net::error::eof || ec == beast::error::timeout ||
        ec == net::error::operation_aborted || ec == net::error::connection_reset || ec.category() ==
        net::error::get_ssl_category() || ec == ssl::error::stream_truncated) {
      return shut();
    }
    // A malformed request: the parser's reason, and the connection closed (where the next
    // request would start is unknown).
    std::string why = ec.message();
    if (ec == http::error::bad_value) {
      why = "a header's value holds a byte HTTP does not allow there (a control byte or DEL)";
    } else if (ec == http::error::bad_field) {
      why = "a header's name is not a token";
    } else if (ec == http::error::bad_target) {
      why = "the request target is not valid";
    }
    auto res = status_answer(
        grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "the HTTP request is malformed: " + why));
    res.result(http::status::bad_request);
    finish(std::move(res), true);
  }

  void dispatch() {
    phase.store(Phase::calling);
    request_ = parser_->release();
    parser_.reset();
    keep_alive_ = request_.keep_alive();
    head_ = request_.method() == http::verb::head;
    http10_ = request_.version() < 11;
    const std::string_view target(request_.target().data(), request_.target().size());
    const auto path = decoded_path(target);
    if (!path) {
      return finish(answer(400, "The request's path is malformed, or holds a NUL byte (raw or %00).\n", kText),
                    false);
    }
    if (is_api(*path)) return api(*path);
    serve_file(*path);
  }

  void api(const std::string& path) {
    const auto method = request_.method();
    const bool get = method == http::verb::get;
    const bool post = method == http::verb::post;
    static const std::vector<std::string_view> kPosts{"/v1/convert", "/v1/plan", "/v1/analyze",
                                                      "/v1/fk",      "/v1/ik",   "/v1/stream"};
    const bool is_post_route = std::find(kPosts.begin(), kPosts.end(), path) != kPosts.end();
    if (path == "/v1/robots") {
      if (!get) return finish(wrong_method("GET"), false);
    } else if (is_post_route) {
      if (!post) return finish(wrong_method("POST"), false);
    } else {
      return finish(status_answer(grpc::Status(grpc::StatusCode::NOT_FOUND,
                                               "no API route " + truncated(path, 256) + ": " + kRoutes)),
                    false);
    }
    // A header gRPC cannot carry is refused before the call.
    {
      grpc::ClientContext probe;
      if (auto bad = pass_on(request_, peer_, probe)) return finish(status_answer(*bad), false);
    }
    if (shared_.answer_bytes.load() > shared_.options.max_answer_bytes) {
      return busy("answers of " + std::to_string(shared_.answer_bytes.load()) +
                  " bytes wait for their clients, more than the web port keeps at once");
    }
    auto self = this->shared_from_this();
    std::function<void()> job;
    if (path == "/v1/stream") {
      job = [self] { self->start_stream(); };
    } else if (path == "/v1/robots") {
      job = [self] {
        grpc::ClientContext context;
        (void)pass_on(self->request_, self->peer_, context);
        v1::ListRobotsResponse response;
        const auto status = self->shared_.stub->ListRobots(&context, v1::ListRobotsRequest{}, &response);
        self->call_done(status, response, context);
      };
    } else if (path == "/v1/convert") {
      job = [self] { self->template unary<v1::ConvertRequest, v1::ConvertResponse>(&Stub::ConvertConstraints); };
    } else if (path == "/v1/plan") {
      job = [self] { self->template unary<v1::PlanRequest, v1::PlanResponse>(&Stub::PlanTrajectory); };
    } else if (path == "/v1/analyze") {
      job = [self] { self->template unary<v1::PlanRequest, v1::PathProfile>(&Stub::AnalyzePath); };
    } else if (path == "/v1/fk") {
      job = [self] {
        self->template unary<v1::ForwardKinematicsRequest, v1::ForwardKinematicsResponse>(&Stub::ComputeForwardKinematics);
      };
    } else {
      job = [self] {
        self->template unary<v1::InverseKinematicsRequest, v1::InverseKinematicsResponse>(&Stub::ComputeInverseKinematics);
      };
    }
    if (!shared_.pool->submit(std::move(job))) {
      busy(std::to_string(shared_.options.max_queued_calls) + " calls wait for the web port's " +
           std::to_string(shared_.options.threads) + " call threads");
    }
  }

  // 503 with Retry-After: the web port is at one of its own caps.
  void busy(const std::string& why) {
    auto res = status_answer(grpc::Status(grpc::StatusCode::UNAVAILABLE, why + ": retry later"));
    res.set(http::field::retry_after, "1");
    finish(std::move(res), false);
  }

  template <class RequestMessage, class ResponseMessage>
  using UnaryMethod = grpc::Status (Stub::*)(grpc::ClientContext*, const RequestMessage&, ResponseMessage*);

  // On a call thread: the body parsed, the blocking call, the answer printed; then sent on
  // the connection's strand.
  template <class RequestMessage, class ResponseMessage>
  void unary(UnaryMethod<RequestMessage, ResponseMessage> method) {
    RequestMessage message;
    if (auto bad = parse_body(request_.body(), message)) return post_answer(status_answer(*bad));
    request_.body().clear();
    request_.body().shrink_to_fit();
    grpc::ClientContext context;
    (void)pass_on(request_, peer_, context);
    ResponseMessage response;
    const auto status = ((*shared_.stub).*method)(&context, message, &response);
    call_done(status, response, context);
  }

  void call_done(const grpc::Status& status, const google::protobuf::Message& response,
                 const grpc::ClientContext& context) {
    const std::string id = request_id_of(context, true);
    if (!status.ok()) return post_answer(status_answer(status, id));
    auto res = answer(200, to_json(response), kJson);
    if (!id.empty()) res.set("X-Request-Id", id);
    post_answer(std::move(res));
  }

  void post_answer(Response res) {
    net::post(lowest().get_executor(),
              [self = this->shared_from_this(), res = std::move(res)]() mutable { self->finish(std::move(res), false); });
  }

  // On a call thread: the stream's body parsed and its call started; the thread is free
  // again at once (the reads come back on gRPC's threads).
  void start_stream() {
    v1::PlanRequest message;
    if (auto bad = parse_body(request_.body(), message)) return post_answer(status_answer(*bad));
    if (shared_.streams.fetch_add(1) >= shared_.options.max_streams) {
      shared_.streams.fetch_sub(1);
      return post_answer(status_answer(grpc::Status(
          grpc::StatusCode::RESOURCE_EXHAUSTED,
          "the web port has " + std::to_string(shared_.options.max_streams) + " streams in flight, its limit: retry later")));
    }
    auto* reactor = new StreamReactor(shared_, this->shared_from_this());
    net::post(lowest().get_executor(), [self = this->shared_from_this(), reactor] {
      self->reactor_ = reactor;
      self->reading_stream_ = true;
      if (self->closed_) self->reactor_->cancel();
    });
    reactor->start(*shared_.stub, std::move(message), request_, peer_);
  }

  // On the strand: one batch's line, the answer's head before the first.
  void send_line(std::string line, const std::string& request_id) {
    reading_stream_ = false;
    if (closed_) return reactor_->abandon();
    std::string out;
    if (!stream_started_) {
      stream_started_ = true;
      phase.store(Phase::writing);
      http::response<http::empty_body> head{http::status::ok, 11};
      decorate(head);
      head.set(http::field::content_type, kNdjson);
      if (!request_id.empty()) head.set("X-Request-Id", request_id);
      // HTTP/1.0 has no chunks: the lines as they are, and the close ends the body.
      if (http10_) keep_alive_ = false;
      head.keep_alive(keep_alive_);
      head.chunked(!http10_);
      std::ostringstream text;
      text << head.base();
      out = text.str();
    }
    out += http10_ ? line : chunk(line);
    write_chunk(std::move(out), [self = this->shared_from_this()](bool ok) {
      if (!ok || self->closed_) return self->reactor_->abandon();
      self->reading_stream_ = true;
      self->reactor_->next();
    });
  }

  // On the strand: the stream's end. Refused before its first batch: its status as a
  // unary call's; after: an error line if it failed, and the last chunk.
  void end_stream(const grpc::Status& status, const std::string& request_id) {
    reactor_ = nullptr;
    reading_stream_ = false;
    if (closed_) return;
    if (!stream_started_) {
      if (!status.ok()) return finish(status_answer(status, request_id), false);
      auto res = answer(200, "", kNdjson);  // a motion without samples
      if (!request_id.empty()) res.set("X-Request-Id", request_id);
      return finish(std::move(res), false);
    }
    std::string out;
    if (!status.ok()) {
      const std::string line = "{\"error\":" + status_json(status) + "}\n";
      out = http10_ ? line : chunk(line);
    }
    if (!http10_) out += "0\r\n\r\n";
    stream_started_ = false;
    write_chunk(std::move(out), [self = this->shared_from_this()](bool ok) {
      if (!ok || !self->keep_alive_) return self->shut();
      self->start_request();
    });
  }

  static std::string chunk(const std::string& data) {
    std::ostringstream size;
    size << std::hex << data.size();
    return size.str() + "\r\n" + data + "\r\n";
  }

  // A client that takes nothing of a line for idle_timeout is cut.
  template <class Then>
  void write_chunk(std::string bytes, Then then) {
    auto data = std::make_shared<std::string>(std::move(bytes));
    lowest().expires_after(shared_.options.idle_timeout);
    net::async_write(stream_, net::buffer(*data), [data, then](beast::error_code ec, std::size_t) { then(!ec); });
  }

  // The page's files: GET and HEAD; Range is not honoured (the whole file, 200): one
  // request never makes more than one file's bytes.
  void serve_file(const std::string& path) {
    const auto method = request_.method();
    if (method != http::verb::get && method != http::verb::head) {
      auto res = answer(405, "The page's files are read with GET or HEAD.\n", kText);
      res.set(http::field::allow, "GET, HEAD");
      return finish(std::move(res), false);
    }
    if (shared_.root.empty()) {
      if (path == "/" || path == "/index.html") return finish(answer(503, shared_.no_page, kText), false);
      return finish(answer(404, "No such file: the operator's page is not installed.\n", kText), false);
    }
    std::string relative = path.substr(1);
    if (relative.empty() || relative.back() == '/') relative += "index.html";
    // Only a path below the root: `root / "/etc/passwd"` would be /etc/passwd (a target
    // of `//etc/passwd` or `/%2Fetc/passwd`), so an absolute path is refused like `..`.
    const std::filesystem::path below(relative);
    bool refused = relative.find('\\') != std::string::npos || below.has_root_name() || below.has_root_directory();
    for (const auto& part : below) {
      if (part == ".." || part == ".") refused = true;
    }
    const std::filesystem::path file = shared_.root / below;
    std::error_code ignored;
    if (refused || !std::filesystem::is_regular_file(file, ignored)) {
      return finish(answer(404, "No such file.\n", kText), false);
    }
    http::file_body::value_type body;
    beast::error_code opened;
    body.open(file.c_str(), beast::file_mode::scan, opened);
    if (opened) return finish(answer(404, "No such file.\n", kText), false);
    const auto size = body.size();
    if (method == http::verb::head) {
      Response res = answer(200, "", content_type(file));
      res.set(http::field::accept_ranges, "none");
      res.content_length(size);
      res.keep_alive(keep_alive_);
      return write_head_only(std::move(res));
    }
    auto res = std::make_shared<http::response<http::file_body>>(
        std::piecewise_construct, std::make_tuple(std::move(body)), std::make_tuple(http::status::ok, 11));
    decorate(*res);
    res->set(http::field::content_type, content_type(file));
    res->set(http::field::accept_ranges, "none");
    res->content_length(size);
    res->keep_alive(keep_alive_);
    phase.store(Phase::writing);
    lowest().expires_after(shared_.options.request_timeout);
    http::async_write(stream_, *res, [self = this->shared_from_this(), res](beast::error_code ec, std::size_t) {
      self->written(ec, !res->keep_alive(), 0);
    });
  }

  void write_head_only(Response res) {
    auto head = std::make_shared<std::string>();
    std::ostringstream text;
    text << res.base();
    *head = text.str();
    const bool last = !res.keep_alive();
    lowest().expires_after(shared_.options.request_timeout);
    net::async_write(stream_, net::buffer(*head), [self = this->shared_from_this(), head, last](beast::error_code ec,
                                                                                               std::size_t) {
      self->written(ec, last, 0);
    });
  }

  // Sends `res`; then the next request, or the close (`last`, or the client's wish).
  void finish(Response res, bool last) {
    if (closed_) return;
    phase.store(Phase::writing);
    res.keep_alive(keep_alive_ && !last);
    res.prepare_payload();
    if (head_) {
      // HEAD: the answer's head alone, its Content-Length that of the body it leaves out (a
      // body would be read as the start of the next answer on a kept-alive connection).
      const auto length = res.body().size();
      res.body().clear();
      res.content_length(length);
      return write_head_only(std::move(res));
    }
    const std::size_t bytes = res.body().size();
    shared_.answer_bytes.fetch_add(bytes);
    auto out = std::make_shared<Response>(std::move(res));
    // The whole answer within request_timeout: a client that takes a large answer slowly
    // is cut rather than holding its memory.
    lowest().expires_after(shared_.options.request_timeout);
    http::async_write(stream_, *out, [self = this->shared_from_this(), out, bytes, last](beast::error_code ec,
                                                                                        std::size_t) mutable {
      const bool close = last || !out->keep_alive();
      out.reset();
      self->written(ec, close, bytes);
    });
  }

  void written(beast::error_code ec, bool close, std::size_t bytes) {
    if (bytes > 0) {
      shared_.answer_bytes.fetch_sub(bytes);
      if (bytes >= kTrimAfterBytes) malloc_trim(0);
    }
    request_ = {};
    if (ec) return shut();
    if (close) return linger();
    start_request();
  }

  // After an answer that ends the connection: the sending side shut, what the client still
  // sends read and dropped for a while, then the close.
  void linger() {
    if (closed_) return;
    if constexpr (!std::is_same_v<Stream, beast::tcp_stream>) {
      return shut();
    } else {
      beast::error_code ignored;
      lowest().socket().shutdown(tcp::socket::shutdown_send, ignored);
      lowest().expires_after(kLinger);
      drain_ = std::make_shared<std::vector<char>>(65536);
      drain();
    }
  }

  void drain() {
    lowest().async_read_some(net::buffer(*drain_), [self = this->shared_from_this()](beast::error_code ec,
                                                                                    std::size_t n) {
      self->drained_ += n;
      if (ec || self->drained_ > kLingerBytes) return self->shut();
      self->drain();
    });
  }

  Shared& shared_;
  Stream stream_;
  std::string peer_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  Request request_;
  bool keep_alive_ = true;
  bool head_ = false;    // the request is a HEAD: answers without their body
  bool http10_ = false;  // an HTTP/1.0 client: streams without chunks, then the close
  bool closed_ = false;
  Clock::time_point head_deadline_;
  Clock::time_point request_deadline_;
  // The stream in flight: its reactor, whether a read of it is outstanding (the reactor's
  // own business then), and whether its head went out.
  StreamReactor* reactor_ = nullptr;
  bool reading_stream_ = false;
  bool stream_started_ = false;
  std::shared_ptr<std::vector<char>> drain_;
  std::size_t drained_ = 0;
};

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
  Shared shared;
  net::io_context io;
  std::optional<net::executor_work_guard<net::io_context::executor_type>> work;
  std::optional<ssl::context> tls;
  std::optional<tcp::acceptor> acceptor;
  std::optional<net::steady_timer> retry;  // after a failed accept
  std::vector<std::thread> io_threads;
  int port = 0;
  std::mutex stop_mutex;
  bool stopped = false;
  // The open connections in the order they came (weak: a connection goes when it ends).
  std::mutex connections_mutex;
  std::list<std::weak_ptr<Connection>> connections;

  // On the acceptor's strand (stop() closes it there too).
  void accept() {
    acceptor->async_accept(net::make_strand(io), [this](beast::error_code ec, tcp::socket socket) {
      if (ec == net::error::operation_aborted || !acceptor->is_open()) return;
      if (ec) {
        // Out of descriptors, or the like: try again a little later rather than spin.
        retry->expires_after(std::chrono::milliseconds(100));
        retry->async_wait([this](beast::error_code waited) {
          if (!waited && acceptor->is_open()) accept();
        });
        return;
      }
      admit(std::move(socket));
      accept();
    });
  }

  // The connection cap: a new connection beyond it closes the oldest one that is reading a
  // request (idle between requests, or slow within one); when every one is busy with a
  // call or an answer, the new one is closed.
  void admit(tcp::socket socket) {
    beast::error_code ec;
    socket.set_option(tcp::no_delay(true), ec);
    const auto remote = socket.remote_endpoint(ec);
    if (ec) return;
    std::string peer = remote.address().to_string() + ":" + std::to_string(remote.port());
    if (remote.address().is_v6()) peer = "[" + remote.address().to_string() + "]:" + std::to_string(remote.port());
    std::shared_ptr<Connection> connection;
    if (tls) {
      auto s = std::make_shared<Session<beast::ssl_stream<beast::tcp_stream>>>(
          shared, beast::ssl_stream<beast::tcp_stream>(beast::tcp_stream(std::move(socket)), *tls), peer);
      connection = s;
      if (!register_connection(connection)) return;
      s->start();
    } else {
      auto s = std::make_shared<Session<beast::tcp_stream>>(shared, beast::tcp_stream(std::move(socket)), peer);
      connection = s;
      if (!register_connection(connection)) return;
      s->start();
    }
  }

  bool register_connection(const std::shared_ptr<Connection>& connection) {
    const std::lock_guard lock(connections_mutex);
    connections.remove_if([](const std::weak_ptr<Connection>& c) { return c.expired(); });
    if (connections.size() >= shared.options.max_connections) {
      auto oldest = connections.end();
      for (auto it = connections.begin(); it != connections.end(); ++it) {
        if (auto c = it->lock(); c && c->phase.load() == Phase::reading) {
          oldest = it;
          break;
        }
      }
      if (oldest == connections.end()) return false;  // the socket closes with its session
      if (auto c = oldest->lock()) c->close();
      connections.erase(oldest);
    }
    connections.push_back(connection);
    return true;
  }
};

WebGateway::WebGateway(std::unique_ptr<State> state) : state_(std::move(state)) {}
WebGateway::~WebGateway() { stop(); }
int WebGateway::port() const { return state_->port; }

void WebGateway::stop() {
  State& s = *state_;
  const std::lock_guard lock(s.stop_mutex);
  if (s.stopped) return;
  s.stopped = true;
  net::post(s.acceptor->get_executor(), [&s] {
    beast::error_code ignored;
    s.acceptor->close(ignored);
    s.retry->cancel();
  });
  {
    const std::lock_guard connections_lock(s.connections_mutex);
    for (auto& weak : s.connections) {
      if (auto c = weak.lock()) c->close();
    }
  }
  // The calls in progress end (the server's calls have ended before), the queued ones are
  // dropped; the streams are cancelled by their connections' close.
  s.shared.pool->shutdown();
  {
    std::unique_lock reactors_lock(s.shared.reactors_mutex);
    s.shared.reactors_done.wait_for(reactors_lock, std::chrono::seconds(10),
                                    [&s] { return s.shared.reactors == 0; });
  }
  s.work.reset();
  s.io.stop();
  for (auto& t : s.io_threads) t.join();
  s.io_threads.clear();
  const std::lock_guard connections_lock(s.connections_mutex);
  s.connections.clear();
}

tl::expected<std::unique_ptr<WebGateway>, std::string> WebGateway::start(const WebOptions& options,
                                                                         std::shared_ptr<grpc::Channel> channel) {
  const std::string quoted = "the web address \"" + options.address + "\"";
  if (const auto address = split_host_port(options.address, quoted); !address) {
    return tl::make_unexpected(address.error());
  }
  auto state = std::make_unique<State>();
  Shared& shared = state->shared;
  shared.options = options;
  shared.options.threads = std::max(1, options.threads);
  shared.options.max_connections = std::max<std::size_t>(1, options.max_connections);
  shared.channel = std::move(channel);
  shared.stub = v1::TrajectoryService::NewStub(shared.channel);

  if (options.tls.enabled()) {
    // The files were read and checked for the gRPC port already (start_server).
    try {
      ssl::context context(ssl::context::tls_server);
      context.set_options(ssl::context::default_workarounds | ssl::context::no_sslv2 | ssl::context::no_sslv3 |
                          ssl::context::no_tlsv1 | ssl::context::no_tlsv1_1);
      context.use_certificate_chain_file(options.tls.cert_file);
      context.use_private_key_file(options.tls.key_file, ssl::context::pem);
      if (!options.tls.client_ca_file.empty()) {
        context.load_verify_file(options.tls.client_ca_file);
        context.set_verify_mode(ssl::verify_peer | ssl::verify_fail_if_no_peer_cert);
      }
      state->tls.emplace(std::move(context));
    } catch (const std::exception& e) {
      return tl::make_unexpected("cannot serve HTTPS on " + quoted + " with the certificate \"" +
                                 options.tls.cert_file + "\" and key \"" + options.tls.key_file + "\": " + e.what());
    }
  }

  const std::filesystem::path root(options.root);
  std::error_code ignored;
  if (!options.root.empty() && std::filesystem::is_regular_file(root / "index.html", ignored)) {
    shared.root = root;
  } else {
    const std::string where = options.root.empty() ? std::string("no web root was given (--web-root)")
                                                   : "\"" + options.root + "\" has no index.html";
    shared.no_page = "The operator's page is not installed: " + where +
                     ". The JSON API under /v1/ is served; build with node and npm to install the page.\n";
  }

  auto listening = listen_tcp(options.address, "web address");
  if (!listening) return tl::make_unexpected(listening.error());
  sockaddr_storage bound{};
  socklen_t length = sizeof bound;
  ::getsockname(listening->fd, reinterpret_cast<sockaddr*>(&bound), &length);
  state->acceptor.emplace(net::make_strand(state->io));
  state->retry.emplace(state->acceptor->get_executor());
  beast::error_code ec;
  state->acceptor->assign(bound.ss_family == AF_INET6 ? tcp::v6() : tcp::v4(), listening->fd, ec);
  if (ec) {
    ::close(listening->fd);
    return tl::make_unexpected("cannot listen on " + quoted + ": " + ec.message());
  }
  state->port = listening->port;

  shared.pool.emplace(static_cast<std::size_t>(shared.options.threads), options.max_queued_calls);
  state->work.emplace(net::make_work_guard(state->io));
  state->accept();
  for (int k = 0; k < std::max(1, options.io_threads); ++k) {
    state->io_threads.emplace_back([s = state.get()] {
      for (;;) {
        try {
          s->io.run();
          return;
        } catch (const std::exception&) {
          // A handler that threw (none should) costs its connection, never the port.
        }
      }
    });
  }
  return std::unique_ptr<WebGateway>(new WebGateway(std::move(state)));
}

}  // namespace geotraj::server
