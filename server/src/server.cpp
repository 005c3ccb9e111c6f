#include "geotraj/server/server.hpp"

#include <grpc/grpc.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server_builder.h>

#include <fstream>
#include <sstream>
#include <thread>

#include "grpc/health/v1/health.pb.h"
#include "http_exporter.hpp"
#include "runtime.hpp"
#include "service.hpp"

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

tl::expected<std::shared_ptr<grpc::ServerCredentials>, std::string> credentials(const ServerOptions& options) {
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
    auto added = table.add(options.auth_token, TokenScopes{true, true}, "GEOTRAJ_AUTH_TOKEN");
    if (!added) return tl::unexpected(added.error());
  }
  return table;
}

tl::expected<RobotCatalog, std::string> robot_catalog(const ServerOptions& options) {
  RobotCatalog robots{core::builtin_robots()};
  for (const auto& file : options.robot_model_files) {
    auto text = read_file(file, "robot model file");
    if (!text) return tl::unexpected(text.error());
    auto model = robot_model_from_json(*text);
    if (!model) {
      std::string why;
      for (const auto& v : model.error()) why += (why.empty() ? "" : "; ") + (v.field.empty() ? "" : v.field + ": ") + v.description;
      return tl::unexpected("robot model file \"" + file + "\": " + why);
    }
    if (robots.find(model->name) != nullptr) {
      return tl::unexpected("robot model file \"" + file + "\": a model named \"" + model->name + "\" is already known");
    }
    robots.models.push_back(std::move(*model));
  }
  return robots;
}

tl::expected<std::string, std::string> check_limits(const ServerOptions& options) {
  const auto& l = options.limits;
  if (l.max_streams < 1) return tl::unexpected(std::string("--max-streams must be at least 1"));
  if (l.max_unary_calls < 1) return tl::unexpected(std::string("--max-unary-calls must be at least 1"));
  if (l.max_frames < 2) return tl::unexpected(std::string("--max-frames must be at least 2 (a path has two frames)"));
  if (l.max_stream_samples < 2) return tl::unexpected(std::string("--max-stream-samples must be at least 2"));
  if (!(l.max_optimize_seconds > 0.0)) return tl::unexpected(std::string("--max-optimize-seconds must be > 0"));
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
}

void set_health(RunningServer& running, const char* name, bool serving) {
  for (auto* server : {running.server.get(), running.health_server.get()}) {
    if (server == nullptr) continue;
    if (name == nullptr) {
      server->GetHealthCheckService()->SetServingStatus(serving);
    } else {
      server->GetHealthCheckService()->SetServingStatus(name, serving);
    }
  }
}

}  // namespace

RunningServer::RunningServer() = default;
RunningServer::RunningServer(RunningServer&&) noexcept = default;
RunningServer& RunningServer::operator=(RunningServer&&) noexcept = default;
RunningServer::~RunningServer() {
  if (metrics) metrics->stop();
  // The servers refer to the service: shut them down first.
  health_server.reset();
  server.reset();
}

tl::expected<RunningServer, std::string> start_server(const ServerOptions& options) {
  // Both are process-wide switches that must be set before a ServerBuilder exists.
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  // Links the health protocol's descriptors into the process, so that reflection can
  // describe grpc.health.v1.Health too (its messages are otherwise unused by the server).
  (void)grpc::health::v1::HealthCheckRequest::descriptor();

  if (auto bad = check_limits(options); !bad) return tl::unexpected(bad.error());
  auto format = parse_log_format(options.log_format);
  if (!format) return tl::unexpected(format.error());
  auto level = parse_log_level(options.log_level);
  if (!level) return tl::unexpected(level.error());
  auto creds = credentials(options);
  if (!creds) return tl::unexpected(creds.error());
  auto table = tokens(options);
  if (!table) return tl::unexpected(table.error());
  auto robots = robot_catalog(options);
  if (!robots) return tl::unexpected(robots.error());

  RunningServer running;
  running.runtime = std::make_shared<Runtime>(options.limits, std::move(*table),
                                              Logger(*format, *level, options.log_output ? options.log_output : stderr));
  running.service = make_trajectory_service(std::move(*robots), running.runtime);
  grpc::ServerBuilder builder;
  if (!options.address.empty()) builder.AddListeningPort(options.address, *creds, &running.port);
  builder.SetMaxReceiveMessageSize(options.max_receive_message_bytes);
  apply_connection_options(builder, options.connections);
  builder.RegisterService(running.service.get());
  running.server = builder.BuildAndStart();
  if (!running.server) {
    return tl::unexpected("cannot start the gRPC server on \"" + options.address +
                          "\" (is the address valid, and the port free?)");
  }
  if (!options.address.empty() && running.port == 0) {
    running.server->Shutdown();
    return tl::unexpected("cannot listen on \"" + options.address + "\" (is the address valid, and the port free?)");
  }
  if (!options.health_address.empty()) {
    grpc::ServerBuilder health;
    health.AddListeningPort(options.health_address, grpc::InsecureServerCredentials(), &running.health_port);
    running.health_server = health.BuildAndStart();
    if (!running.health_server || running.health_port == 0) {
      return tl::unexpected("cannot listen on the health address \"" + options.health_address +
                            "\" (is the address valid, and the port free?)");
    }
  }
  if (!options.metrics_address.empty()) {
    auto runtime = running.runtime;
    auto exporter = HttpExporter::start(options.metrics_address, [runtime] { return runtime->metrics().exposition(); });
    if (!exporter) return tl::unexpected(exporter.error());
    running.metrics = std::move(*exporter);
    running.metrics_port = running.metrics->port();
  }
  // Liveness: the process serves. Readiness waits for the warm-up.
  set_health(running, nullptr, true);
  set_health(running, kServiceName, true);
  set_health(running, kReadinessService, false);
  if (auto warm = warm_up(*running.service); !warm.ok()) {
    return tl::unexpected("the warm-up plan failed (" + warm.error_message() + ")");
  }
  set_health(running, kReadinessService, true);
  return running;
}

void stop_server(RunningServer& running, std::chrono::milliseconds drain, std::chrono::milliseconds lame_duck) {
  if (!running.server) return;
  const auto began = std::chrono::steady_clock::now();
  running.runtime->start_draining();
  set_health(running, nullptr, false);
  set_health(running, kServiceName, false);
  set_health(running, kReadinessService, false);
  // New calls are refused (UNAVAILABLE) from now on; those in flight may finish.
  // The lame duck: even with no call in flight, keep refusing (UNAVAILABLE, which clients
  // retry elsewhere) while clients and load balancers see NOT_SERVING; calls that reach a
  // server that has begun its shutdown would be CANCELLED instead.
  const auto until = began + drain;
  const auto refuse_until = began + std::min(lame_duck, drain);
  while ((running.runtime->calls_in_flight() > 0 || std::chrono::steady_clock::now() < refuse_until) &&
         std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const int left = running.runtime->calls_in_flight();
  if (left > 0) {
    running.runtime->logger().log(LogLevel::kWarning, "drain time over: cancelling the calls in flight",
                                  {{"calls", static_cast<std::int64_t>(left)}});
  }
  // Whatever is left is cancelled; a short deadline lets cancelled reactors finish.
  running.server->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
  running.server->Wait();
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
