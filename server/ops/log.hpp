// Structured logging for geotrajd: one line per event, as text for people or as JSON for log
// pipelines, and the request ids that tie a call's lines together.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <tl/expected.hpp>

#include "server/wire/text.hpp"

namespace geotraj::server {

enum class LogFormat { kText, kJson };
enum class LogLevel { kDebug, kInfo, kWarning, kError };

/// "text" or "json"; otherwise a sentence naming the value and the choices.
tl::expected<LogFormat, std::string> parse_log_format(std::string_view text);
/// "debug", "info", "warning" or "error"; otherwise a sentence naming the value and the choices.
tl::expected<LogLevel, std::string> parse_log_level(std::string_view text);

/// One key/value of an event.
struct LogField {
  std::string key;
  std::variant<std::string, std::int64_t, double, bool> value;
};

/// Writes events at or above a level to a stream. Thread-safe: each event is formatted
/// first, then written with one fwrite under a process-wide mutex and flushed, so lines
/// never interleave (not even those of two loggers on one stream). Copyable and movable.
///
/// JSON (written by nlohmann-json): {"ts":"2026-11-30T16:40:01.123Z","level":"info","msg":"...",
/// <fields>} with strings escaped (control characters below U+0020 as \u00XX, valid UTF-8
/// passed through, invalid bytes as U+FFFD) and non-finite doubles as null; a field named ts, level or msg is written as
/// _ts, _level or _msg so keys stay unique.
/// Text: 2026-11-30T16:40:01.123Z INFO msg key=value key2="quoted value"; the message has
/// control characters escaped; values with spaces, quotes, '=' or control characters (and
/// empty ones) are quoted with backslash escapes.
class Logger {
 public:
  Logger(LogFormat format, LogLevel level, std::FILE* out = stderr);

  void log(LogLevel level, std::string_view message, std::vector<LogField> fields = {}) const;
  /// Whether log(level, ...) writes anything: lets callers skip building costly fields.
  bool enabled(LogLevel level) const;

 private:
  LogFormat format_;
  LogLevel level_;
  std::FILE* out_;
};

/// 16 lowercase hex characters (64 random bits) for a call without a usable x-request-id.
/// Thread-safe: each thread has its own generator seeded from std::random_device.
std::string new_request_id();
/// Whether a client's x-request-id can be logged as is: 1 to 64 characters of [A-Za-z0-9._-].
bool valid_request_id(std::string_view id);

/// Longest value of a string field in a log line [bytes]: a client's 1 MB robot name stays
/// a short line (log.cpp).
inline constexpr std::size_t kMaxLogValueBytes = 512;

/// Sends gRPC core's own log lines (gpr_log) through `logger`, in its format, so that a JSON
/// log holds JSON lines only; their severity maps to debug, info and error. Process-wide: the
/// last logger given wins; nullptr writes them to stderr as gRPC does.
void route_grpc_logs(const Logger* logger);
/// Restores gRPC's default when `logger` is the one routed to (a server that stops: its
/// stream may be closed after it).
void unroute_grpc_logs(const Logger& logger);

}  // namespace geotraj::server
