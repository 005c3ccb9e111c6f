#include "server/ops/http_exporter.hpp"

#include "server/ops/socket.hpp"

#include <httplib.h>

#include <algorithm>
#include <cstdint>
#include <cerrno>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace geotraj::server {
namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxHead = 8192;              // request line + headers, terminator included
constexpr auto kLinger = std::chrono::seconds(1);   // reading leftovers after a response

std::string errno_text(int error) { return std::generic_category().message(error); }

// One client: its request bytes, then its response, then leftovers read until the client
// closes, so that closing with unread data does not reset the connection and lose the answer.
struct Connection {
  enum class State { kReading, kWriting, kLingering };
  int fd = -1;
  State state = State::kReading;
  Clock::time_point deadline;
  std::string in;
  std::string out;
  std::size_t sent = 0;
  std::uint64_t round = 0;  // the poll round that accepted it
};

// RFC 9110 tchar: what a method and a header name are made of.
bool is_token(std::string_view s) {
  if (s.empty()) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           std::string_view("!#$%&'*+-.^_`|~").find(c) != std::string_view::npos;
  });
}

// Where the header block ends (just past its empty line), or npos if it has not yet arrived.
// A bare LF block end is found too, so that it is answered (400, by cpp-httplib) at once.
std::size_t head_end(std::string_view in) {
  const std::size_t crlf = in.find("\r\n\r\n");
  const std::size_t lf = in.find("\n\n");
  std::size_t end = std::string_view::npos;
  if (crlf != std::string_view::npos) end = crlf + 4;
  if (lf != std::string_view::npos) end = std::min(end, lf + 2);
  return end;
}

// What RFC 9112 requires a server to refuse and cpp-httplib 0.11 accepts: a method that is
// not a token (3.1: cpp-httplib skips leading whitespace such as a tab), more than one
// space between the parts of the request line (3), a target that is not in origin form
// (3.2.1), a header line without a colon or with whitespace before it (5.1). cpp-httplib
// itself refuses an unknown method or version and bare LF line ends.
bool breaks_rfc9112(std::string_view head) {
  if (!head.ends_with("\r\n\r\n")) return true;  // incomplete, oversized, or bare LF line ends
  const std::size_t line_end = head.find("\r\n");
  if (line_end == std::string_view::npos) return true;
  const std::string_view request_line = head.substr(0, line_end);
  const std::size_t sp1 = request_line.find(' ');
  const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : request_line.find(' ', sp1 + 1);
  if (sp2 == std::string_view::npos || sp2 == sp1 + 1 || request_line.find(' ', sp2 + 1) != std::string_view::npos ||
      request_line[sp1 + 1] != '/' || !is_token(request_line.substr(0, sp1))) {
    return true;
  }
  for (std::string_view rest = head.substr(line_end + 2); !rest.empty() && !rest.starts_with("\r\n");) {
    const std::size_t end = rest.find("\r\n");
    const std::string_view line = rest.substr(0, end);
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos || !is_token(line.substr(0, colon))) return true;
    if (end == std::string_view::npos) break;
    rest.remove_prefix(end + 2);
  }
  return false;
}

// cpp-httplib's parser and writer over bytes already read: the request head is read from
// memory (then end of stream), the response is written to memory.
class MemoryStream final : public httplib::Stream {
 public:
  explicit MemoryStream(std::string_view in) : in_(in) {}
  bool is_readable() const override { return true; }
  bool is_writable() const override { return true; }
  ssize_t read(char* data, size_t size) override {
    size = std::min(size, in_.size());
    std::copy_n(in_.data(), size, data);
    in_.remove_prefix(size);
    return static_cast<ssize_t>(size);
  }
  ssize_t write(const char* data, size_t size) override {
    out_.append(data, size);
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string&, int&) const override {}
  void get_local_ip_and_port(std::string&, int&) const override {}
  socket_t socket() const override { return INVALID_SOCKET; }
  std::string take() { return std::move(out_); }

 private:
  std::string_view in_;
  std::string out_;
};

constexpr const char* kText = "text/plain; charset=utf-8";

std::string refusal_text(int status) {
  switch (status) {
    case 400: return "bad request\n";
    case 404: return "not found\n";
    case 405: return "method not allowed\n";
    case 414: return "request target too long\n";
    default: return "error " + std::to_string(status) + "\n";
  }
}

void close_fd(int fd) {
  if (fd >= 0) ::close(fd);
}

}  // namespace

struct HttpRoutes::Router final : httplib::Server {
  explicit Router(std::function<std::string()> metrics_body) {
    set_pre_routing_handler([this](const httplib::Request& request, httplib::Response& response) {
      if (refuse) {
        response.status = 400;
        return HandlerResponse::Handled;
      }
      if (request.method != "GET" && request.method != "HEAD") {
        response.status = 405;
        response.set_header("Allow", "GET, HEAD");
        return HandlerResponse::Handled;
      }
      return HandlerResponse::Unhandled;
    });
    Get("/metrics", [body = std::move(metrics_body)](const httplib::Request&, httplib::Response& response) {
      try {
        response.set_content(body(), "text/plain; version=0.0.4; charset=utf-8");
      } catch (...) {
        response.status = 500;
        response.set_content("metrics unavailable\n", kText);
      }
    });
    Get("/healthz", [](const httplib::Request&, httplib::Response& response) { response.set_content("ok", kText); });
    // Every refusal says what it is in its body too.
    set_error_handler([](const httplib::Request&, httplib::Response& response) {
      if (response.body.empty()) {
        response.set_content(refusal_text(response.status), kText);
      }
    });
  }

  std::string answer(std::string_view head) {
    refuse = breaks_rfc9112(head);
    // cpp-httplib answers nothing when there is no line at all: give it an empty one (400).
    MemoryStream stream(head.empty() ? std::string_view("\r\n") : head);
    bool closed = false;
    process_request(stream, /*close_connection=*/true, closed, [](httplib::Request&) {});
    return stream.take();
  }

  bool refuse = false;  // the head breaks RFC 9112 where cpp-httplib does not look
};

HttpRoutes::HttpRoutes(std::function<std::string()> metrics_body)
    : router_(std::make_unique<Router>(std::move(metrics_body))) {}
HttpRoutes::~HttpRoutes() = default;
std::string HttpRoutes::answer(std::string_view head) { return router_->answer(head); }

tl::expected<std::unique_ptr<HttpExporter>, std::string> HttpExporter::start(const std::string& address,
                                                                             std::function<std::string()> metrics_body,
                                                                             HttpExporterOptions options) {
  const std::string quoted = "metrics address \"" + address + "\"";
  if (!metrics_body) return tl::make_unexpected("no metrics source for " + quoted);
  auto listening = listen_tcp(address, "metrics address", 128);
  if (!listening) return tl::make_unexpected(listening.error());
  const int listen_fd = listening->fd;
  const int bound_port = listening->port;
  int error = 0;

  // stop() wakes the thread's poll() through this pipe.
  int wake[2];
  if (::pipe2(wake, O_NONBLOCK | O_CLOEXEC) != 0) {
    error = errno;
    ::close(listen_fd);
    return tl::make_unexpected("cannot serve " + quoted + ": " + errno_text(error));
  }
  std::unique_ptr<HttpExporter> exporter(
      new HttpExporter(listen_fd, wake[0], wake[1], bound_port, std::move(metrics_body), options));
  try {
    exporter->thread_ = std::thread(&HttpExporter::run, exporter.get());
  } catch (const std::system_error& e) {
    return tl::make_unexpected("cannot serve " + quoted + ": " + e.what());  // the destructor closes the fds
  }
  return exporter;
}

HttpExporter::HttpExporter(int listen_fd, int wake_read_fd, int wake_write_fd, int port,
                           std::function<std::string()> metrics_body, HttpExporterOptions options)
    : listen_fd_(listen_fd),
      wake_read_fd_(wake_read_fd),
      wake_write_fd_(wake_write_fd),
      port_(port),
      routes_(std::move(metrics_body)),
      options_(options) {}

HttpExporter::~HttpExporter() {
  stop();
  close_fd(listen_fd_);
  close_fd(wake_read_fd_);
  close_fd(wake_write_fd_);
}

void HttpExporter::stop() {
  const std::lock_guard lock(stop_mutex_);
  if (!thread_.joinable()) return;
  const char byte = 0;
  while (::write(wake_write_fd_, &byte, 1) < 0 && errno == EINTR) {
  }
  thread_.join();
  close_fd(listen_fd_);
  listen_fd_ = -1;
}

void HttpExporter::run() {
  std::vector<Connection> connections;
  std::vector<pollfd> fds;
  const std::size_t max_connections = std::max<std::size_t>(options_.max_connections, 1);
  Clock::time_point accept_paused_until{};  // after EMFILE and the like: retry later, do not spin

  const auto close_connection = [](Connection& c) {
    ::close(c.fd);
    c.fd = -1;
  };
  // Sends what the socket takes; once all is sent, half-closes and lingers.
  const auto write_some = [&close_connection](Connection& c) {
    while (c.sent < c.out.size()) {
      const ssize_t n = ::send(c.fd, c.out.data() + c.sent, c.out.size() - c.sent, MSG_NOSIGNAL);
      if (n < 0) {
        if (errno == EINTR) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK) close_connection(c);
        return;
      }
      c.sent += static_cast<std::size_t>(n);
    }
    ::shutdown(c.fd, SHUT_WR);
    c.state = Connection::State::kLingering;
    c.deadline = std::min(c.deadline, Clock::now() + kLinger);
  };
  const auto respond = [&write_some](Connection& c, std::string out) {
    c.out = std::move(out);
    c.in.clear();
    c.state = Connection::State::kWriting;
    write_some(c);
  };
  // Reads what the socket has; a whole request head is answered at once.
  const auto read_some = [this, &close_connection, &respond](Connection& c) {
    char buffer[4096];
    for (;;) {
      const ssize_t n = ::recv(c.fd, buffer, sizeof buffer, 0);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
      if (n <= 0) {  // end of stream or reset: nothing left to answer
        close_connection(c);
        break;
      }
      if (c.state == Connection::State::kLingering) continue;  // discard leftovers
      c.in.append(buffer, static_cast<std::size_t>(n));
      const std::size_t end = head_end(c.in);
      if (end != std::string::npos && end <= kMaxHead) {
        respond(c, routes_.answer(std::string_view(c.in).substr(0, end)));
        break;
      }
      if (c.in.size() > kMaxHead) {
        respond(c, routes_.answer(c.in));  // 400: no end within the limit
        break;
      }
    }
  };
  std::uint64_t round = 0;  // poll rounds: a connection is read in the round after its accept

  for (;;) {
    const auto now = Clock::now();
    fds.clear();
    fds.push_back({wake_read_fd_, POLLIN, 0});
    const bool accepting = now >= accept_paused_until;
    fds.push_back({accepting ? listen_fd_ : -1, POLLIN, 0});  // a negative fd is skipped by poll()
    Clock::time_point wake_at = accepting ? Clock::time_point::max() : accept_paused_until;
    for (const Connection& c : connections) {
      fds.push_back({c.fd, static_cast<short>(c.state == Connection::State::kWriting ? POLLOUT : POLLIN), 0});
      wake_at = std::min(wake_at, c.deadline);
    }
    int timeout_ms = -1;
    if (wake_at != Clock::time_point::max()) {
      const auto wait = std::chrono::ceil<std::chrono::milliseconds>(wake_at - now).count();
      timeout_ms = static_cast<int>(std::clamp<decltype(wait)>(wait, 0, 60'000));
    }
    if (::poll(fds.data(), fds.size(), timeout_ms) < 0) {
      if (errno == EINTR) continue;
      break;  // cannot happen with valid arguments; leave rather than spin
    }
    if (fds[0].revents != 0) break;  // stop()

    // Existing connections first: fds[2 + i] belongs to connections[i].
    for (std::size_t i = 0; i < connections.size(); ++i) {
      Connection& c = connections[i];
      if (fds[2 + i].revents == 0) continue;
      if (c.state == Connection::State::kWriting) {
        write_some(c);
        continue;
      }
      read_some(c);
    }
    ++round;

    // New connections.
    if (fds[1].revents != 0) {
      for (;;) {
        const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
          if (errno == EINTR || errno == ECONNABORTED) continue;
          if (errno != EAGAIN && errno != EWOULDBLOCK) accept_paused_until = Clock::now() + std::chrono::milliseconds(100);
          break;
        }
        Connection c;
        c.fd = fd;
        c.deadline = Clock::now() + options_.timeout;
        c.round = round;
        read_some(c);  // a client that sent its request with the connection is answered now
        if (c.fd < 0) continue;
        std::erase_if(connections, [](const Connection& k) { return k.fd < 0; });
        if (connections.size() >= max_connections) {
          // Full: the oldest connection still reading a request, and polled at least once
          // since its accept (not one of this burst, whose request may be on its way), makes
          // room (connections are kept in arrival order); with none, the answers in flight
          // keep their slots and the new connection is closed (after its answer, when it
          // sent its request with the connection and the socket took the answer whole).
          const auto oldest = std::find_if(connections.begin(), connections.end(), [round](const Connection& k) {
            return k.state == Connection::State::kReading && k.round < round;
          });
          if (oldest == connections.end()) {
            close_connection(c);
            continue;
          }
          close_connection(*oldest);
          connections.erase(oldest);
        }
        connections.push_back(std::move(c));
      }
    }

    // Closed and timed-out connections go (a stalled client is simply disconnected).
    const auto after = Clock::now();
    for (Connection& c : connections) {
      if (c.fd >= 0 && after >= c.deadline) close_connection(c);
    }
    std::erase_if(connections, [](const Connection& c) { return c.fd < 0; });
  }

  for (Connection& c : connections) close_connection(c);
}

}  // namespace geotraj::server
