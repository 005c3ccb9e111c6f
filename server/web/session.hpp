// What a gateway's connections share, private to server/web: Connection (what the connection
// cap sees of one), Shared (what every one shares), and make_session, which opens a Session
// (session.cpp) on an accepted socket.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl/context.hpp>
#include <grpcpp/channel.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "server/web/call_pool.hpp"
#include "server/web/gateway.hpp"

namespace geotraj::server::web_detail {

namespace v1 = geotraj::v1;
using Stub = v1::TrajectoryService::Stub;

// What a connection is doing, for the connection cap's choice of whom to close.
enum class Phase { reading, calling, writing };

class Connection {
 public:
  virtual ~Connection() = default;
  // Starts serving on the connection's strand, once the connection cap has taken it in.
  virtual void start() = 0;
  // Closes the connection from any thread (on its strand).
  virtual void close() = 0;
  std::atomic<Phase> phase{Phase::reading};
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

// A Session on an accepted socket, TLS when `tls` is given (HTTPS), not started yet.
std::shared_ptr<Connection> make_session(Shared& shared, boost::asio::ip::tcp::socket socket,
                                         boost::asio::ssl::context* tls, std::string peer);

}  // namespace geotraj::server::web_detail
