// WebGateway (gateway.hpp): the port listened on, its connections accepted under the
// connection cap, the stop; and the HTTP status and JSON of a gRPC status.
#include "server/web/gateway.hpp"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <list>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <google/protobuf/util/json_util.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "google/rpc/status.pb.h"
#include "server/ops/socket.hpp"
#include "server/web/call_pool.hpp"
#include "server/web/session.hpp"

namespace geotraj::server {
namespace {

namespace v1 = geotraj::v1;
namespace pbu = google::protobuf::util;
namespace net = boost::asio;
namespace ssl = boost::asio::ssl;
namespace beast = boost::beast;
using tcp = boost::asio::ip::tcp;
using web_detail::Connection;
using web_detail::Phase;
using web_detail::Shared;

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
    const std::shared_ptr<Connection> connection =
        web_detail::make_session(shared, std::move(socket), tls ? &*tls : nullptr, std::move(peer));
    if (!register_connection(connection)) return;
    connection->start();
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
