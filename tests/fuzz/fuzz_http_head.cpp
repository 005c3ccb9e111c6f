// fuzz_http_head: bytes as the head of a request to the metrics endpoint (what
// HttpExporter hands to cpp-httplib once a client's head has arrived, 8 KiB at most). Every
// input gets one well-formed response that closes the connection: a status line with a
// status the endpoint gives, headers, the empty line, and a body of the announced length
// (or none, for a HEAD); 200 only for a GET or HEAD of /metrics or /healthz.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <string>
#include <string_view>

#include "server/ops/http_exporter.hpp"

namespace {

[[noreturn]] void fail(const char* what, std::string_view response) {
  std::fprintf(stderr, "==== geotraj fuzz check failed: %s\n%.*s\n", what, static_cast<int>(response.size()),
               response.data());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 8192) return -1;  // the exporter answers a longer head 400 before it gets here
  static geotraj::server::HttpRoutes routes([] { return std::string("geotraj_up 1\n"); });
  const std::string_view head(reinterpret_cast<const char*>(data), size);
  const std::string response = routes.answer(head);

  if (!response.starts_with("HTTP/1.1 ") || response.size() < 12) fail("no status line", response);
  const int status = std::atoi(response.substr(9, 3).c_str());
  static const std::set<int> kStatuses = {200, 206, 400, 404, 405, 414, 416, 500};  // 206, 416: Range
  if (kStatuses.count(status) == 0) fail("a status the endpoint does not give", response);
  const std::size_t end = response.find("\r\n\r\n");
  if (end == std::string::npos) fail("no end of the headers", response);
  const std::string_view headers = std::string_view(response).substr(0, end + 2);
  if (headers.find("\r\nConnection: close\r\n") == std::string_view::npos) fail("the connection stays open", response);
  const std::size_t length_at = headers.find("\r\nContent-Length: ");
  if (length_at == std::string_view::npos) fail("no Content-Length", response);
  const std::size_t length = std::strtoul(response.c_str() + length_at + 18, nullptr, 10);
  const std::size_t body = response.size() - end - 4;
  // No body at all answers what cpp-httplib read as a HEAD (its request line parser skips
  // leading bytes that RFC 9112 would refuse, and the 400 that follows is sent bodiless).
  if (body != length && body != 0) fail("a body of another length than announced", response);
  if ((status == 200 || status == 206) && !(head.starts_with("GET /metrics") || head.starts_with("GET /healthz") ||
                         head.starts_with("HEAD /metrics") || head.starts_with("HEAD /healthz"))) {
    fail("200 for another request than a GET or HEAD of /metrics or /healthz", response);
  }
  return 0;
}
