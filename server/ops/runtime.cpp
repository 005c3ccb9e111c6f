#include "server/ops/runtime.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>

#include <grpcpp/server_context.h>

#include "server/status_codes.hpp"
#include "server/wire/text.hpp"

namespace geotraj::server {
namespace {

constexpr std::string_view kBearer = "bearer ";

// Equal strings, in a time that depends on the lengths only (no early exit on the first
// differing byte, so response times do not reveal a token's prefix).
bool constant_time_equal(std::string_view a, std::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const std::size_t n = std::min(a.size(), b.size());
  for (std::size_t i = 0; i < n; ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

bool token_char(char c) { return c > ' ' && c < 127; }

// A rate [Hz] as a message shows it: whole numbers without a fraction.
std::string format_hz(double rate) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", rate);
  return text;
}

// The scope a method needs.
std::string_view scope_of(Method method) {
  switch (method) {
    case Method::kStreamSamples: return "stream";
    case Method::kExecute:
    case Method::kJog: return "move";
    default: return "plan";
  }
}

bool allows(const TokenScopes& scopes, Method method) {
  const std::string_view scope = scope_of(method);
  return scope == "stream" ? scopes.stream : scope == "move" ? scopes.move : scopes.plan;
}

}  // namespace

std::string_view method_name(Method method) {
  switch (method) {
    case Method::kConvertConstraints: return "ConvertConstraints";
    case Method::kPlanTrajectory: return "PlanTrajectory";
    case Method::kStreamSamples: return "StreamSamples";
    case Method::kAnalyzePath: return "AnalyzePath";
    case Method::kListRobots: return "ListRobots";
    case Method::kComputeForwardKinematics: return "ComputeForwardKinematics";
    case Method::kComputeInverseKinematics: return "ComputeInverseKinematics";
    case Method::kExecute: return "Execute";
    case Method::kJog: return "Jog";
  }
  return "unknown";
}

bool is_streaming(Method method) {
  return method == Method::kStreamSamples || method == Method::kExecute || method == Method::kJog;
}

tl::expected<void, std::string> TokenTable::add(std::string token, TokenScopes scopes, const std::string& origin) {
  if (token.size() < 16) return tl::unexpected(origin + ": a token must have at least 16 characters");
  for (char c : token) {
    if (!token_char(c)) return tl::unexpected(origin + ": a token may hold printable ASCII characters only");
  }
  tokens_.push_back({std::move(token), scopes});
  return {};
}

tl::expected<TokenTable, std::string> TokenTable::from_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return tl::unexpected("cannot read the tokens file \"" + path + "\"");
  TokenTable table;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream fields(line);
    std::string token, scope_list, extra;
    if (!(fields >> token) || token.front() == '#') continue;
    const std::string where = "tokens file \"" + path + "\" line " + std::to_string(number);
    TokenScopes scopes{true, true, true};
    if (fields >> scope_list) {
      scopes = {};
      std::istringstream names(scope_list);
      for (std::string name; std::getline(names, name, ',');) {
        if (name == "plan") {
          scopes.plan = true;
        } else if (name == "stream") {
          scopes.stream = true;
        } else if (name == "move") {
          scopes.move = true;
        } else {
          return tl::unexpected(where + ": unknown scope \"" + name +
                                "\" (use plan, stream, move or a list of them: plan,stream)");
        }
      }
    }
    if (fields >> extra) return tl::unexpected(where + ": expected `TOKEN [SCOPES]`, found more fields");
    if (auto added = table.add(std::move(token), scopes, where); !added) return tl::unexpected(added.error());
  }
  if (table.empty()) return tl::unexpected("the tokens file \"" + path + "\" holds no token");
  return table;
}

std::optional<grpc::Status> TokenTable::check(const grpc::CallbackServerContext& context, Method method) const {
  if (tokens_.empty()) return std::nullopt;
  const auto& metadata = context.client_metadata();
  const auto header = metadata.find("authorization");
  if (header == metadata.end()) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                        "this server needs a bearer token: send the metadata `authorization: Bearer <token>`");
  }
  const std::string_view value(header->second.data(), header->second.size());
  std::string scheme(value.substr(0, std::min(value.size(), kBearer.size())));
  for (auto& c : scheme) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (scheme != kBearer) {
    return grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                        "the `authorization` metadata must be `Bearer <token>`");
  }
  const std::string_view token = value.substr(kBearer.size());
  const Entry* match = nullptr;
  for (const auto& entry : tokens_) {
    if (constant_time_equal(entry.token, token)) match = &entry;
  }
  if (match == nullptr) return grpc::Status(grpc::StatusCode::UNAUTHENTICATED, "the bearer token is not valid");
  if (!allows(match->scopes, method)) {
    return grpc::Status(grpc::StatusCode::PERMISSION_DENIED, "this token may not call " +
                                                                 std::string(method_name(method)) +
                                                                 ": it needs the scope `" + std::string(scope_of(method)) + "`");
  }
  return std::nullopt;
}

Runtime::Runtime(ServiceLimits limits, TokenTable tokens, Logger logger)
    : limits_(limits),
      tokens_(std::move(tokens)),
      logger_(std::move(logger)),
      pacing_(std::max(1, limits.pacing_threads), 0, /*nice=*/0),
      workers_(limits.workers > 0 ? limits.workers : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))) {}

std::optional<grpc::Status> Runtime::begin_watch() {
  if (draining()) return grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is shutting down");
  if (active_watches_.fetch_add(1) >= limits_.max_health_watches) {
    active_watches_.fetch_sub(1);
    metrics_.rejected("Health.Watch", "capacity");
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "the server has " + std::to_string(limits_.max_health_watches) +
                            " health watches in flight, its limit (geotrajd --max-health-watches): retry later");
  }
  if (stream_slots_.fetch_add(1) >= limits_.max_streams) {
    active_watches_.fetch_sub(1);
    stream_slots_.fetch_sub(1);
    metrics_.rejected("Health.Watch", "capacity");
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "the server has " + std::to_string(limits_.max_streams) +
                            " stream slots taken, health watches included, its limit (geotrajd --max-streams): retry later");
  }
  active_streams_.fetch_add(1);
  return std::nullopt;
}

void Runtime::end_watch() {
  active_watches_.fetch_sub(1);
  active_streams_.fetch_sub(1);
  stream_slots_.fetch_sub(1);
}

Call::Call(Runtime& runtime, grpc::CallbackServerContext& context, Method method)
    : runtime_(&runtime), method_(method), peer_(context.peer()), started_(std::chrono::steady_clock::now()) {
  const auto& metadata = context.client_metadata();
  // In process (the web side): no address of its own ("ipv4:...", "unix:..." have one).
  if (peer_.find(':') == std::string::npos) {
    if (const auto web = metadata.find(std::string(kWebPeerMetadata)); web != metadata.end()) {
      peer_ = "web:" + truncated(std::string_view(web->second.data(), web->second.size()), 64);
    }
  }
  const auto given = metadata.find("x-request-id");
  if (given != metadata.end() && valid_request_id(std::string_view(given->second.data(), given->second.size()))) {
    request_id_.assign(given->second.data(), given->second.size());
  } else {
    request_id_ = new_request_id();
  }
  const bool streaming = is_streaming(method);
  const auto name = method_name(method);
  admit(context, streaming, name);
  // A refusal is answered with trailers only (no initial metadata), so that a client may
  // retry it transparently elsewhere (UNAVAILABLE while draining); the id goes with it.
  if (refusal_) {
    context.AddTrailingMetadata("x-request-id", request_id_);
  } else {
    context.AddInitialMetadata("x-request-id", request_id_);
  }
}

void Call::admit(const grpc::CallbackServerContext& context, bool streaming, std::string_view name) {
  Runtime& runtime = *runtime_;
  if (runtime.draining()) {
    runtime.metrics().rejected(name, "draining");
    refusal_ = grpc::Status(grpc::StatusCode::UNAVAILABLE, "the server is shutting down: retry on another replica");
    return;
  }
  if (auto denied = runtime.tokens().check(context, method_)) {
    runtime.metrics().rejected(
        name, denied->error_code() == grpc::StatusCode::PERMISSION_DENIED ? "permission_denied" : "unauthenticated");
    refusal_ = std::move(denied);
    return;
  }
  // Streams take slots of --max-streams (a fast live call more than one, price_live).
  auto& taken = streaming ? runtime.stream_slots_ : runtime.active_unary_;
  const int cap = streaming ? runtime.limits().max_streams : runtime.limits().max_unary_calls;
  if (taken.fetch_add(1) >= cap) {
    taken.fetch_sub(1);
    runtime.metrics().rejected(name, "capacity");
    refusal_ = grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                            "the server has " + std::to_string(cap) + (streaming ? " stream slots taken" : " unary calls in flight") +
                                ", its limit (geotrajd " +
                                (streaming ? "--max-streams" : "--max-unary-calls") + "): retry later");
    return;
  }
  if (streaming) {
    runtime.active_streams_.fetch_add(1);
    slots_ = 1;
  }
  admitted_ = true;
  runtime.metrics().call_started(name, streaming);
}

Call::Call(Call&& other) noexcept
    : runtime_(other.runtime_),
      method_(other.method_),
      request_id_(std::move(other.request_id_)),
      peer_(std::move(other.peer_)),
      started_(other.started_),
      refusal_(std::move(other.refusal_)),
      admitted_(other.admitted_),
      slots_(other.slots_),
      live_rate_hz_(other.live_rate_hz_),
      finished_(other.finished_) {
  other.admitted_ = false;
  other.finished_ = true;
}

Call::~Call() {
  if (!finished_) finish(grpc::Status(grpc::StatusCode::CANCELLED, "the call ended without a status"));
}

void Call::finish(const grpc::Status& status, std::uint64_t samples) {
  if (finished_) return;
  finished_ = true;
  const bool streaming = is_streaming(method_);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  const auto name = method_name(method_);
  // The log line first: a drain waits for the count of calls in flight, so the call must be
  // written down before it stops counting.
  const auto& logger = runtime_->logger();
  const bool server_fault = status.error_code() == grpc::StatusCode::INTERNAL ||
                            status.error_code() == grpc::StatusCode::UNKNOWN ||
                            status.error_code() == grpc::StatusCode::DATA_LOSS;
  const LogLevel level = server_fault ? LogLevel::kError : LogLevel::kInfo;
  if (logger.enabled(level)) {
    std::vector<LogField> fields{{"request_id", request_id_},
                                 {"method", std::string(name)},
                                 {"peer", peer_},
                                 {"code", std::string(status_code_name(status.error_code()))},
                                 {"duration_ms", std::round(seconds * 1e6) / 1e3}};  // to the microsecond
    if (streaming) fields.push_back({"samples", static_cast<std::int64_t>(samples)});
    if (!status.ok()) fields.push_back({"error", status.error_message()});
    logger.log(level, "call", std::move(fields));
  }
  if (admitted_) {
    runtime_->metrics().call_finished(name, streaming, static_cast<int>(status.error_code()), seconds);
    if (streaming) {
      runtime_->stream_slots_.fetch_sub(slots_);
      runtime_->live_rate_hz_.fetch_sub(live_rate_hz_);
      runtime_->active_streams_.fetch_sub(1);
    } else {
      runtime_->active_unary_.fetch_sub(1);
    }
  } else {
    runtime_->metrics().call_refused(name, static_cast<int>(status.error_code()));
  }
}

std::optional<grpc::Status> Call::price_live(double rate_hz) {
  if (!admitted_ || finished_) return std::nullopt;
  Runtime& runtime = *runtime_;
  const double rate = std::isfinite(rate_hz) ? std::clamp(rate_hz, 0.0, 1e12) : 1e12;
  const int slots = static_cast<int>(std::clamp(std::ceil(rate / kLiveRateUnitHz), 1.0, 1e9));
  const auto hz = static_cast<std::int64_t>(std::ceil(rate));
  const auto name = method_name(method_);
  const int more_slots = slots - slots_;
  if (more_slots > 0) {
    const int cap = runtime.limits().max_streams;
    const int before = runtime.stream_slots_.fetch_add(more_slots);
    if (before + more_slots > cap) {
      runtime.stream_slots_.fetch_sub(more_slots);
      runtime.metrics().rejected(name, "live_rate");
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "a live call at " + format_hz(rate_hz) + " Hz takes " + std::to_string(slots) +
                              " of the server's " + std::to_string(cap) + " stream slots (one per " +
                              format_hz(kLiveRateUnitHz) + " Hz or part of it) and " +
                              std::to_string(std::max(0, before - slots_)) +
                              " are taken by other calls (geotrajd --max-streams): retry later or lower the cycle rate");
    }
  } else if (more_slots < 0) {
    runtime.stream_slots_.fetch_add(more_slots);
  }
  const std::int64_t more_hz = hz - live_rate_hz_;
  const double budget = runtime.limits().max_live_rate_hz;
  const std::int64_t before_hz = runtime.live_rate_hz_.fetch_add(more_hz);
  if (more_hz > 0 && static_cast<double>(before_hz + more_hz) > budget) {
    runtime.live_rate_hz_.fetch_sub(more_hz);
    runtime.stream_slots_.fetch_sub(more_slots);
    runtime.metrics().rejected(name, "live_rate");
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "the live calls in flight make " + std::to_string(std::max<std::int64_t>(0, before_hz - live_rate_hz_)) +
                            " set points per second; this call's " + format_hz(rate_hz) +
                            " Hz would pass the server's budget of " + format_hz(budget) +
                            " (geotrajd --max-live-rate-hz): retry later or lower the cycle rate");
  }
  slots_ = slots;
  live_rate_hz_ = hz;
  return std::nullopt;
}

}  // namespace geotraj::server
