// fuzz_web: bytes as what one client sends on a connection to the web side
// (--web-address) of a server started once in this process: request lines, headers and
// bodies (several, when the input holds several). Boost.Beast
// parses them, the gateway parses the JSON bodies and calls the service in process. Every
// input must leave the server serving, and what comes back must be HTTP/1.1 answers whose
// JSON carries no NaN or Infinity; an error of the API must be a google.rpc.Status in JSON
// whose code is one that bad input may get (not UNKNOWN, INTERNAL or DATA_LOSS: an
// exception in a handler is answered INTERNAL, and is a bug).
//
// The server's limits keep one input short: 2 s per call, 1001 analysis points, 20000
// streamed samples, 1 s of optimisation, 1 MiB of body, 200 ms of silence in a request,
// 1 s for a head and 2 s for a whole request.
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <string_view>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <google/protobuf/util/json_util.h>

#include "google/rpc/status.pb.h"
#include "server/server.hpp"
#include "server/web/gateway.hpp"

namespace {

[[noreturn]] void fail(const char* what, std::string_view input, std::string_view answer) {
  std::fprintf(stderr, "==== geotraj fuzz check failed: %s\n---- input (%zu bytes)\n%.*s\n---- answer\n%.*s\n", what,
               input.size(), static_cast<int>(std::min<std::size_t>(input.size(), 2000)), input.data(),
               static_cast<int>(std::min<std::size_t>(answer.size(), 2000)), answer.data());
  std::abort();
}

// The server (in process only) and its web side, started once. The web side's idle
// timeout is short: an input that ends within a request (most mutations do) is closed by
// the server 200 ms later instead of 5 s.
struct Web {
  geotraj::server::RunningServer running;
  std::unique_ptr<geotraj::server::WebGateway> gateway;
};

Web& web() {
  static Web instance = [] {
    geotraj::server::ServerOptions options;
    options.address = "";
    options.log_level = "error";
    options.limits.default_deadline_s = 2.0;
    options.limits.max_analysis_points = 1001;
    options.limits.max_stream_samples = 20000;
    options.limits.max_optimize_seconds = 1.0;
    auto started = geotraj::server::start_server(options);
    if (!started) {
      std::fprintf(stderr, "fuzz_web: %s\n", started.error().c_str());
      std::abort();
    }
    Web w{std::move(*started), nullptr};
    geotraj::server::WebOptions web_options;
    web_options.address = "127.0.0.1:0";
    web_options.idle_timeout = std::chrono::milliseconds(200);
    web_options.header_timeout = std::chrono::milliseconds(1000);
    web_options.request_timeout = std::chrono::milliseconds(2000);
    web_options.max_request_bytes = 1 << 20;
    auto gateway = geotraj::server::WebGateway::start(web_options, w.running.server->InProcessChannel({}));
    if (!gateway) {
      std::fprintf(stderr, "fuzz_web: %s\n", gateway.error().c_str());
      std::abort();
    }
    w.gateway = std::move(*gateway);
    return w;
  }();
  return instance;
}

// Sends `bytes` on a new connection and reads what comes back until the server closes the
// connection, or has been quiet for `quiet_ms` after answering, or `limit_ms` pass. (No
// half-close: the input may end within a request, which the server then waits on until
// its deadline, as it does for a live client.) Empty when nothing came back.
std::string round_trip(std::string_view bytes, int limit_ms, int quiet_ms = 100) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return {};
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(web().gateway->port()));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string answer;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0) {
    std::size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) break;  // the server may close early (a bad head): what it said is read below
      sent += static_cast<std::size_t>(n);
    }
    char buffer[16384];
    const auto start = std::chrono::steady_clock::now();
    auto last = start;
    for (;;) {
      const auto now = std::chrono::steady_clock::now();
      if (now - start > std::chrono::milliseconds(limit_ms)) break;
      if (!answer.empty() && now - last > std::chrono::milliseconds(quiet_ms)) break;
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
      if (n <= 0) break;
      answer.append(buffer, static_cast<std::size_t>(n));
      last = std::chrono::steady_clock::now();
    }
  }
  ::close(fd);
  return answer;
}

void check_answer(std::string_view input, const std::string& answer) {
  if (answer.empty()) return;  // closed without an answer (e.g. a head that never ended)
  if (!answer.starts_with("HTTP/1.1 ") || answer.size() < 12) fail("no status line", input, answer);
  const int status = std::atoi(answer.substr(9, 3).c_str());
  // 100 Continue answers a request that expects it, before its final answer.
  if (status < 100 || status > 599) fail("a status out of range", input, answer);
  if (answer.find("\"NaN\"") != std::string::npos || answer.find("Infinity\"") != std::string::npos) {
    fail("NaN or Infinity in an answer", input, answer);
  }
  // The first answer's body, when it is a JSON error of the API.
  const std::size_t end = answer.find("\r\n\r\n");
  if (end == std::string::npos) return;
  const std::string_view head = std::string_view(answer).substr(0, end);
  if (status < 400 || head.find("Content-Type: application/json") == std::string_view::npos) return;
  const std::size_t length_at = head.find("Content-Length: ");
  if (length_at == std::string_view::npos) return;
  const std::size_t length = std::strtoul(answer.c_str() + length_at + 16, nullptr, 10);
  if (answer.size() < end + 4 + length) fail("a body shorter than announced", input, answer);
  google::rpc::Status error;
  if (!google::protobuf::util::JsonStringToMessage(answer.substr(end + 4, length), &error).ok()) {
    fail("an API error whose body is no google.rpc.Status", input, answer);
  }
  if (error.code() == 2 || error.code() == 13 || error.code() == 15 || error.code() == 0) {
    fail("an API error with a code that no request may get", input, answer);
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  (void)web();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 65536) return -1;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  check_answer(input, round_trip(input, 8000));
  // Still serving: a plan of two frames over a new connection.
  static const std::string kBody =
      "{\"path\":{\"frames\":[{\"position\":{},\"tangent\":{\"x\":1}},{\"position\":{\"x\":1},\"tangent\":{\"x\":1}}]}}";
  static const std::string kProbe = "POST /v1/plan HTTP/1.1\r\nHost: fuzz\r\nConnection: close\r\n"
                                    "Content-Type: application/json\r\n"
                                    "Content-Length: " + std::to_string(kBody.size()) + "\r\n\r\n" + kBody;
  if (const std::string probe = round_trip(kProbe, 8000); !probe.starts_with("HTTP/1.1 200")) {
    fail("the server stopped answering a good plan", input, probe);
  }
  return 0;
}
