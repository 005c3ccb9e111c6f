// Service metrics in the Prometheus text exposition format (0.0.4), with no client library:
// the service records calls, rejections, streamed samples and optimisation times here, and
// the HTTP exporter serves exposition() on /metrics.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace geotraj::server {

/// The version reported by geotraj_build_info (the project() version in CMakeLists.txt).
inline constexpr std::string_view kGeotrajVersion = GEOTRAJ_VERSION;

/// Counters, gauges and histograms of one geotrajd process. Every member function is
/// thread-safe: gauges and the sample counter are atomics (the streaming hot path takes no
/// lock); labelled series sit behind one mutex, held only to bump a few integers.
class Metrics {
 public:
  /// Records the process start time (process_start_time_seconds).
  Metrics();

  Metrics(const Metrics&) = delete;
  Metrics& operator=(const Metrics&) = delete;

  /// A call was accepted: raises geotraj_active_streams or geotraj_active_unary_calls.
  void call_started(std::string_view method, bool streaming);
  /// A call ended with `grpc_code` (a grpc::StatusCode; out-of-range values count as
  /// UNKNOWN) after `seconds`: lowers the gauge, counts geotraj_rpc_calls_total and
  /// observes geotraj_rpc_duration_seconds. Pair each call_started with one call_finished.
  void call_finished(std::string_view method, bool streaming, int grpc_code, double seconds);
  /// A call was refused before any work ("capacity", "draining", "unauthenticated",
  /// "permission_denied", "limit"; any string is accepted).
  void rejected(std::string_view method, std::string_view reason);
  /// A refused call (see rejected) ended with `grpc_code`: counted in geotraj_rpc_calls_total
  /// like every call, without a duration and without touching the gauges.
  void call_refused(std::string_view method, int grpc_code);
  /// A live call (Execute, Jog) ended its motion at rest for `reason` ("completed",
  /// "stopped", "deadman", "drain", "deadline", "invalid"): geotraj_live_stops_total.
  void live_stopped(std::string_view method, std::string_view reason);
  /// `count` more samples were written to streams (call once per batch).
  void samples_streamed(std::uint64_t count);
  /// One optimisation of `kind` ("tangent_scales", "breakpoints", "time_optimal",
  /// "time_optimal_jerk") took `seconds`.
  void optimization(std::string_view kind, double seconds);

  /// The TCP connections open on `listener` ("grpc", "health") now.
  void connections_open(std::string_view listener, std::int64_t open);
  /// A connection on `listener` was closed at once ("max_connections": the cap;
  /// "descriptors": the process has no descriptor left for it).
  void connection_refused(std::string_view listener, std::string_view reason);
  /// Where exposition() reads the calls waiting for a worker and the workers busy now.
  void set_worker_source(std::function<std::pair<std::int64_t, std::int64_t>()> source);

  /// Every family with # HELP and # TYPE. Labelled series appear once observed; the
  /// unlabelled counters and the gauges always appear. Deterministic order.
  std::string exposition() const;

 private:
  // Cumulative-on-print histogram: per-bucket counts (last one is +Inf), count and sum.
  struct Histogram {
    std::vector<std::uint64_t> buckets;
    std::uint64_t count = 0;
    double sum = 0.0;
  };
  static constexpr int kCodes = 17;  // grpc::StatusCode OK (0) .. UNAUTHENTICATED (16)

  // One more call of `method` ended with `grpc_code`; mutex_ is held.
  void count_call(std::string_view method, int grpc_code);
  void observe(Histogram& histogram, std::span<const double> bounds, double value);

  const double start_time_seconds_;
  std::atomic<std::int64_t> active_streams_{0};
  std::atomic<std::int64_t> active_unary_{0};
  std::atomic<std::uint64_t> samples_streamed_{0};

  mutable std::mutex mutex_;
  // Keyed by method / reason / kind; std::less<> finds string_view keys without allocating.
  std::map<std::string, std::array<std::uint64_t, kCodes>, std::less<>> calls_;
  std::map<std::string, Histogram, std::less<>> call_durations_;
  // Counts by method, then by reason (rejected, live_stopped); mutex_ is held.
  using Reasons = std::map<std::string, std::map<std::string, std::uint64_t, std::less<>>, std::less<>>;
  static void count_reason(Reasons& family, std::string_view method, std::string_view reason);
  Reasons rejected_;
  Reasons live_stops_;
  std::map<std::string, Histogram, std::less<>> optimization_durations_;
  std::map<std::string, std::int64_t, std::less<>> connections_open_;
  std::map<std::string, std::map<std::string, std::uint64_t, std::less<>>, std::less<>> connections_refused_;
  std::function<std::pair<std::int64_t, std::int64_t>()> worker_source_;
};

}  // namespace geotraj::server
