// geotrajd accepts the TCP connections of its gRPC ports itself and hands each to gRPC
// (grpc::experimental::ExternalConnectionAcceptor), so that:
//  - the number of connections open at once is capped (gRPC 1.51 has no such limit): at the
//    cap, connections that have sent nothing that starts a session (fewer bytes than the
//    HTTP/2 preface) for kIdleGrace make room first, and a connection still beyond the cap is
//    closed on arrival, and counted; gRPC's handshake timeout closes the rest that never
//    finish the preface and settings;
//  - running out of descriptors does not end acceptance for good (gRPC 1.51's listener
//    stops polling after an accept4 error other than EAGAIN): on EMFILE the connection
//    waiting in the backlog is closed through a reserve descriptor, acceptance pauses for
//    100 ms and resumes, and readiness is NOT_SERVING until descriptors are free again;
//  - the port is bound without SO_REUSEPORT: a second server on a port in use fails.
// The TLS handshake, the HTTP/2 preface and everything after stay gRPC's.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <chrono>
#include <unordered_map>
#include <unordered_set>

#include <grpcpp/server_builder.h>
#include <sys/types.h>
#include <tl/expected.hpp>

#include "server/ops/log.hpp"
#include "server/ops/metrics.hpp"
#include "server/ops/socket.hpp"

namespace geotraj::server {

class Acceptor {
 public:
  struct Options {
    std::string listener;  ///< label in logs and metrics ("grpc", "health")
    std::size_t max_connections = 4096;
    /// Called from the acceptor's thread when acceptance fails (false) and recovers (true).
    std::function<void(bool accepting)> on_accepting;
  };

  /// Binds `address` (socket.hpp; the error names `what`).
  static tl::expected<std::unique_ptr<Acceptor>, std::string> listen(const std::string& address,
                                                                     const std::string& what);
  Acceptor(const Acceptor&) = delete;
  Acceptor& operator=(const Acceptor&) = delete;
  ~Acceptor();

  int port() const { return socket_.port; }

  /// Starts accepting on a thread of its own and hands every connection to `sink` (from a
  /// ServerBuilder whose server has started). `metrics` and `logger` outlive the acceptor.
  void start(std::unique_ptr<grpc::experimental::ExternalConnectionAcceptor> sink, Options options,
             Metrics& metrics, const Logger& logger);
  /// Stops accepting and closes the listening socket (connections handed to gRPC stay
  /// gRPC's). Idempotent.
  void stop();

  /// Connections handed to gRPC and still open (an estimate between two counts).
  std::size_t connections() const { return open_.load(); }
  /// False while descriptors are exhausted.
  bool accepting() const { return accepting_.load(); }

 private:
  explicit Acceptor(ListeningSocket socket, int wake_read, int wake_write);
  void run();
  // Forgets the connections gRPC has closed (their socket inodes are gone from
  // /proc/self/fd); returns how many are left.
  std::size_t count_open();
  // At the cap: shuts down the connections older than kIdleGrace that have received fewer
  // bytes than the HTTP/2 preface; returns how many.
  std::size_t close_idle();
  // At the cap: whether a new connection may come in (gRPC closed some, or silent ones were
  // shut down to make room).
  bool make_room();
  void set_accepting(bool accepting);

  ListeningSocket socket_;
  const int wake_read_;
  const int wake_write_;
  int reserve_fd_ = -1;  // a spare descriptor, closed to make room for shedding on EMFILE
  std::unique_ptr<grpc::experimental::ExternalConnectionAcceptor> sink_;
  Options options_;
  Metrics* metrics_ = nullptr;
  const Logger* logger_ = nullptr;
  // Inodes of the sockets handed to gRPC, with when they were accepted (acceptor thread).
  std::unordered_map<ino_t, std::chrono::steady_clock::time_point> live_;
  std::unordered_set<ino_t> shut_down_;  // shut down by close_idle, not yet closed by gRPC
  std::chrono::steady_clock::time_point last_scan_{};
  std::atomic<std::size_t> open_{0};
  std::atomic<bool> accepting_{true};
  std::mutex stop_mutex_;
  std::thread thread_;
};

}  // namespace geotraj::server
