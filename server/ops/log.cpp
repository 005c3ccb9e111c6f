#include "server/ops/log.hpp"

#include <grpc/support/log.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <ctime>
#include <mutex>
#include <optional>
#include <random>
#include <type_traits>

namespace geotraj::server {
namespace {

constexpr std::array<std::string_view, 4> kLevelNames = {"debug", "info", "warning", "error"};
constexpr std::array<std::string_view, 4> kTextLevelNames = {"DEBUG", "INFO", "WARNING", "ERROR"};

std::string_view level_name(LogLevel level, LogFormat format) {
  const auto index = static_cast<std::size_t>(level);
  return format == LogFormat::kJson ? kLevelNames[index] : kTextLevelNames[index];
}


void append_u00(std::string& out, unsigned char c) {
  static constexpr char kHex[] = "0123456789abcdef";
  out += "\\u00";
  out += kHex[c >> 4];
  out += kHex[c & 0xF];
}

// Escapes `s` for both formats: control characters always (\n, \r, \t short, others
// \u00XX, DEL included), quote and backslash when `quotes`, invalid UTF-8 as U+FFFD.
void append_escaped(std::string& out, std::string_view s, bool quotes) {
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x80) {
      if (quotes && (c == '"' || c == '\\')) {
        out += '\\';
        out += static_cast<char>(c);
      } else if (c == '\n') {
        out += "\\n";
      } else if (c == '\r') {
        out += "\\r";
      } else if (c == '\t') {
        out += "\\t";
      } else if (c < 0x20 || c == 0x7F) {
        append_u00(out, c);
      } else {
        out += static_cast<char>(c);
      }
      ++i;
      continue;
    }
    const std::size_t n = utf8_sequence(s, i);
    if (n == 0) {
      out += "\xEF\xBF\xBD";
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
  }
}

// Whether a text-format value needs quotes to stay one token.
bool needs_quotes(std::string_view s) {
  if (s.empty()) return true;
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c <= ' ' || c == '"' || c == '=' || c == '\\' || c == 0x7F) return true;
  }
  return false;
}

// Text format only (JSON numbers are nlohmann-json's).
void append_double(std::string& out, double value) {
  if (!std::isfinite(value)) {
    out += std::isnan(value) ? "NaN" : (value > 0 ? "+Inf" : "-Inf");
    return;
  }
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, result.ptr);
}

// UTC with milliseconds: 2026-11-30T16:40:01.123Z.
void append_timestamp(std::string& out) {
  const auto now = std::chrono::system_clock::now();
  const auto since_epoch = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch());
  const auto seconds = std::chrono::floor<std::chrono::seconds>(since_epoch);
  const std::time_t t = static_cast<std::time_t>(seconds.count());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buffer[40];
  const auto millis = static_cast<int>((since_epoch - seconds).count());
  const int n = std::snprintf(buffer, sizeof buffer, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                              tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, millis);
  if (n > 0) out.append(buffer, static_cast<std::size_t>(n));
}

// JSON lines through nlohmann-json: the envelope first (ordered_json keeps insertion order),
// strings escaped by the library (control characters as \u00XX), invalid UTF-8 replaced by
// U+FFFD (error_handler_t::replace), non-finite doubles written as null.
std::string format_json(LogLevel level, std::string_view message, const std::vector<LogField>& fields) {
  std::string ts;
  append_timestamp(ts);
  nlohmann::ordered_json line;
  line["ts"] = std::move(ts);
  line["level"] = level_name(level, LogFormat::kJson);
  line["msg"] = message;
  for (const auto& field : fields) {
    // The envelope's keys stay unique: a field cannot shadow ts, level or msg.
    const bool reserved = field.key == "ts" || field.key == "level" || field.key == "msg";
    std::visit([&](const auto& value) { line[reserved ? "_" + field.key : field.key] = value; }, field.value);
  }
  std::string out = line.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
  out += '\n';
  return out;
}

std::string format_text(LogLevel level, std::string_view message, const std::vector<LogField>& fields) {
  std::string out;
  append_timestamp(out);
  out += ' ';
  out += level_name(level, LogFormat::kText);
  out += ' ';
  append_escaped(out, message, false);
  for (const auto& field : fields) {
    out += ' ';
    // Keys are identifiers chosen in code; anything else would break key=value parsing.
    if (field.key.empty()) out += '_';
    for (const char c : field.key) {
      const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                         c == '.' || c == '-';
      out += plain ? c : '_';
    }
    out += '=';
    std::visit(
        [&out](const auto& value) {
          using T = std::decay_t<decltype(value)>;
          if constexpr (std::is_same_v<T, std::string>) {
            if (needs_quotes(value)) {
              out += '"';
              append_escaped(out, value, true);
              out += '"';
            } else {
              append_escaped(out, value, false);
            }
          } else if constexpr (std::is_same_v<T, bool>) {
            out += value ? "true" : "false";
          } else if constexpr (std::is_same_v<T, double>) {
            append_double(out, value);
          } else {
            out += std::to_string(value);
          }
        },
        field.value);
  }
  out += '\n';
  return out;
}

}  // namespace

tl::expected<LogFormat, std::string> parse_log_format(std::string_view text) {
  if (text == "text") return LogFormat::kText;
  if (text == "json") return LogFormat::kJson;
  return tl::make_unexpected("unknown log format \"" + std::string(text) + "\" (expected text or json)");
}

tl::expected<LogLevel, std::string> parse_log_level(std::string_view text) {
  for (std::size_t i = 0; i < kLevelNames.size(); ++i) {
    if (text == kLevelNames[i]) return static_cast<LogLevel>(i);
  }
  return tl::make_unexpected("unknown log level \"" + std::string(text) +
                             "\" (expected debug, info, warning or error)");
}

Logger::Logger(LogFormat format, LogLevel level, std::FILE* out) : format_(format), level_(level), out_(out) {}

bool Logger::enabled(LogLevel level) const { return level >= level_; }

void Logger::log(LogLevel level, std::string_view message, std::vector<LogField> fields) const {
  if (!enabled(level) || out_ == nullptr) return;
  for (auto& field : fields) {
    if (auto* text = std::get_if<std::string>(&field.value); text != nullptr && text->size() > kMaxLogValueBytes) {
      *text = truncated(*text, kMaxLogValueBytes);
    }
  }
  const std::string line =
      format_ == LogFormat::kJson ? format_json(level, message, fields) : format_text(level, message, fields);
  // One mutex for every logger: they may share a stream (stderr).
  static std::mutex mutex;
  const std::lock_guard lock(mutex);
  std::fwrite(line.data(), 1, line.size(), out_);
  std::fflush(out_);
}


namespace {

std::mutex grpc_log_mutex;
std::optional<Logger> grpc_logger;  // guarded by grpc_log_mutex
const Logger* grpc_logger_owner = nullptr;  // the logger grpc_logger copies

void grpc_log_line(gpr_log_func_args* args) {
  const std::lock_guard lock(grpc_log_mutex);
  if (!grpc_logger) {  // no server routes them: as gRPC itself writes them
    std::fprintf(stderr, "%s %s:%d] %s\n", gpr_log_severity_string(args->severity), args->file ? args->file : "?",
                 args->line, args->message ? args->message : "");
    return;
  }
  const LogLevel level = args->severity == GPR_LOG_SEVERITY_ERROR  ? LogLevel::kError
                         : args->severity == GPR_LOG_SEVERITY_INFO ? LogLevel::kInfo
                                                                   : LogLevel::kDebug;
  std::vector<LogField> fields{{"source", std::string("grpc")}};
  if (args->file != nullptr) fields.push_back({"at", std::string(args->file) + ":" + std::to_string(args->line)});
  grpc_logger->log(level, truncated(args->message != nullptr ? args->message : "", 4 * kMaxLogValueBytes),
                   std::move(fields));
}

}  // namespace

void route_grpc_logs(const Logger* logger) {
  {
    const std::lock_guard lock(grpc_log_mutex);
    if (logger != nullptr) {
      grpc_logger = *logger;
    } else {
      grpc_logger.reset();
    }
    grpc_logger_owner = logger;
  }
  gpr_set_log_function(grpc_log_line);  // stays: it writes to stderr when nothing is routed
}

void unroute_grpc_logs(const Logger& logger) {
  {
    const std::lock_guard lock(grpc_log_mutex);
    if (grpc_logger_owner != &logger) return;
  }
  route_grpc_logs(nullptr);
}

std::string new_request_id() {
  // One generator per thread: no lock, and random_device seeds each from the OS.
  thread_local std::mt19937_64 generator = [] {
    std::random_device device;
    std::seed_seq seed{device(), device(), device(), device()};
    return std::mt19937_64(seed);
  }();
  static constexpr char kHex[] = "0123456789abcdef";
  std::uint64_t bits = generator();
  std::string id(16, '0');
  for (int i = 15; i >= 0; --i) {
    id[static_cast<std::size_t>(i)] = kHex[bits & 0xF];
    bits >>= 4;
  }
  return id;
}

bool valid_request_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (const char c : id) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}


}  // namespace geotraj::server
