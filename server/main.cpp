// geotrajd: serves the geotraj gRPC API until SIGINT or SIGTERM, then drains.
#include <pthread.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <stop_token>
#include <string>
#include <thread>

#include <CLI/CLI.hpp>

#include "core/format.hpp"
#include "server/ops/exit_guard.hpp"
#include "server/server.hpp"

namespace {

constexpr const char* kFooter = R"(Environment only (secrets do not belong on a command line, where ps shows them):
  GEOTRAJ_AUTH_TOKEN    one bearer token with every scope (added to --auth-tokens-file's)

Health (grpc.health.v1.Health): "" and "geotraj.v1.TrajectoryService" are SERVING while
the process serves (liveness); "geotraj.readiness" once the warm-up plan has run, and
NOT_SERVING from the first moment of a shutdown. On SIGTERM or SIGINT: health turns
NOT_SERVING, new calls get UNAVAILABLE (for --lame-duck-seconds at least), calls in flight
may finish for --drain-seconds, then the rest are cancelled and the process exits 0; a
second signal during the drain cancels them at once.

Refusals name their limit: RESOURCE_EXHAUSTED beyond --max-streams / --max-unary-calls
(a live call takes a --max-streams slot per 1000 Hz of its rate) and --max-live-rate-hz,
INVALID_ARGUMENT beyond --max-frames, --max-stream-samples, --max-live-samples, --max-optimize-seconds,
RESOURCE_EXHAUSTED beyond --max-request-bytes (from gRPC itself) and --max-response-bytes,
INVALID_ARGUMENT beyond --max-analysis-points; DEADLINE_EXCEEDED after
--default-deadline-seconds for a call that gives no deadline. Connections beyond
--max-connections are closed on arrival.
A process ended by a library (not by a signal or a shutdown) exits with status 70.
The web page and its JSON API (--web-address) call the same service in process: the same
tokens (`Authorization: Bearer TOKEN`), limits, drain and metrics.
Documentation: docs/deploy.md, docs/reliability.md, docs/web-api.md.)";

// CLI::Range(min, max) for a floating-point flag, that also refuses NaN (which compares
// false with both bounds, so CLI::Range alone lets it through) and infinities.
CLI::Validator finite_range(double min, double max) {
  const CLI::Range range(min, max);
  return CLI::Validator(
      [range](std::string& text) -> std::string {
        double value = 0.0;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value)) {
          return "Value " + text + " is not a finite number";
        }
        return range(text);
      },
      range.get_description());
}

// share/geotraj/web beside the directory of this binary: <prefix>/share/geotraj/web for
// <prefix>/bin/geotrajd, and <build>/share/geotraj/web (where the build writes the page) for
// <build>/server/geotrajd.
std::string default_web_root() {
  std::error_code error;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error) return {};
  return (exe.parent_path().parent_path() / "share" / "geotraj" / "web").string();
}

}  // namespace

int main(int argc, char** argv) {
  geotraj::server::ServerOptions options;
  double drain_s = 30.0;
  double lame_duck_s = 1.0;
  CLI::App app{"geotrajd: the geotraj trajectory service (gRPC). Every flag also reads the environment "
               "variable named beside it; a flag on the command line wins."};
  app.footer(kFooter);
  app.get_formatter()->column_width(44);

  // Listening.
  app.add_option("--address", options.address,
                 "listening address HOST:PORT (port 0: any free port; 0.0.0.0:50051 in containers)")
      ->envname("GEOTRAJ_ADDRESS")
      ->capture_default_str()
      ->group("Listening");
  app.add_flag("--plaintext", options.plaintext,
               "serve without TLS on a non-loopback address (loopback and unix sockets need no flag)")
      ->envname("GEOTRAJ_PLAINTEXT")
      ->group("Listening");
  app.add_option("--tls-cert", options.tls.cert_file, "server certificate chain, PEM file: serve TLS")
      ->envname("GEOTRAJ_TLS_CERT")
      ->group("Listening");
  app.add_option("--tls-key", options.tls.key_file, "server private key, PEM file")
      ->envname("GEOTRAJ_TLS_KEY")
      ->group("Listening");
  app.add_option("--tls-client-ca", options.tls.client_ca_file,
                 "CA certificates, PEM file: require client certificates signed by them (mutual TLS)")
      ->envname("GEOTRAJ_TLS_CLIENT_CA")
      ->group("Listening");
  app.add_option("--auth-tokens-file", options.auth_tokens_file,
                 "bearer tokens, one per line: `TOKEN [plan,stream,move]` (no scopes: all); every call then needs "
                 "`authorization: Bearer TOKEN` (UNAUTHENTICATED / PERMISSION_DENIED)")
      ->envname("GEOTRAJ_AUTH_TOKENS_FILE")
      ->group("Listening");
  app.add_option("--health-address", options.health_address,
                 "second plaintext address serving only grpc.health.v1.Health (for kubelet gRPC probes when the "
                 "main port is TLS)")
      ->envname("GEOTRAJ_HEALTH_ADDRESS")
      ->group("Listening");
  app.add_option("--metrics-address", options.metrics_address,
                 "HTTP address of Prometheus metrics (GET /metrics) and GET /healthz; empty: off")
      ->envname("GEOTRAJ_METRICS_ADDRESS")
      ->group("Listening");

  app.add_option("--web-address", options.web_address,
                 "HTTP address of the operator's page (GET /) and the JSON API (POST /v1/plan, ...), with the gRPC "
                 "port's TLS, tokens and limits; empty: off")
      ->envname("GEOTRAJ_WEB_ADDRESS")
      ->group("Listening");
  app.add_option("--web-root", options.web_root,
                 "directory of the page's files (default: share/geotraj/web beside the binary's directory)")
      ->envname("GEOTRAJ_WEB_ROOT")
      ->group("Listening");

  // The web port's limits.
  auto& web = options.web_limits;
  double web_idle_s = std::chrono::duration<double>(web.idle_timeout).count();
  double web_header_s = std::chrono::duration<double>(web.header_timeout).count();
  double web_request_s = std::chrono::duration<double>(web.request_timeout).count();
  app.add_option("--web-threads", web.threads,
                 "threads that make the web port's calls and print their JSON (at the workers' priority)")
      ->envname("GEOTRAJ_WEB_THREADS")
      ->check(CLI::Range(1, 256))
      ->capture_default_str()
      ->group("Web port");
  app.add_option("--web-max-queued-calls", web.max_queued_calls,
                 "web calls waiting for one of those threads; beyond: 503 with Retry-After")
      ->envname("GEOTRAJ_WEB_MAX_QUEUED_CALLS")
      ->check(CLI::Range(std::size_t{0}, std::size_t{100'000}))
      ->capture_default_str()
      ->group("Web port");
  app.add_option("--web-max-connections", web.max_connections,
                 "HTTP connections open at once; a new one beyond closes the oldest idle or slow one, or itself")
      ->envname("GEOTRAJ_WEB_MAX_CONNECTIONS")
      ->check(CLI::Range(std::size_t{1}, std::size_t{100'000}))
      ->capture_default_str()
      ->group("Web port");
  app.add_option("--web-max-streams", web.max_streams,
                 "/v1/stream calls in flight (each also takes its --max-streams slots); beyond: 429")
      ->envname("GEOTRAJ_WEB_MAX_STREAMS")
      ->check(CLI::Range(0, 100'000))
      ->capture_default_str()
      ->group("Web port");
  app.add_option("--web-max-answer-bytes", web.max_answer_bytes,
                 "bytes of answers made and not yet taken by their clients; while beyond: 503 with Retry-After")
      ->envname("GEOTRAJ_WEB_MAX_ANSWER_BYTES")
      ->check(CLI::Range(std::size_t{1} << 20, std::size_t{1} << 36))
      ->capture_default_str()
      ->group("Web port");
  app.add_option("--web-idle-timeout-seconds", web_idle_s,
                 "a connection silent this long within a request, not reading a stream, or idle between requests is "
                 "closed [s]")
      ->envname("GEOTRAJ_WEB_IDLE_TIMEOUT_SECONDS")
      ->check(finite_range(0.01, 86400.0))
      ->capture_default_str()
      ->group("Web port");
  app.add_option("--web-header-timeout-seconds", web_header_s,
                 "a request's line and headers must arrive within this [s]; beyond, the connection is closed")
      ->envname("GEOTRAJ_WEB_HEADER_TIMEOUT_SECONDS")
      ->check(finite_range(0.01, 86400.0))
      ->capture_default_str()
      ->group("Web port");
  app.add_option("--web-request-timeout-seconds", web_request_s,
                 "a request must arrive, and a unary answer or file be taken, within this [s]; beyond, the connection is closed")
      ->envname("GEOTRAJ_WEB_REQUEST_TIMEOUT_SECONDS")
      ->check(finite_range(0.01, 86400.0))
      ->capture_default_str()
      ->group("Web port");

  // Limits.
  auto& limits = options.limits;
  app.add_option("--max-streams", limits.max_streams, "streams in flight; beyond: RESOURCE_EXHAUSTED")
      ->envname("GEOTRAJ_MAX_STREAMS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-health-watches", limits.max_health_watches,
                 "grpc.health.v1.Health/Watch streams in flight (no token needed; counted in --max-streams too); "
                 "beyond: RESOURCE_EXHAUSTED")
      ->envname("GEOTRAJ_MAX_HEALTH_WATCHES")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-unary-calls", limits.max_unary_calls,
                 "unary calls in flight (plans, analyses, conversions); beyond: RESOURCE_EXHAUSTED")
      ->envname("GEOTRAJ_MAX_UNARY_CALLS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-live-rate-hz", limits.max_live_rate_hz,
                 "set points per second of all live calls (Execute, Jog) together; a live call also takes one "
                 "--max-streams slot per 1000 Hz of its rate; beyond either: RESOURCE_EXHAUSTED")
      ->envname("GEOTRAJ_MAX_LIVE_RATE_HZ")
      ->check(finite_range(1.0, 1e9))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-live-samples", limits.max_live_samples,
                 "samples of one Execute plan (duration x cycle rate), checked before it is planned when the "
                 "request gives its duration; beyond: INVALID_ARGUMENT")
      ->envname("GEOTRAJ_MAX_LIVE_SAMPLES")
      ->check(CLI::Range(std::uint64_t{2}, std::uint64_t{1'000'000'000}))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--pacing-threads", limits.pacing_threads,
                 "threads that make the live calls' set points, off gRPC's threads (1 on a 2-core machine)")
      ->envname("GEOTRAJ_PACING_THREADS")
      ->check(CLI::Range(1, 64))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-request-bytes", options.max_receive_message_bytes, "largest request message [bytes]")
      ->envname("GEOTRAJ_MAX_REQUEST_BYTES")
      ->check(CLI::Range(1024, 1 << 30))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-frames", limits.max_frames, "key frames in one path")
      ->envname("GEOTRAJ_MAX_FRAMES")
      ->check(CLI::Range(2, 1'000'000))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-stream-samples", limits.max_stream_samples,
                 "samples in one motion that is planned, streamed or checked on a robot")
      ->envname("GEOTRAJ_MAX_STREAM_SAMPLES")
      ->check(CLI::Range(std::uint64_t{2}, std::uint64_t{1'000'000'000}))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-optimize-seconds", limits.max_optimize_seconds,
                 "time one call may optimise [s] (largest optimize.timeBudgetS)")
      ->envname("GEOTRAJ_MAX_OPTIMIZE_SECONDS")
      ->check(finite_range(0.001, 3600.0))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-analysis-points", limits.max_analysis_points,
                 "points of one AnalyzePath answer (analysisPoints); beyond: INVALID_ARGUMENT")
      ->envname("GEOTRAJ_MAX_ANALYSIS_POINTS")
      ->check(CLI::Range(std::uint64_t{2}, std::uint64_t{1'000'000}))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--max-response-bytes", limits.max_response_bytes,
                 "largest answer of a unary call [bytes]; beyond: RESOURCE_EXHAUSTED")
      ->envname("GEOTRAJ_MAX_RESPONSE_BYTES")
      ->check(CLI::Range(std::uint64_t{1024}, std::uint64_t{1} << 31))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--default-deadline-seconds", limits.default_deadline_s,
                 "deadline of a call that carries none (and of a stream's planning) [s]; a client's earlier one wins")
      ->envname("GEOTRAJ_DEFAULT_DEADLINE_SECONDS")
      ->check(finite_range(0.001, 86400.0))
      ->capture_default_str()
      ->group("Limits");
  app.add_option("--workers", limits.workers,
                 "threads that run plans, optimisations, analyses and stream planning, off gRPC's threads (0: one "
                 "per core); calls beyond them queue, up to --max-unary-calls")
      ->envname("GEOTRAJ_WORKERS")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str()
      ->group("Limits");

  // Connections and shutdown.
  auto& connections = options.connections;
  app.add_option("--keepalive-seconds", connections.keepalive_s, "ping a connection idle this long [s]")
      ->envname("GEOTRAJ_KEEPALIVE_SECONDS")
      ->check(finite_range(1.0, 86400.0))
      ->capture_default_str()
      ->group("Connections");
  app.add_option("--keepalive-timeout-seconds", connections.keepalive_timeout_s,
                 "close a connection whose ping is unanswered this long [s]")
      ->envname("GEOTRAJ_KEEPALIVE_TIMEOUT_SECONDS")
      ->check(finite_range(1.0, 3600.0))
      ->capture_default_str()
      ->group("Connections");
  app.add_option("--max-connection-age-seconds", connections.max_connection_age_s,
                 "ask clients to reconnect after this long, so they spread over new replicas [s]; 0: never")
      ->envname("GEOTRAJ_MAX_CONNECTION_AGE_SECONDS")
      ->check(finite_range(0.0, 1e7))
      ->capture_default_str()
      ->group("Connections");
  app.add_option("--max-connection-age-grace-seconds", connections.max_connection_age_grace_s,
                 "calls in flight on an aged connection may finish within this [s]; keep it longer than the longest "
                 "real-time stream")
      ->envname("GEOTRAJ_MAX_CONNECTION_AGE_GRACE_SECONDS")
      ->check(finite_range(0.0, 1e7))
      ->capture_default_str()
      ->group("Connections");
  app.add_option("--max-connections", connections.max_connections,
                 "TCP connections open at once on the gRPC port; beyond, new ones are closed on arrival (lowered "
                 "to fit the descriptor limit, whose soft value is raised to the hard one)")
      ->envname("GEOTRAJ_MAX_CONNECTIONS")
      ->check(CLI::Range(1, 1'000'000))
      ->capture_default_str()
      ->group("Connections");
  app.add_option("--handshake-timeout-seconds", connections.handshake_timeout_s,
                 "close a connection that has not sent the HTTP/2 preface (or finished TLS) within this [s]")
      ->envname("GEOTRAJ_HANDSHAKE_TIMEOUT_SECONDS")
      ->check(finite_range(0.1, 3600.0))
      ->capture_default_str()
      ->group("Connections");
  app.add_option("--max-connection-idle-seconds", connections.max_connection_idle_s,
                 "close a connection with no call for this long (GOAWAY; clients reconnect when needed) [s]; 0: never")
      ->envname("GEOTRAJ_MAX_CONNECTION_IDLE_SECONDS")
      ->check(finite_range(0.0, 1e7))
      ->capture_default_str()
      ->group("Connections");
  app.add_option("--drain-seconds,--shutdown-grace", drain_s,
                 "after SIGTERM/SIGINT, calls in flight may finish this long [s]; keep Kubernetes' "
                 "terminationGracePeriodSeconds longer")
      ->envname("GEOTRAJ_DRAIN_SECONDS")
      ->check(finite_range(0.0, 86400.0))
      ->capture_default_str()
      ->group("Connections");

  app.add_option("--lame-duck-seconds", lame_duck_s,
                 "after SIGTERM/SIGINT, refuse new calls (UNAVAILABLE, retried elsewhere by clients) for at least "
                 "this long [s] even when none is in flight, so clients see NOT_SERVING before connections close")
      ->envname("GEOTRAJ_LAME_DUCK_SECONDS")
      ->check(finite_range(0.0, 3600.0))
      ->capture_default_str()
      ->group("Connections");

  // Logs and models.
  app.add_option("--log-format", options.log_format, "text or json (one object per line)")
      ->envname("GEOTRAJ_LOG_FORMAT")
      ->check(CLI::IsMember({"text", "json"}))
      ->capture_default_str()
      ->group("Logs");
  app.add_option("--log-level", options.log_level, "debug, info (one line per call), warning or error")
      ->envname("GEOTRAJ_LOG_LEVEL")
      ->check(CLI::IsMember({"debug", "info", "warning", "error"}))
      ->capture_default_str()
      ->group("Logs");
  app.add_option("--robot-model", options.robot_model_files,
                 "robot model file: a URDF document (.urdf; docs/kinematics.md; FILE.urdf:TIP_LINK names the chain's "
                 "tip link, by default the leaf through the most moving joints) or proto3 JSON of "
                 "geotraj.v1.RobotModel (as ListRobots prints it), served by its name beside the built-in models; "
                 "repeat for several (environment: comma-separated)")
      ->envname("GEOTRAJ_ROBOT_MODELS")
      ->delimiter(',')
      ->group("Models");
  app.add_option("--joint-limits", options.joint_limits_files,
                 "MoveIt's joint_limits.yaml: the velocity, acceleration, jerk and effort limits of the --robot-model "
                 "models' joints it names (where its has_..._limits flags are true), over each model's own; repeat "
                 "for several (environment: comma-separated)")
      ->envname("GEOTRAJ_JOINT_LIMITS")
      ->delimiter(',')
      ->group("Models");
  CLI11_PARSE(app, argc, argv);
  const auto to_ms = [](double seconds) {
    return std::chrono::milliseconds(static_cast<std::int64_t>(std::llround(seconds * 1000.0)));
  };
  web.idle_timeout = std::max(std::chrono::milliseconds(10), to_ms(web_idle_s));
  web.header_timeout = std::max(std::chrono::milliseconds(10), to_ms(web_header_s));
  web.request_timeout = std::max(std::chrono::milliseconds(10), to_ms(web_request_s));
  if (options.web_root.empty() && !options.web_address.empty()) options.web_root = default_web_root();
  if (const char* token = std::getenv("GEOTRAJ_AUTH_TOKEN")) options.auth_token = token;

  // Block the stop signals in every thread (gRPC's threads inherit the mask) and take them
  // synchronously below, so no handler runs in an arbitrary thread.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  // From here, an exit that main() does not make (a library's exit(0)) is a failure.
  geotraj::server::guard_exit();
  auto running = geotraj::server::start_server(options);
  if (!running) {
    std::fprintf(stderr, "geotrajd: %s\n", running.error().c_str());
    geotraj::server::allow_exit();
    return 1;
  }
  const auto host = options.address.substr(0, options.address.rfind(':'));
  const bool tls = options.tls.enabled();
  // The first line on stdout names the bound port: scripts and tests read it.
  std::printf("geotrajd: serving %s on %s:%d (%s, health SERVING, reflection on)\n", geotraj::server::kServiceName,
              host.c_str(), running->port, tls ? (options.tls.client_ca_file.empty() ? "TLS" : "mutual TLS") : "plaintext");
  if (running->health_port != 0) std::printf("geotrajd: health on port %d\n", running->health_port);
  if (running->metrics_port != 0) std::printf("geotrajd: metrics on http port %d\n", running->metrics_port);
  if (running->web_port != 0) {
    std::printf("geotrajd: web page and JSON API on %s port %d\n", tls ? "https" : "http", running->web_port);
  }
  std::fflush(stdout);
  geotraj::server::log_info(*running, "serving",
                            {{"address", host + ":" + std::to_string(running->port)},
                             {"transport", tls ? "tls" : "plaintext"},
                             {"client_certificates", options.tls.client_ca_file.empty() ? "no" : "required"},
                             {"bearer_tokens", options.auth_tokens_file.empty() && options.auth_token.empty() ? "no" : "required"}});

  int signal = 0;
  sigwait(&stop_signals, &signal);
  const char* name = signal == SIGINT ? "SIGINT" : "SIGTERM";
  geotraj::server::begin_drain(*running);  // refusing new calls before saying so
  std::printf("geotrajd: %s received, draining (up to %s s); a second signal stops at once\n", name,
              geotraj::core::number(drain_s, 6).c_str());
  std::fflush(stdout);
  geotraj::server::log_info(*running, "draining", {{"signal", name}, {"drain_seconds", geotraj::core::number(drain_s)}});
  // A second SIGTERM or SIGINT during the drain ends it: the calls left are cancelled.
  std::stop_source now;
  std::jthread second([&stop_signals, &now, &running](std::stop_token done) {
    while (!done.stop_requested()) {
      const timespec poll_every{0, 100'000'000};
      if (sigtimedwait(&stop_signals, nullptr, &poll_every) > 0) {
        geotraj::server::log_info(*running, "second stop signal: stopping now");
        now.request_stop();
        return;
      }
    }
  });
  geotraj::server::stop_server(*running, std::chrono::milliseconds(static_cast<long long>(drain_s * 1000.0)),
                               std::chrono::milliseconds(static_cast<long long>(lame_duck_s * 1000.0)),
                               now.get_token());
  second.request_stop();
  second.join();
  geotraj::server::log_info(*running, "stopped");
  geotraj::server::allow_exit();
  return 0;
}
