// What every call of the service shares: the limits it enforces, the bearer tokens it
// accepts, the counts of calls in flight (the admission cap), the draining switch, the
// metrics and the log. One Runtime per server; the service and start/stop share it.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <grpcpp/support/server_callback.h>
#include <grpcpp/support/status.h>
#include <tl/expected.hpp>

#include "server/ops/log.hpp"
#include "server/ops/metrics.hpp"
#include "server/ops/worker_pool.hpp"
#include "server/options.hpp"

namespace geotraj::server {

/// The RPCs of geotraj.v1.TrajectoryService.
enum class Method {
  kConvertConstraints,
  kPlanTrajectory,
  kStreamSamples,
  kAnalyzePath,
  kListRobots,
  kComputeForwardKinematics,
  kComputeInverseKinematics,
  kExecute,
  kJog,
};

std::string_view method_name(Method method);
/// Streams (StreamSamples, Execute, Jog) count against --max-streams, unary calls against
/// --max-unary-calls.
bool is_streaming(Method method);

/// What a bearer token may call: `plan` (every unary RPC), `stream` (StreamSamples, whose
/// samples a controller may follow), `move` (Execute and Jog, which drive a robot live).
struct TokenScopes {
  bool plan = false;
  bool stream = false;
  bool move = false;
};

/// The bearer tokens a server accepts, with their scopes. Empty: no token is asked for.
class TokenTable {
 public:
  /// Reads a tokens file: one token per line, optionally followed by its scopes
  /// (`TOKEN plan,stream,move`; none: every scope); blank lines and lines starting with # are
  /// skipped. Errors name the file and the line, never the token.
  static tl::expected<TokenTable, std::string> from_file(const std::string& path);
  /// Adds one token with every scope (the GEOTRAJ_AUTH_TOKEN environment variable).
  tl::expected<void, std::string> add(std::string token, TokenScopes scopes, const std::string& origin);

  bool empty() const { return tokens_.empty(); }
  std::size_t size() const { return tokens_.size(); }

  /// The refusal for a call with these client metadata, or nullopt when it may go on:
  /// UNAUTHENTICATED without a valid `authorization: Bearer <token>`, PERMISSION_DENIED when
  /// the token's scopes do not cover `method`. Tokens are compared in constant time.
  std::optional<grpc::Status> check(const grpc::CallbackServerContext& context, Method method) const;

 private:
  struct Entry {
    std::string token;
    TokenScopes scopes;
  };
  std::vector<Entry> tokens_;
};

/// State shared by the calls of one server.
class Runtime {
 public:
  Runtime(ServiceLimits limits, TokenTable tokens, Logger logger);

  const ServiceLimits& limits() const { return limits_; }
  /// Where long work runs (worker_pool.hpp).
  WorkerPool& workers() { return workers_; }
  /// Where the live calls make their set points (--pacing-threads, normal priority): never
  /// on gRPC's threads, so health checks and other calls do not wait behind them.
  WorkerPool& pacing() { return pacing_; }
  Metrics& metrics() { return metrics_; }
  const Logger& logger() const { return logger_; }
  const TokenTable& tokens() const { return tokens_; }

  /// From now on, new calls are refused with UNAVAILABLE (the server is going away).
  void start_draining() { draining_.store(true); }
  bool draining() const { return draining_.load(); }
  /// Calls admitted and not yet finished (streams and unary calls; health watches aside).
  int calls_in_flight() const {
    return std::max(0, active_streams_.load() - active_watches_.load()) + active_unary_.load();
  }

  /// Admits one grpc.health.v1.Health/Watch against --max-streams: nullopt when admitted
  /// (release it with end_watch()), else RESOURCE_EXHAUSTED naming the flag.
  std::optional<grpc::Status> begin_watch();
  void end_watch();

  /// How the live calls that ended during a drain ended (counted from start_draining on):
  /// brought to rest (their motion at rest when they ended) or cut mid-motion (the drain
  /// time over, a second stop signal, the client gone).
  struct DrainedLive {
    int at_rest = 0;
    int cut = 0;
  };
  void live_ended_in_drain(bool at_rest) { (at_rest ? live_rested_ : live_cut_).fetch_add(1); }
  DrainedLive drained_live() const { return {live_rested_.load(), live_cut_.load()}; }

 private:
  friend class Call;
  const ServiceLimits limits_;
  const TokenTable tokens_;
  const Logger logger_;
  Metrics metrics_;
  std::atomic<bool> draining_{false};
  std::atomic<int> active_streams_{0};
  std::atomic<int> active_unary_{0};
  std::atomic<int> active_watches_{0};  // admitted ones are counted in active_streams_ too
  // The --max-streams slots taken: one per stream, more for a fast live call.
  std::atomic<int> stream_slots_{0};
  // The live calls' cycle rates in flight [Hz, each rounded up] (--max-live-rate-hz).
  std::atomic<std::int64_t> live_rate_hz_{0};
  std::atomic<int> live_rested_{0};
  std::atomic<int> live_cut_{0};
  WorkerPool pacing_;   // outlives the workers, which hand live calls to it
  WorkerPool workers_;  // last: its threads stop before the rest goes
};

/// One RPC from its admission to its end: takes a request id (the client's `x-request-id`
/// when valid, else a new one) and sends it back in the initial metadata; refuses the call
/// when the server drains, the token does not allow it, or the cap on calls in flight is
/// reached; on finish() records the metrics and writes the call's log line.
/// Metadata of a call from the web side (server/web): the HTTP client's address, logged as
/// the call's peer. Read only on calls that arrive in process, whose gRPC peer has no
/// address (a TCP client's peer is its own address, whatever metadata it sends).
inline constexpr std::string_view kWebPeerMetadata = "geotraj-web-peer";

class Call {
 public:
  Call(Runtime& runtime, grpc::CallbackServerContext& context, Method method);
  Call(Call&& other) noexcept;
  Call& operator=(Call&&) = delete;
  Call(const Call&) = delete;
  ~Call();

  /// Why the call is refused (and counted as rejected), or nullopt when admitted.
  const std::optional<grpc::Status>& refusal() const { return refusal_; }
  /// Records the end of the call with its final status; `samples` sent (streams).
  void finish(const grpc::Status& status, std::uint64_t samples = 0);

  /// Prices an admitted live call at its cycle rate `rate_hz` (again when it changes): it
  /// takes ceil(rate / kLiveRateUnitHz) --max-streams slots (at least the one it was
  /// admitted with) and its rate of --max-live-rate-hz. nullopt when that fits, else
  /// RESOURCE_EXHAUSTED naming the flag (the call keeps what it had).
  std::optional<grpc::Status> price_live(double rate_hz);

  const std::string& request_id() const { return request_id_; }
  Runtime& runtime() const { return *runtime_; }

 private:
  // Sets refusal_, or counts the call in flight (admitted_).
  void admit(const grpc::CallbackServerContext& context, bool streaming, std::string_view name);

  Runtime* runtime_;
  Method method_;
  std::string request_id_;
  std::string peer_;
  std::chrono::steady_clock::time_point started_;
  std::optional<grpc::Status> refusal_;
  bool admitted_ = false;  // counted in the runtime's calls in flight
  int slots_ = 0;                // --max-streams slots taken (streams)
  std::int64_t live_rate_hz_ = 0;  // of --max-live-rate-hz (live calls)
  bool finished_ = false;
};

}  // namespace geotraj::server
