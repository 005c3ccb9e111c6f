#include "server/ops/metrics.hpp"

#include <span>

#include "server/ops/log.hpp"
#include "server/status_codes.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>

namespace geotraj::server {
namespace {

// Arrays, not vectors: nothing to destroy at exit, while a call in flight may still be
// counted (a process that exits with its server running, as the fuzz targets do).
// RPC latencies: 0.5 ms (ListRobots) to 60 s (long streams, deadline-bound optimisations).
constexpr std::array<double, 16> kRpcBounds = {0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1,
                                               0.25,   0.5,   1,      2.5,   5,    10,    30,    60};
// Optimisations: milliseconds (small time-optimal problems) to minutes (Ipopt, NLopt).
constexpr std::array<double, 16> kOptimizationBounds = {0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5,
                                                        1,     2.5,   5,    10,    30,    60,  120,  300};

// A label value as the text format wants it: backslash, quote and newline escaped; invalid
// UTF-8 (which scrapers reject) replaced by U+FFFD.
void append_label_value(std::string& out, std::string_view value) {
  for (std::size_t i = 0; i < value.size();) {
    const char c = value[i];
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      const std::size_t n = utf8_sequence(value, i);
      if (n == 0) {
        out += "\xEF\xBF\xBD";
        ++i;
        continue;
      }
      out.append(value.substr(i, n));
      i += n;
      continue;
    }
    ++i;
  }
}

// Shortest round-trip decimal, with the text format's spellings of the non-finite values.
void append_number(std::string& out, double value) {
  if (std::isnan(value)) {
    out += "NaN";
  } else if (std::isinf(value)) {
    out += value > 0 ? "+Inf" : "-Inf";
  } else {
    char buffer[32];
    const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
    out.append(buffer, result.ptr);
  }
}

void append_number(std::string& out, std::uint64_t value) { out += std::to_string(value); }
void append_number(std::string& out, std::int64_t value) { out += std::to_string(value); }

void append_header(std::string& out, std::string_view name, std::string_view type, std::string_view help) {
  out.append("# HELP ").append(name).append(" ").append(help).append("\n");
  out.append("# TYPE ").append(name).append(" ").append(type).append("\n");
}

// `name{labels} value` where `labels` is already formatted (without braces) or empty.
template <typename T>
void append_sample(std::string& out, std::string_view name, const std::string& labels, T value) {
  out.append(name);
  if (!labels.empty()) out.append("{").append(labels).append("}");
  out += ' ';
  append_number(out, value);
  out += '\n';
}

std::string label(std::string_view key, std::string_view value) {
  std::string out(key);
  out += "=\"";
  append_label_value(out, value);
  out += '"';
  return out;
}

}  // namespace

Metrics::Metrics()
    : start_time_seconds_(std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count()) {}

void Metrics::call_started(std::string_view /*method*/, bool streaming) {
  (streaming ? active_streams_ : active_unary_).fetch_add(1, std::memory_order_relaxed);
}

void Metrics::count_call(std::string_view method, int grpc_code) {
  const int code = grpc_code >= 0 && grpc_code < kCodes ? grpc_code : 2;  // else UNKNOWN
  auto calls = calls_.find(method);
  if (calls == calls_.end()) calls = calls_.emplace(std::string(method), std::array<std::uint64_t, kCodes>{}).first;
  ++calls->second[static_cast<std::size_t>(code)];
}

void Metrics::call_finished(std::string_view method, bool streaming, int grpc_code, double seconds) {
  {
    const std::lock_guard lock(mutex_);
    count_call(method, grpc_code);
    auto durations = call_durations_.find(method);
    if (durations == call_durations_.end()) durations = call_durations_.emplace(std::string(method), Histogram{}).first;
    observe(durations->second, kRpcBounds, seconds);
  }
  // Last: a scrape that sees the gauge back at 0 also sees the call counted.
  (streaming ? active_streams_ : active_unary_).fetch_sub(1, std::memory_order_release);
}

void Metrics::call_refused(std::string_view method, int grpc_code) {
  const std::lock_guard lock(mutex_);
  count_call(method, grpc_code);
}

void Metrics::count_reason(Reasons& family, std::string_view method, std::string_view reason) {
  auto by_method = family.find(method);
  if (by_method == family.end()) by_method = family.emplace(std::string(method), decltype(by_method->second){}).first;
  auto count = by_method->second.find(reason);
  if (count == by_method->second.end()) count = by_method->second.emplace(std::string(reason), 0).first;
  ++count->second;
}

void Metrics::rejected(std::string_view method, std::string_view reason) {
  const std::lock_guard lock(mutex_);
  count_reason(rejected_, method, reason);
}

void Metrics::live_stopped(std::string_view method, std::string_view reason) {
  const std::lock_guard lock(mutex_);
  count_reason(live_stops_, method, reason);
}

void Metrics::samples_streamed(std::uint64_t count) { samples_streamed_.fetch_add(count, std::memory_order_relaxed); }

void Metrics::optimization(std::string_view kind, double seconds) {
  const std::lock_guard lock(mutex_);
  auto durations = optimization_durations_.find(kind);
  if (durations == optimization_durations_.end()) {
    durations = optimization_durations_.emplace(std::string(kind), Histogram{}).first;
  }
  observe(durations->second, kOptimizationBounds, seconds);
}

void Metrics::observe(Histogram& histogram, std::span<const double> bounds, double value) {
  if (histogram.buckets.empty()) histogram.buckets.assign(bounds.size() + 1, 0);
  // A NaN or infinite time is a caller's bug; it would poison _sum for the life of the process.
  if (!std::isfinite(value)) return;
  value = std::max(value, 0.0);
  // Bucket `le` holds value <= le: the first bound not below the value.
  const auto index = static_cast<std::size_t>(std::lower_bound(bounds.begin(), bounds.end(), value) - bounds.begin());
  ++histogram.buckets[index];
  ++histogram.count;
  histogram.sum += value;
}

void Metrics::connections_open(std::string_view listener, std::int64_t open) {
  const std::lock_guard lock(mutex_);
  auto it = connections_open_.find(listener);
  if (it == connections_open_.end()) it = connections_open_.emplace(std::string(listener), 0).first;
  it->second = open;
}

void Metrics::connection_refused(std::string_view listener, std::string_view reason) {
  const std::lock_guard lock(mutex_);
  auto it = connections_refused_.find(listener);
  if (it == connections_refused_.end()) it = connections_refused_.emplace(std::string(listener), decltype(it->second){}).first;
  auto r = it->second.find(reason);
  if (r == it->second.end()) r = it->second.emplace(std::string(reason), 0).first;
  ++r->second;
}

void Metrics::set_worker_source(std::function<std::pair<std::int64_t, std::int64_t>()> source) {
  const std::lock_guard lock(mutex_);
  worker_source_ = std::move(source);
}

std::string Metrics::exposition() const {
  std::string out;
  out.reserve(8192);

  const auto histogram_family = [&out](std::string_view name, std::string_view label_key,
                                       const std::map<std::string, Histogram, std::less<>>& series,
                                       std::span<const double> bounds) {
    const std::string bucket = std::string(name) + "_bucket";
    for (const auto& [key, histogram] : series) {
      if (histogram.buckets.empty()) continue;
      const std::string labels = label(label_key, key);
      std::uint64_t cumulative = 0;
      for (std::size_t i = 0; i < histogram.buckets.size(); ++i) {
        cumulative += histogram.buckets[i];
        // Bounds in plain decimal ("0.0005", not "5e-04"), as the client libraries print them.
        std::string le = "+Inf";
        if (i < bounds.size()) {
          char buffer[32];
          const auto result = std::to_chars(buffer, buffer + sizeof buffer, bounds[i], std::chars_format::fixed);
          le.assign(buffer, result.ptr);
        }
        append_sample(out, bucket, labels + "," + label("le", le), cumulative);
      }
      append_sample(out, std::string(name) + "_sum", labels, histogram.sum);
      append_sample(out, std::string(name) + "_count", labels, histogram.count);
    }
  };

  {
    const std::lock_guard lock(mutex_);

    append_header(out, "geotraj_rpc_calls_total", "counter", "RPCs finished, by method and gRPC status code.");
    for (const auto& [method, counts] : calls_) {
      for (std::size_t code = 0; code < counts.size(); ++code) {
        if (counts[code] == 0) continue;
        append_sample(out, "geotraj_rpc_calls_total", label("method", method) + "," + label("code", status_code_name(static_cast<grpc::StatusCode>(code))),
                      counts[code]);
      }
    }

    append_header(out, "geotraj_rpc_duration_seconds", "histogram", "Time from the start to the end of an RPC.");
    histogram_family("geotraj_rpc_duration_seconds", "method", call_durations_, kRpcBounds);

    append_header(out, "geotraj_rpc_rejected_total", "counter",
                  "RPCs refused before any work (reason: capacity, draining, unauthenticated, permission_denied).");
    for (const auto& [method, reasons] : rejected_) {
      for (const auto& [reason, count] : reasons) {
        append_sample(out, "geotraj_rpc_rejected_total", label("method", method) + "," + label("reason", reason),
                      count);
      }
    }

    append_header(out, "geotraj_live_stops_total", "counter",
                  "Live calls (Execute, Jog) whose motion ended at rest, by reason (completed, stopped, deadman, "
                  "drain, deadline, invalid).");
    for (const auto& [method, reasons] : live_stops_) {
      for (const auto& [reason, count] : reasons) {
        append_sample(out, "geotraj_live_stops_total", label("method", method) + "," + label("reason", reason), count);
      }
    }

    append_header(out, "geotraj_optimization_duration_seconds", "histogram", "Time spent in one optimisation, by kind.");
    histogram_family("geotraj_optimization_duration_seconds", "kind", optimization_durations_, kOptimizationBounds);

    append_header(out, "geotraj_connections", "gauge", "TCP connections open, by listening port (grpc, health).");
    for (const auto& [listener, open] : connections_open_) {
      append_sample(out, "geotraj_connections", label("listener", listener), open);
    }
    append_header(out, "geotraj_connections_refused_total", "counter",
                  "TCP connections closed by the server (reason: max_connections and descriptors, on arrival; idle, silent ones shut down at the cap).");
    for (const auto& [listener, reasons] : connections_refused_) {
      for (const auto& [reason, count] : reasons) {
        append_sample(out, "geotraj_connections_refused_total", label("listener", listener) + "," + label("reason", reason),
                      count);
      }
    }
    if (worker_source_) {
      const auto [queued, busy] = worker_source_();
      append_header(out, "geotraj_queued_calls", "gauge", "Calls admitted and waiting for a worker thread.");
      append_sample(out, "geotraj_queued_calls", {}, queued);
      append_header(out, "geotraj_busy_workers", "gauge", "Worker threads running a call now.");
      append_sample(out, "geotraj_busy_workers", {}, busy);
    }
  }

  append_header(out, "geotraj_active_streams", "gauge", "Server-streaming RPCs in progress.");
  append_sample(out, "geotraj_active_streams", {}, active_streams_.load(std::memory_order_acquire));
  append_header(out, "geotraj_active_unary_calls", "gauge", "Unary RPCs in progress.");
  append_sample(out, "geotraj_active_unary_calls", {}, active_unary_.load(std::memory_order_acquire));
  append_header(out, "geotraj_samples_streamed_total", "counter", "Trajectory samples written to StreamSamples streams.");
  append_sample(out, "geotraj_samples_streamed_total", {}, samples_streamed_.load(std::memory_order_relaxed));
  append_header(out, "geotraj_build_info", "gauge", "Always 1; the version of geotrajd is a label.");
  append_sample(out, "geotraj_build_info", label("version", kGeotrajVersion), std::int64_t{1});
  append_header(out, "process_start_time_seconds", "gauge", "Start time of the process since the Unix epoch in seconds.");
  append_sample(out, "process_start_time_seconds", {}, start_time_seconds_);
  return out;
}

}  // namespace geotraj::server
