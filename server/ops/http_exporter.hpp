// The HTTP endpoint for scrapes and probes (GET /metrics, GET /healthz) on its own thread.
// cpp-httplib parses each request, routes it and writes the response; geotraj keeps the
// connections: cpp-httplib 0.11 (Debian 12's) gives every connection one of its 8 threads
// until it has sent its request, with a read timeout per recv() but none on the whole
// request, so that clients trickling a byte now and then hold every thread and scrapes wait
// behind them (measured on cpp-httplib alone, read timeout 2 s: 16 clients sending a byte
// every 1.5 s, and none of 5 scrapes was answered within 30 s). Here one thread multiplexes
// the connections with poll(), gives each one deadline for the whole exchange, caps them,
// and hands a request to cpp-httplib only once its head has arrived whole.
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>

#include <tl/expected.hpp>

namespace geotraj::server {

/// Limits of the exporter; the defaults suit production.
struct HttpExporterOptions {
  /// A connection must deliver its request and take its response within this time: well
  /// below Prometheus's 10 s scrape timeout, so that clients that trickle bytes go first.
  std::chrono::milliseconds timeout{2000};
  /// Connections served at once. A request sent with its connection is answered at its
  /// accept; a new connection beyond them closes the oldest that is still reading a request
  /// and has been polled once (a scrape is never kept waiting in the backlog behind clients
  /// that hold connections and send nothing, nor closed by a burst of new ones before its
  /// request is read), or is closed itself when every slot holds an answer in flight.
  std::size_t max_connections = 512;
};

/// The response to one request head (request line, header lines and the empty line that ends
/// them; CRLF line ends): routing and response by cpp-httplib, after the checks RFC 9112
/// requires of a server that cpp-httplib 0.11 leaves out (one space between the parts of the
/// request line, a target that starts with '/', header names that are tokens followed at
/// once by ':'; 400 otherwise). `metrics_body` is called for GET /metrics; one that throws
/// gives 500. Not thread-safe: one per thread.
class HttpRoutes {
 public:
  explicit HttpRoutes(std::function<std::string()> metrics_body);
  ~HttpRoutes();
  HttpRoutes(const HttpRoutes&) = delete;
  HttpRoutes& operator=(const HttpRoutes&) = delete;

  std::string answer(std::string_view head);

 private:
  struct Router;
  std::unique_ptr<Router> router_;
};

/// Serves, one request per connection (Connection: close):
///   GET /metrics -> 200, text/plain; version=0.0.4; charset=utf-8, the body of metrics_body()
///   GET /healthz -> 200, "ok"
///   HEAD of either -> the same headers without the body
///   other paths -> 404, other methods -> 405 (Allow: GET, HEAD), a malformed or oversized
///   (> 8 KiB) request line or header block -> 400; then the connection is closed.
/// One thread multiplexes all connections with poll() on non-blocking sockets, so a slow
/// or silent client holds only its own slot, and only until the timeout or until a newer
/// connection needs the slot.
class HttpExporter {
 public:
  /// Listens on `address` (HOST:PORT; [IPv6]:PORT; a host name is resolved; an empty host
  /// means every address; port 0 picks a free port) and starts serving. `metrics_body` is
  /// called on the exporter's thread for each scrape and must be thread-safe. The error is
  /// a sentence naming the address, e.g.
  /// `cannot listen on metrics address "127.0.0.1:9090": Address already in use`.
  static tl::expected<std::unique_ptr<HttpExporter>, std::string> start(const std::string& address,
                                                                        std::function<std::string()> metrics_body,
                                                                        HttpExporterOptions options = {});

  HttpExporter(const HttpExporter&) = delete;
  HttpExporter& operator=(const HttpExporter&) = delete;
  ~HttpExporter();

  /// The bound port (the chosen one when started with port 0).
  int port() const { return port_; }
  /// Stops serving, closes every connection and the listening socket; returns as soon as
  /// the thread has exited (it is woken through a pipe, not by a timeout). Idempotent.
  void stop();

 private:
  HttpExporter(int listen_fd, int wake_read_fd, int wake_write_fd, int port,
               std::function<std::string()> metrics_body, HttpExporterOptions options);
  // run() answers through routes_: it is only used on the exporter's thread.
  void run();

  int listen_fd_;  // closed by stop(), which frees the port
  const int wake_read_fd_;
  const int wake_write_fd_;
  const int port_;
  HttpRoutes routes_;
  const HttpExporterOptions options_;
  std::mutex stop_mutex_;
  std::thread thread_;
};

}  // namespace geotraj::server
