// What the gateway's HTTP side shares, private to server/web: the answers' content types and
// headers, proto JSON in and out, the call metadata taken from a request, request paths.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include <boost/beast/http.hpp>
#include <google/protobuf/message.h>
#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>
#include <grpcpp/support/status.h>

#include "core/error.hpp"
#include "server/wire/status.hpp"
#include "server/wire/text.hpp"

namespace geotraj::server::web_detail {

namespace pbu = google::protobuf::util;
namespace http = boost::beast::http;
using Request = http::request<http::string_body>;
using Response = http::response<http::string_body>;

// No compression of the API's answers or the page's files: the page is served on loopback
// or a LAN, where compressing a 200 kB analysis costs more than sending it.
inline constexpr const char* kJson = "application/json; charset=utf-8";
inline constexpr const char* kNdjson = "application/x-ndjson";
inline constexpr const char* kText = "text/plain; charset=utf-8";
// What a parse error of the body may add to its status message.
inline constexpr std::size_t kMaxParseErrorBytes = 512;

// Proto3 JSON: lowerCamelCase names, enums by name, fields at their default left out (as
// grpcurl and the other proto3 JSON printers write them), 64-bit integers as strings.
std::string to_json(const google::protobuf::Message& message);

// The request in `body`, or INVALID_ARGUMENT naming what is wrong with it. Unknown fields
// are refused (a misspelt field would otherwise be a silent default).
template <class Message>
std::optional<grpc::Status> parse_body(const std::string& body, Message& message) {
  const std::string name = Message::descriptor()->full_name();
  if (body.find_first_not_of(" \t\r\n") == std::string::npos) {
    return invalid_argument(core::Violations{{"", "the request body is empty: send a " + name + " in proto JSON"}});
  }
  // JSON is UTF-8 (RFC 8259), and protobuf's JSON parser lets invalid bytes through into
  // string fields (its binary parser refuses them): a robot name of such bytes would come
  // back in an error message no client could decode.
  for (std::size_t i = 0; i < body.size();) {
    const std::size_t n = utf8_sequence(body, i);
    if (n == 0) {
      return invalid_argument(core::Violations{
          {"", "the request body is not valid UTF-8 (byte " + std::to_string(i) + "): JSON text is UTF-8"}});
    }
    i += n;
  }
  pbu::JsonParseOptions options;
  options.ignore_unknown_fields = false;
  if (const auto parsed = pbu::JsonStringToMessage(body, &message, options); !parsed.ok()) {
    return invalid_argument(core::Violations{
        {"", "the request body is not a " + name + " in proto JSON: " +
                 truncated(std::string(parsed.message()), kMaxParseErrorBytes)}});
  }
  return std::nullopt;
}

// The HTTP request's bearer token and request id become the call's metadata, checked and
// logged by the service as a gRPC client's would be; the HTTP client's address is logged
// as the call's peer (the service honours it on in-process calls only). A request id the
// service would not take (the rule of valid_request_id) is left out: the call gets its own,
// as a gRPC call with such an id does. An Authorization header gRPC cannot carry is
// refused (INVALID_ARGUMENT naming it).
std::optional<grpc::Status> pass_on(const Request& req, const std::string& peer, grpc::ClientContext& context);

// The call's request id (in its initial metadata, or its trailers when it was refused).
std::string request_id_of(const grpc::ClientContext& context, bool trailers_too);

// Headers of every answer.
template <class Fields>
void decorate(Fields& fields) {
  fields.set(http::field::server, "geotrajd");
  fields.set("X-Content-Type-Options", "nosniff");
  fields.set("Referrer-Policy", "no-referrer");
  // The page loads its own files only and talks to this server only.
  fields.set("Content-Security-Policy",
             "default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "
             "connect-src 'self'; worker-src 'self' blob:; frame-ancestors 'none'; base-uri 'none'; form-action "
             "'none'");
}

Response answer(unsigned status, std::string body, const char* type);

Response status_answer(const grpc::Status& status, const std::string& request_id = {});

// A route's wrong method: 405 with the methods it takes.
Response wrong_method(const char* allow);

// The path of a request target: its query left out, %XX decoded. Empty when the target is
// not an origin form, an escape is malformed, or it holds a NUL (raw or %00): such a path
// names no file, and a NUL would cut it short where a C string is made of it.
std::optional<std::string> decoded_path(std::string_view target);

bool is_api(std::string_view path);

// The content type of a file of the page, by its extension.
const char* content_type(const std::filesystem::path& file);

}  // namespace geotraj::server::web_detail
