#include "server/ops/http_exporter.hpp"

#include "server/ops/socket.hpp"

#include <algorithm>
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
};

// RFC 9110 tchar: what a method and a header name are made of.
bool is_token(std::string_view s) {
  if (s.empty()) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           std::string_view("!#$%&'*+-.^_`|~").find(c) != std::string_view::npos;
  });
}

std::string response(std::string_view status, std::string_view content_type, std::string_view body,
                     std::string_view extra_headers = {}) {
  std::string out = "HTTP/1.1 ";
  out.append(status).append("\r\nContent-Type: ").append(content_type);
  out.append("\r\nContent-Length: ").append(std::to_string(body.size()));
  out.append("\r\nConnection: close\r\n").append(extra_headers).append("\r\n").append(body);
  return out;
}

std::string bad_request() { return response("400 Bad Request", "text/plain; charset=utf-8", "bad request\n"); }

// Where the header block ends (just past its empty line), or npos if it has not yet arrived.
// Bare LF line ends are tolerated, as RFC 9112 allows.
std::size_t head_end(std::string_view in) {
  const std::size_t crlf = in.find("\r\n\r\n");
  const std::size_t lf = in.find("\n\n");
  std::size_t end = std::string_view::npos;
  if (crlf != std::string_view::npos) end = crlf + 4;
  if (lf != std::string_view::npos) end = std::min(end, lf + 2);
  return end;
}

// The response to a complete header block.
std::string answer(std::string_view head, const std::function<std::string()>& metrics_body) {
  std::vector<std::string_view> lines;
  while (!head.empty()) {
    const std::size_t nl = head.find('\n');
    std::string_view line = head.substr(0, nl);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.push_back(line);
    head.remove_prefix(nl == std::string_view::npos ? head.size() : nl + 1);
  }
  // Request line: METHOD SP TARGET SP HTTP/1.x, then header lines, then the empty line.
  if (lines.size() < 2 || !lines.back().empty()) return bad_request();
  const std::string_view request_line = lines.front();
  const std::size_t sp1 = request_line.find(' ');
  const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : request_line.find(' ', sp1 + 1);
  if (sp2 == std::string_view::npos || request_line.find(' ', sp2 + 1) != std::string_view::npos) {
    return bad_request();
  }
  const std::string_view method = request_line.substr(0, sp1);
  std::string_view target = request_line.substr(sp1 + 1, sp2 - sp1 - 1);
  const std::string_view version = request_line.substr(sp2 + 1);
  if (!is_token(method) || target.empty() || target.front() != '/' || (version != "HTTP/1.1" && version != "HTTP/1.0")) {
    return bad_request();
  }
  for (std::size_t i = 1; i + 1 < lines.size(); ++i) {
    const std::size_t colon = lines[i].find(':');
    if (colon == std::string_view::npos || !is_token(lines[i].substr(0, colon))) return bad_request();
  }

  if (method != "GET") {
    return response("405 Method Not Allowed", "text/plain; charset=utf-8", "method not allowed\n", "Allow: GET\r\n");
  }
  target = target.substr(0, target.find('?'));
  if (target == "/metrics") {
    try {
      return response("200 OK", "text/plain; version=0.0.4; charset=utf-8", metrics_body());
    } catch (...) {
      return response("500 Internal Server Error", "text/plain; charset=utf-8", "metrics unavailable\n");
    }
  }
  if (target == "/healthz") return response("200 OK", "text/plain; charset=utf-8", "ok");
  return response("404 Not Found", "text/plain; charset=utf-8", "not found\n");
}

void close_fd(int fd) {
  if (fd >= 0) ::close(fd);
}

}  // namespace

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
      metrics_body_(std::move(metrics_body)),
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
          respond(c, answer(std::string_view(c.in).substr(0, end), metrics_body_));
          break;
        }
        if (c.in.size() > kMaxHead) {
          respond(c, bad_request());
          break;
        }
      }
    }

    // New connections.
    if (fds[1].revents != 0) {
      for (;;) {
        const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
          if (errno == EINTR || errno == ECONNABORTED) continue;
          if (errno != EAGAIN && errno != EWOULDBLOCK) accept_paused_until = Clock::now() + std::chrono::milliseconds(100);
          break;
        }
        std::erase_if(connections, [](const Connection& c) { return c.fd < 0; });
        if (connections.size() >= max_connections) {
          // Full: the oldest connection makes room (connections are kept in arrival order).
          close_connection(connections.front());
          connections.erase(connections.begin());
        }
        Connection c;
        c.fd = fd;
        c.deadline = Clock::now() + options_.timeout;
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
