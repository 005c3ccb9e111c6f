// Session: one connection of the web port, plain or TLS (HTTPS), from its request's head to
// its answer: the API's routes, the streamed samples and the page's files; make_session.
#include "server/web/session.hpp"

#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <sstream>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <grpcpp/client_context.h>

#include "server/web/http.hpp"
#include "server/web/stream_reactor.hpp"
#include "server/wire/text.hpp"

namespace geotraj::server::web_detail {
namespace {

namespace net = boost::asio;
namespace ssl = boost::asio::ssl;
namespace beast = boost::beast;
using tcp = boost::asio::ip::tcp;
using Clock = std::chrono::steady_clock;

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
  void start() override {
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

std::shared_ptr<Connection> make_session(Shared& shared, tcp::socket socket, ssl::context* tls, std::string peer) {
  if (tls != nullptr) {
    return std::make_shared<Session<beast::ssl_stream<beast::tcp_stream>>>(
        shared, beast::ssl_stream<beast::tcp_stream>(beast::tcp_stream(std::move(socket)), *tls), std::move(peer));
  }
  return std::make_shared<Session<beast::tcp_stream>>(shared, beast::tcp_stream(std::move(socket)), std::move(peer));
}

}  // namespace geotraj::server::web_detail
