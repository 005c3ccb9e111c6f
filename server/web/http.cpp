// The gateway's HTTP side (http.hpp): proto JSON out, the call metadata taken from a request,
// the answers, request paths and the page's content types.
#include "server/web/http.hpp"

#include <algorithm>
#include <utility>

#include "server/ops/log.hpp"
#include "server/ops/runtime.hpp"
#include "server/web/gateway.hpp"

namespace geotraj::server::web_detail {
namespace {

// The longest Authorization header passed on: a bearer token is far shorter.
constexpr std::size_t kMaxAuthorizationBytes = 4096;

// Whether gRPC can carry `value` as the value of an ASCII metadata key: printable ASCII
// only (0x20-0x7e). gRPC asserts, and the process aborts, on any other byte (a tab, a
// control byte, UTF-8), so nothing a client sends reaches metadata unchecked.
bool metadata_safe(std::string_view value) {
  return std::all_of(value.begin(), value.end(), [](char c) { return c >= 0x20 && c <= 0x7e; });
}

}  // namespace

std::string to_json(const google::protobuf::Message& message) {
  std::string out;
  (void)pbu::MessageToJsonString(message, &out, pbu::JsonPrintOptions{});
  return out;
}

std::optional<grpc::Status> pass_on(const Request& req, const std::string& peer, grpc::ClientContext& context) {
  if (const auto auth = req.find(http::field::authorization); auth != req.end()) {
    const std::string_view value(auth->value().data(), auth->value().size());
    if (value.size() > kMaxAuthorizationBytes) {
      return invalid_argument(core::Violations{
          {"", "the Authorization header has " + std::to_string(value.size()) + " bytes, more than " +
                   std::to_string(kMaxAuthorizationBytes) + ": send \"Bearer <token>\""}});
    }
    if (!metadata_safe(value)) {
      return invalid_argument(core::Violations{
          {"", "the Authorization header holds a byte that is not printable ASCII (a tab, a control byte or a "
               "non-ASCII byte): send \"Bearer <token>\""}});
    }
    context.AddMetadata("authorization", std::string(value));
  }
  if (const auto id = req.find("X-Request-Id"); id != req.end()) {
    const std::string_view value(id->value().data(), id->value().size());
    if (valid_request_id(value)) context.AddMetadata("x-request-id", std::string(value));
  }
  if (metadata_safe(peer)) context.AddMetadata(std::string(kWebPeerMetadata), peer);
  return std::nullopt;
}

std::string request_id_of(const grpc::ClientContext& context, bool trailers_too) {
  const auto& initial = context.GetServerInitialMetadata();
  if (const auto id = initial.find("x-request-id"); id != initial.end()) {
    return std::string(id->second.data(), id->second.size());
  }
  if (trailers_too) {
    const auto& trailing = context.GetServerTrailingMetadata();
    if (const auto id = trailing.find("x-request-id"); id != trailing.end()) {
      return std::string(id->second.data(), id->second.size());
    }
  }
  return {};
}

Response answer(unsigned status, std::string body, const char* type) {
  Response res{static_cast<http::status>(status), 11};
  decorate(res);
  res.set(http::field::content_type, type);
  res.body() = std::move(body);
  return res;
}

Response status_answer(const grpc::Status& status, const std::string& request_id) {
  auto res = answer(static_cast<unsigned>(http_status(status.error_code())), status_json(status), kJson);
  if (!request_id.empty()) res.set("X-Request-Id", request_id);
  return res;
}

Response wrong_method(const char* allow) {
  auto res = status_answer(
      grpc::Status(grpc::StatusCode::UNIMPLEMENTED, std::string("this route takes ") + allow + " only"));
  res.result(http::status::method_not_allowed);
  res.set(http::field::allow, allow);
  return res;
}

std::optional<std::string> decoded_path(std::string_view target) {
  if (target.empty() || target.front() != '/') return std::nullopt;
  target = target.substr(0, target.find_first_of("?#"));
  std::string out;
  out.reserve(target.size());
  const auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (std::size_t i = 0; i < target.size(); ++i) {
    char c = target[i];
    if (c == '%') {
      if (i + 2 >= target.size()) return std::nullopt;
      const int hi = hex(target[i + 1]);
      const int lo = hex(target[i + 2]);
      if (hi < 0 || lo < 0) return std::nullopt;
      c = static_cast<char>(hi * 16 + lo);
      i += 2;
    }
    if (c == '\0') return std::nullopt;
    out.push_back(c);
  }
  return out;
}

bool is_api(std::string_view path) { return path.starts_with("/v1/") || path == "/v1"; }

const char* content_type(const std::filesystem::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".html" || ext == ".htm") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "application/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json" || ext == ".map") return "application/json";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".ico") return "image/x-icon";
  if (ext == ".wasm") return "application/wasm";
  if (ext == ".txt") return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

}  // namespace geotraj::server::web_detail
