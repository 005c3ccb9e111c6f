#include "server/server.hpp"

#include <grpc/grpc.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_builder.h>

#include <cmath>
#include <filesystem>
#include <csignal>
#include <fstream>
#include <sstream>
#include <thread>
#include <optional>

#include <openssl/bio.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include "grpc/health/v1/health.pb.h"
#include "server/ops/acceptor.hpp"
#include "server/ops/http_exporter.hpp"
#include "server/ops/runtime.hpp"
#include "server/ops/socket.hpp"
#include "server/rpc/health.hpp"
#include "planner/joint_limits_yaml.hpp"
#include "planner/robots.hpp"
#include "server/rpc/service.hpp"
#include "server/web/gateway.hpp"

namespace geotraj::server {
namespace {

tl::expected<std::string, std::string> read_file(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return tl::unexpected("cannot read the " + what + " \"" + path + "\"");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Loopback addresses and unix sockets (and no address: in-process channels only): reachable
// from this machine only.
bool local_only(const std::string& address) {
  if (address.empty()) return true;
  if (address.rfind("unix:", 0) == 0 || address.rfind("unix-abstract:", 0) == 0) return true;
  const auto colon = address.rfind(':');
  std::string host = colon == std::string::npos ? address : address.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host == "localhost" || host == "::1") return true;
  // 127.0.0.0/8 written as numbers only: a host name such as 127.0.0.1.example.com is not.
  const bool numeric = !host.empty() && host.find_first_not_of("0123456789.") == std::string::npos;
  return numeric && host.rfind("127.", 0) == 0;
}

// The certificate's validity period as a warning (expired, or not valid yet), and a key
// that does not belong to the certificate as an error: gRPC would only fail to start.
tl::expected<std::vector<std::string>, std::string> check_certificate(const std::string& cert_pem,
                                                                       const std::string& key_pem,
                                                                       const TlsOptions& tls) {
  const auto bio = [](const std::string& pem) {
    return std::unique_ptr<BIO, decltype(&BIO_free)>(BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size())), BIO_free);
  };
  auto cert_bio = bio(cert_pem);
  std::unique_ptr<X509, decltype(&X509_free)> cert(PEM_read_bio_X509(cert_bio.get(), nullptr, nullptr, nullptr),
                                                    X509_free);
  if (!cert) return tl::unexpected("the TLS certificate file (--tls-cert) \"" + tls.cert_file + "\" holds no PEM certificate");
  auto key_bio = bio(key_pem);
  std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(
      PEM_read_bio_PrivateKey(key_bio.get(), nullptr, nullptr, nullptr), EVP_PKEY_free);
  if (!key) {
    return tl::unexpected("the TLS private key file (--tls-key) \"" + tls.key_file +
                          "\" holds no PEM private key (or it is encrypted: geotrajd takes unencrypted keys)");
  }
  if (X509_check_private_key(cert.get(), key.get()) != 1) {
    return tl::unexpected("the TLS private key (--tls-key \"" + tls.key_file +
                          "\") does not belong to the certificate (--tls-cert \"" + tls.cert_file + "\")");
  }
  std::vector<std::string> warnings;
  const auto when = [](const ASN1_TIME* t) {
    std::unique_ptr<BIO, decltype(&BIO_free)> out(BIO_new(BIO_s_mem()), BIO_free);
    ASN1_TIME_print(out.get(), t);
    char* data = nullptr;
    const long n = BIO_get_mem_data(out.get(), &data);
    return std::string(data, static_cast<std::size_t>(std::max(0L, n)));
  };
  if (X509_cmp_current_time(X509_get0_notAfter(cert.get())) < 0) {
    warnings.push_back("the TLS certificate (--tls-cert \"" + tls.cert_file + "\") expired on " +
                       when(X509_get0_notAfter(cert.get())) + ": clients will refuse the handshake");
  }
  if (X509_cmp_current_time(X509_get0_notBefore(cert.get())) > 0) {
    warnings.push_back("the TLS certificate (--tls-cert \"" + tls.cert_file + "\") is not valid before " +
                       when(X509_get0_notBefore(cert.get())) + ": clients will refuse the handshake until then");
  }
  return warnings;
}

tl::expected<std::shared_ptr<grpc::ServerCredentials>, std::string> credentials(const ServerOptions& options,
                                                                                std::vector<std::string>& warnings) {
  const auto& tls = options.tls;
  if (!tls.enabled()) {
    if (!tls.client_ca_file.empty()) {
      return tl::unexpected(std::string("--tls-client-ca needs --tls-cert and --tls-key (mutual TLS is TLS)"));
    }
    if (!options.plaintext && !local_only(options.address)) {
      return tl::unexpected("refusing to serve plaintext on \"" + options.address +
                            "\": give --tls-cert and --tls-key, or --plaintext (GEOTRAJ_PLAINTEXT=true) to accept "
                            "unencrypted connections on a non-loopback address");
    }
    return grpc::InsecureServerCredentials();
  }
  if (tls.cert_file.empty() || tls.key_file.empty()) {
    return tl::unexpected(std::string("TLS needs both --tls-cert and --tls-key"));
  }
  if (options.plaintext) return tl::unexpected(std::string("--plaintext and --tls-cert exclude each other"));
  auto cert = read_file(tls.cert_file, "TLS certificate file (--tls-cert)");
  if (!cert) return tl::unexpected(cert.error());
  auto key = read_file(tls.key_file, "TLS private key file (--tls-key)");
  if (!key) return tl::unexpected(key.error());
  auto checked = check_certificate(*cert, *key, tls);
  if (!checked) return tl::unexpected(checked.error());
  warnings = std::move(*checked);
  grpc::SslServerCredentialsOptions ssl;
  ssl.pem_key_cert_pairs.push_back({std::move(*key), std::move(*cert)});
  if (!tls.client_ca_file.empty()) {
    auto ca = read_file(tls.client_ca_file, "client CA file (--tls-client-ca)");
    if (!ca) return tl::unexpected(ca.error());
    ssl.pem_root_certs = std::move(*ca);
    ssl.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  return grpc::SslServerCredentials(ssl);
}

tl::expected<TokenTable, std::string> tokens(const ServerOptions& options) {
  TokenTable table;
  if (!options.auth_tokens_file.empty()) {
    auto from_file = TokenTable::from_file(options.auth_tokens_file);
    if (!from_file) return tl::unexpected(from_file.error());
    table = std::move(*from_file);
  }
  if (!options.auth_token.empty()) {
    auto added = table.add(options.auth_token, TokenScopes{true, true, true}, "GEOTRAJ_AUTH_TOKEN");
    if (!added) return tl::unexpected(added.error());
  }
  return table;
}

// The limits of the --joint-limits files, in order (later files over earlier ones), each
// naming its file as its source.
tl::expected<std::vector<planner::NamedLimits>, std::string> joint_limits_files(const ServerOptions& options) {
  std::vector<planner::NamedLimits> limits;
  for (const auto& file : options.joint_limits_files) {
    auto text = read_file(file, "joint limits file (--joint-limits)");
    if (!text) return tl::unexpected(text.error());
    auto read = planner::joint_limits_from_yaml(*text, "");
    if (!read) {
      std::string why;
      for (const auto& v : read.error()) why += (why.empty() ? "" : "; ") + v.description;
      return tl::unexpected("joint limits file \"" + file + "\" " + why);
    }
    for (auto& l : *read) {
      l.source = "joint_limits.yaml \"" + file + "\" (geotrajd --joint-limits)";
      limits.push_back(std::move(l));
    }
  }
  return limits;
}

tl::expected<RobotCatalog, std::string> robot_catalog(const ServerOptions& options) {
  RobotCatalog robots{planner::builtin_robots()};
  const auto yaml = joint_limits_files(options);
  if (!yaml) return tl::unexpected(yaml.error());
  bool named = false;
  for (const auto& given : options.robot_model_files) {
    // FILE, or FILE:TIP_LINK where FILE names a file and the whole does not.
    std::string file = given;
    planner::UrdfOptions urdf_options;
    if (const auto colon = given.rfind(':'); colon != std::string::npos && !std::filesystem::exists(given) &&
                                             std::filesystem::exists(given.substr(0, colon))) {
      file = given.substr(0, colon);
      urdf_options.tip_link = given.substr(colon + 1);
    }
    auto text = read_file(file, "robot model file");
    if (!text) return tl::unexpected(text.error());
    // A URDF document (by its extension, or its first character) or a RobotModel in JSON.
    // MoveIt's limits over the model's, for the joints it has (a gripper's are not the arm's).
    const auto first = text->find_first_not_of(" \t\r\n");
    const bool urdf = file.ends_with(".urdf") || (first != std::string::npos && (*text)[first] == '<');
    if (!urdf && !urdf_options.tip_link.empty()) {
      return tl::unexpected("robot model file \"" + file + "\": a tip link (\":" + urdf_options.tip_link +
                            "\") is read for a URDF document only");
    }
    auto read = urdf ? planner::robot_from_urdf(*text, urdf_options) : robot_model_from_json(*text);
    if (read) {
      for (bool n : planner::apply_named_limits(*yaml, *read)) named = named || n;
    }
    // Checked once, here: the catalogue's models carry the proof to every request.
    auto model = read.and_then([](core::RobotModel m) { return core::ValidRobot::check(std::move(m)); });
    if (!model) {
      std::string why;
      for (const auto& v : model.error()) why += (why.empty() ? "" : "; ") + (v.field.empty() ? "" : v.field + ": ") + v.description;
      return tl::unexpected("robot model file \"" + file + "\": " + why);
    }
    if (robots.find((*model)->name) != nullptr) {
      return tl::unexpected("robot model file \"" + file + "\": a model named \"" + (*model)->name + "\" is already known");
    }
    robots.models.push_back(std::move(*model));
  }
  if (!yaml->empty() && !named)
    return tl::unexpected(std::string("--joint-limits names no joint of the --robot-model models"));
  return robots;
}

tl::expected<std::string, std::string> check_limits(const ServerOptions& options) {
  const auto& l = options.limits;
  if (l.max_streams < 1) return tl::unexpected(std::string("--max-streams must be at least 1"));
  if (l.max_unary_calls < 1) return tl::unexpected(std::string("--max-unary-calls must be at least 1"));
  if (l.max_health_watches < 0) return tl::unexpected(std::string("--max-health-watches must be >= 0"));
  if (l.max_frames < 2) return tl::unexpected(std::string("--max-frames must be at least 2 (a path has two frames)"));
  if (l.max_stream_samples < 2) return tl::unexpected(std::string("--max-stream-samples must be at least 2"));
  if (l.max_live_samples < 2) return tl::unexpected(std::string("--max-live-samples must be at least 2"));
  if (!(l.max_live_rate_hz >= 1.0) || !std::isfinite(l.max_live_rate_hz)) {
    return tl::unexpected(std::string("--max-live-rate-hz must be a number of at least 1 (one live call at 1 Hz)"));
  }
  if (l.pacing_threads < 1 || l.pacing_threads > 64) {
    return tl::unexpected(std::string("--pacing-threads must be between 1 and 64"));
  }
  if (!(l.max_optimize_seconds > 0.0)) return tl::unexpected(std::string("--max-optimize-seconds must be > 0"));
  if (l.max_analysis_points < 2) return tl::unexpected(std::string("--max-analysis-points must be at least 2"));
  if (l.max_response_bytes < 1024) return tl::unexpected(std::string("--max-response-bytes must be at least 1024"));
  if (!(l.default_deadline_s > 0.0)) return tl::unexpected(std::string("--default-deadline-seconds must be > 0"));
  if (l.workers < 0) return tl::unexpected(std::string("--workers must be >= 0 (0: one per core)"));
  if (options.max_receive_message_bytes < 1024) {
    return tl::unexpected(std::string("--max-request-bytes must be at least 1024"));
  }
  const auto& c = options.connections;
  if (!(c.keepalive_s >= 1.0) || !(c.keepalive_timeout_s >= 1.0)) {
    return tl::unexpected(std::string("--keepalive-seconds and --keepalive-timeout-seconds must be at least 1"));
  }
  if (!(c.max_connection_age_s >= 0.0) || !(c.max_connection_age_grace_s >= 0.0)) {
    return tl::unexpected(std::string("--max-connection-age-seconds and its grace must be >= 0"));
  }
  if (!(c.handshake_timeout_s > 0.0)) return tl::unexpected(std::string("--handshake-timeout-seconds must be > 0"));
  if (!(c.max_connection_idle_s >= 0.0)) return tl::unexpected(std::string("--max-connection-idle-seconds must be >= 0"));
  if (c.max_connections < 1) return tl::unexpected(std::string("--max-connections must be at least 1"));
  return std::string();
}

int milliseconds(double seconds) {
  return static_cast<int>(std::min(seconds * 1e3, static_cast<double>(std::numeric_limits<int>::max())));
}

void apply_connection_options(grpc::ServerBuilder& builder, const ConnectionOptions& c) {
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, milliseconds(c.keepalive_s));
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, milliseconds(c.keepalive_timeout_s));
  // Clients may ping idle connections every 10 s without being told off (GOAWAY).
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10'000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  if (c.max_connection_age_s > 0.0) {
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_MS, milliseconds(c.max_connection_age_s));
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_AGE_GRACE_MS, milliseconds(c.max_connection_age_grace_s));
  }
  // A connection that never sends the HTTP/2 preface and settings (or never finishes the TLS
  // handshake) is closed after this, so that idle sockets do not hold descriptors.
  builder.AddChannelArgument(GRPC_ARG_SERVER_HANDSHAKE_TIMEOUT_MS, milliseconds(c.handshake_timeout_s));
  if (c.max_connection_idle_s > 0.0) {
    builder.AddChannelArgument(GRPC_ARG_MAX_CONNECTION_IDLE_MS, milliseconds(c.max_connection_idle_s));
  }
  // Ports that gRPC binds itself (unix sockets) are never shared with another process.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
}

// Server reflection on one builder (the gRPC port) and not on another (the health-only
// port, which serves health and nothing else): linking gRPC's reflection library adds its
// plugin to every builder of the process, so the plugin list is set here either way.
class Reflection final : public grpc::ServerBuilderOption {
 public:
  explicit Reflection(bool on) : on_(on) {}
  void UpdateArguments(grpc::ChannelArguments* /*args*/) override {}
  void UpdatePlugins(std::vector<std::unique_ptr<grpc::ServerBuilderPlugin>>* plugins) override {
    std::erase_if(*plugins, [](const auto& plugin) { return plugin->name() == kPluginName; });
    if (on_) plugins->push_back(std::make_unique<grpc::reflection::ProtoServerReflectionPlugin>());
  }

 private:
  static constexpr const char* kPluginName = "proto_server_reflection";
  bool on_;
};

// TCP addresses are accepted by geotrajd's own acceptor (acceptor.hpp); unix sockets, and
// no address, by gRPC.
bool tcp_address(const std::string& address) {
  return !address.empty() && address.rfind("unix:", 0) != 0 && address.rfind("unix-abstract:", 0) != 0;
}

// Descriptors kept free of connections (files, pipes, gRPC's own, the metrics port's): an
// eighth of the limit, at least 64; the health-only port (kubelet's probes need a few) takes
// another eighth, at most 256.
long reserved_descriptors(long limit) { return std::max(64L, limit / 8); }
long health_connections(long limit) { return std::clamp(limit / 8, 4L, 256L); }

// A builder's listening port: the acceptor's sink for TCP, gRPC's own listener otherwise.
struct Listening {
  std::unique_ptr<Acceptor> acceptor;
  std::unique_ptr<grpc::experimental::ExternalConnectionAcceptor> sink;
  int port = 0;  // gRPC's own listener writes the bound port here at BuildAndStart
};

tl::expected<Listening, std::string> add_listening(grpc::ServerBuilder& builder, const std::string& address,
                                                   const std::shared_ptr<grpc::ServerCredentials>& creds,
                                                   const std::string& what, std::unique_ptr<Listening>& own) {
  Listening out;
  if (!tcp_address(address)) {
    if (!address.empty()) {
      own = std::make_unique<Listening>();
      builder.AddListeningPort(address, creds, &own->port);
    }
    return out;
  }
  auto acceptor = Acceptor::listen(address, what);
  if (!acceptor) return tl::unexpected(acceptor.error());
  out.acceptor = std::move(*acceptor);
  out.port = out.acceptor->port();
  out.sink = builder.experimental().AddExternalConnectionAcceptor(
      grpc::ServerBuilder::experimental_type::ExternalConnectionType::FROM_FD, creds);
  return out;
}

}  // namespace

RunningServer::RunningServer() = default;
RunningServer::RunningServer(RunningServer&&) noexcept = default;
RunningServer& RunningServer::operator=(RunningServer&&) noexcept = default;
RunningServer::~RunningServer() {
  if (metrics) metrics->stop();
  // No connection may reach a server being destroyed (the servers refer to the services);
  // then every call is cancelled at once: a health watch or a real-time stream would
  // otherwise keep ~Server's unbounded shutdown waiting.
  if (runtime) runtime->start_draining();
  acceptor.reset();
  health_acceptor.reset();
  for (auto* s : {health_server.get(), server.get()}) {
    if (s != nullptr) s->Shutdown(std::chrono::system_clock::now());
  }
  // The web side's calls were refused or cancelled with the server: its threads are
  // joined before the server they call goes.
  web.reset();
  health_server.reset();
  server.reset();
  if (runtime) unroute_grpc_logs(runtime->logger());
}

tl::expected<RunningServer, std::string> start_server(const ServerOptions& options) {
  // geotrajd serves grpc.health.v1.Health itself (health.hpp): gRPC's default service off.
  grpc::EnableDefaultHealthCheckService(false);
  // Links the health protocol's descriptors into the process, so that reflection can
  // describe grpc.health.v1.Health too.
  (void)grpc::health::v1::HealthCheckRequest::descriptor();

  if (auto bad = check_limits(options); !bad) return tl::unexpected(bad.error());
  auto format = parse_log_format(options.log_format);
  if (!format) return tl::unexpected(format.error());
  auto level = parse_log_level(options.log_level);
  if (!level) return tl::unexpected(level.error());
  std::vector<std::string> warnings;
  auto creds = credentials(options, warnings);
  if (!creds) return tl::unexpected(creds.error());
  auto table = tokens(options);
  if (!table) return tl::unexpected(table.error());
  auto robots = robot_catalog(options);
  if (!robots) return tl::unexpected(robots.error());
  for (const auto& m : robots->models) {  // served for the kinematics; a motion says what it lacks
    if (std::string why = planner::missing_accelerations(m); !why.empty())
      warnings.push_back("robot model \"" + m->name + "\" serves the kinematics only until its limits are given: " +
                         why);
  }

  RunningServer running;
  running.runtime = std::make_shared<Runtime>(options.limits, std::move(*table),
                                              Logger(*format, *level, options.log_output ? options.log_output : stderr));
  const Logger& logger = running.runtime->logger();
  route_grpc_logs(&logger);
  for (const auto& w : warnings) logger.log(LogLevel::kWarning, w);
  {
    Runtime* runtime = running.runtime.get();
    runtime->metrics().set_worker_source([runtime] {
      return std::pair<std::int64_t, std::int64_t>(static_cast<std::int64_t>(runtime->workers().queued()),
                                                   runtime->workers().busy());
    });
  }

  // Connections fit the descriptors: the soft limit raised to the hard one, and the cap
  // lowered below it when it would not fit.
  const long descriptors = raise_descriptor_limit();
  int max_connections = options.connections.max_connections;
  const long health_cap = health_connections(descriptors);
  const long room = std::max(16L, descriptors - reserved_descriptors(descriptors) - health_cap);
  if (max_connections > room) {
    logger.log(LogLevel::kWarning, "--max-connections lowered to fit the descriptor limit",
               {{"max_connections", static_cast<std::int64_t>(room)}, {"asked", static_cast<std::int64_t>(max_connections)},
                {"descriptor_limit", static_cast<std::int64_t>(descriptors)}});
    max_connections = static_cast<int>(room);
  }

  running.health = std::make_shared<HealthState>();
  running.health->set_readiness_name(kReadinessService);
  running.service = make_trajectory_service(std::move(*robots), running.runtime);
  running.health_service = make_health_service(running.health, running.runtime);
  grpc::ServerBuilder builder;
  std::unique_ptr<Listening> own_port;  // gRPC's listener (unix sockets)
  auto main_port = add_listening(builder, options.address, *creds, "gRPC address", own_port);
  if (!main_port) return tl::unexpected(main_port.error());
  builder.SetMaxReceiveMessageSize(options.max_receive_message_bytes);
  apply_connection_options(builder, options.connections);
  builder.SetOption(std::make_unique<Reflection>(true));
  builder.RegisterService(running.service.get());
  builder.RegisterService(running.health_service.get());
  running.server = builder.BuildAndStart();
  if (!running.server || (own_port && own_port->port == 0)) {
    return tl::unexpected("cannot start the gRPC server on \"" + options.address + "\"");
  }
  running.port = main_port->port;
  running.acceptor = std::move(main_port->acceptor);

  std::optional<Listening> health_port;
  if (!options.health_address.empty()) {
    running.health_only_service = make_health_service(running.health, running.runtime);
    grpc::ServerBuilder health;
    std::unique_ptr<Listening> unused;
    auto port = add_listening(health, options.health_address, grpc::InsecureServerCredentials(), "health address", unused);
    if (!port) return tl::unexpected(port.error());
    apply_connection_options(health, options.connections);
    health.SetOption(std::make_unique<Reflection>(false));
    health.RegisterService(running.health_only_service.get());
    running.health_server = health.BuildAndStart();
    if (!running.health_server) {
      return tl::unexpected("cannot start the health server on \"" + options.health_address + "\"");
    }
    running.health_port = port->port;
    running.health_acceptor = std::move(port->acceptor);
    health_port = std::move(*port);
  }
  if (!options.metrics_address.empty()) {
    auto runtime = running.runtime;
    auto exporter = HttpExporter::start(options.metrics_address, [runtime] { return runtime->metrics().exposition(); });
    if (!exporter) return tl::unexpected(exporter.error());
    running.metrics = std::move(*exporter);
    running.metrics_port = running.metrics->port();
  }
  if (!options.web_address.empty()) {
    if (!options.tls.enabled() && !options.plaintext && !local_only(options.web_address)) {
      return tl::unexpected("refusing to serve plaintext HTTP on the web address \"" + options.web_address +
                            "\": give --tls-cert and --tls-key, or --plaintext to accept unencrypted connections on a "
                            "non-loopback address");
    }
    // A page closed mid-answer must give EPIPE, not end the process by SIGPIPE (Asio sends
    // with MSG_NOSIGNAL; this covers any write that does not).
    std::signal(SIGPIPE, SIG_IGN);
    grpc::ChannelArguments channel;
    channel.SetMaxReceiveMessageSize(-1);  // answers are bounded by the service (--max-response-bytes)
    WebOptions web;
    static_cast<WebLimits&>(web) = options.web_limits;
    web.address = options.web_address;
    web.root = options.web_root;
    web.tls = options.tls;
    web.max_request_bytes = static_cast<std::size_t>(std::max(0, options.max_receive_message_bytes));
    auto gateway = WebGateway::start(web, running.server->InProcessChannel(channel));
    if (!gateway) return tl::unexpected(gateway.error());
    running.web = std::move(*gateway);
    running.web_port = running.web->port();
  }
  // Liveness: the process serves. Readiness waits for the warm-up, and for the ports to
  // accept connections.
  running.health->set("", true);
  running.health->set(kServiceName, true);
  running.health->set(kReadinessService, false);
  const auto accepting = [health = running.health](const char* listener) {
    return [health, listener](bool ok) { health->set_accepting(listener, ok); };
  };
  if (running.acceptor) {
    running.acceptor->start(std::move(main_port->sink),
                            {"grpc", static_cast<std::size_t>(max_connections), accepting("grpc")},
                            running.runtime->metrics(), logger);
  }
  if (running.health_acceptor) {
    running.health_acceptor->start(std::move(health_port->sink),
                                   {"health", static_cast<std::size_t>(health_cap), accepting("health")},
                                   running.runtime->metrics(), logger);
  }
  if (auto warm = warm_up(*running.service); !warm.ok()) {
    return tl::unexpected("the warm-up plan failed (" + warm.error_message() + ")");
  }
  running.health->set(kReadinessService, true);
  return running;
}

void begin_drain(RunningServer& running) {
  if (!running.server) return;
  running.runtime->start_draining();
  running.health->set_all(false);
}

void stop_server(RunningServer& running, std::chrono::milliseconds drain, std::chrono::milliseconds lame_duck,
                 std::stop_token now) {
  if (!running.server) return;
  const auto began = std::chrono::steady_clock::now();
  begin_drain(running);
  // New calls are refused (UNAVAILABLE) from now on; those in flight may finish.
  // The lame duck: even with no call in flight, keep refusing (UNAVAILABLE, which clients
  // retry elsewhere) while clients and load balancers see NOT_SERVING; calls that reach a
  // server that has begun its shutdown would be CANCELLED instead.
  const auto until = began + drain;
  const auto refuse_until = began + std::min(lame_duck, drain);
  // Health watches are not calls in flight, but each is owed its NOT_SERVING before the
  // server ends it (under load the write could still be in flight at the shutdown).
  while ((running.runtime->calls_in_flight() > 0 || std::chrono::steady_clock::now() < refuse_until ||
          !running.health->delivered()) &&
         std::chrono::steady_clock::now() < until && !now.stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const int left = running.runtime->calls_in_flight();
  if (left > 0) {
    running.runtime->logger().log(LogLevel::kWarning,
                                  now.stop_requested() ? "stopping now: cancelling the calls in flight"
                                                       : "drain time over: cancelling the calls in flight",
                                  {{"calls", static_cast<std::int64_t>(left)}});
  }
  // No more connections (gRPC would leave one handed to a server that is shutting down
  // open and silent); clients now get ECONNREFUSED and go elsewhere.
  if (running.acceptor) running.acceptor->stop();
  if (running.health_acceptor) running.health_acceptor->stop();
  // Whatever is left is cancelled (its reactors' stop tokens trip, so optimisations end
  // within an iteration); a short deadline lets cancelled reactors finish.
  running.server->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
  running.server->Wait();
  // Every live call has ended: say how many arms the drain brought to rest and how many it
  // cut mid-motion (a drain shorter than a stop, a second signal, a client gone).
  const Runtime::DrainedLive live = running.runtime->drained_live();
  if (live.at_rest + live.cut > 0) {
    running.runtime->logger().log(live.cut > 0 ? LogLevel::kWarning : LogLevel::kInfo,
                                  live.cut > 0 ? "drain over: live motions cut before they came to rest"
                                               : "drain over: every live motion brought to rest",
                                  {{"live_at_rest", static_cast<std::int64_t>(live.at_rest)},
                                   {"live_cut", static_cast<std::int64_t>(live.cut)}});
  }
  // The web side's calls have ended with the server's; its connections close.
  if (running.web) running.web->stop();
  if (running.health_server) {
    running.health_server->Shutdown(std::chrono::system_clock::now());
    running.health_server->Wait();
  }
  if (running.metrics) running.metrics->stop();
}

std::string metrics_exposition(const RunningServer& running) { return running.runtime->metrics().exposition(); }

void log_info(const RunningServer& running, std::string_view message,
              const std::vector<std::pair<std::string, std::string>>& fields) {
  std::vector<LogField> out;
  for (const auto& [key, value] : fields) out.push_back({key, value});
  running.runtime->logger().log(LogLevel::kInfo, message, std::move(out));
}

}  // namespace geotraj::server
