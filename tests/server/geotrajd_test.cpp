// geotrajd as a process: it serves on the address it is given (here through the environment
// variables GEOTRAJ_ADDRESS, port 0, and GEOTRAJ_DRAIN_SECONDS), logs the bound port,
// reports SERVING, and exits 0 on SIGTERM and on SIGINT. The web port's limits come from
// their flags (--web-...), and a bad value is refused by name.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <utility>

#include <gmock/gmock.h>

#include "tests/server/support/daemon.hpp"
#include "grpc/health/v1/health.grpc.pb.h"
#include "tests/server/support/raw_sockets.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

class GeotrajdTest : public ::testing::TestWithParam<int> {};

TEST_P(GeotrajdTest, ServesAndStopsOnSignal) {
  // Configured through the environment; connected clients (this test's channel) are
  // disconnected when the drain ends.
  Daemon daemon({}, {{"GEOTRAJ_ADDRESS", "127.0.0.1:0"}, {"GEOTRAJ_DRAIN_SECONDS", "0.2"}});
  ASSERT_TRUE(daemon.started());
  const std::string serving = daemon.line();
  ASSERT_THAT(serving, ::testing::HasSubstr("geotrajd: serving geotraj.v1.TrajectoryService on 127.0.0.1:"));
  const int port = port_of(serving);
  ASSERT_GT(port, 0) << serving;

  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  grpc::health::v1::HealthCheckRequest request;
  grpc::health::v1::HealthCheckResponse response;
  const auto status = grpc::health::v1::Health::NewStub(channel)->Check(&context, request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.status(), grpc::health::v1::HealthCheckResponse::SERVING);

  daemon.signal(GetParam());
  EXPECT_THAT(daemon.line(), ::testing::HasSubstr("draining (up to 0.2 s)"));
  EXPECT_EQ(daemon.wait(), 0);
}

INSTANTIATE_TEST_SUITE_P(Signals, GeotrajdTest, ::testing::Values(SIGTERM, SIGINT),
                         [](const auto& p) { return std::string(p.param == SIGTERM ? "SIGTERM" : "SIGINT"); });

// --web-max-connections 1 with idle and header timeouts of 10 minutes: a silent connection
// is closed when a second one arrives (evicted as the oldest reading a request), not by a
// timeout, and the second is answered.
TEST(GeotrajdWeb, FlagsSetTheWebPortsLimits) {
  Daemon daemon({"--address", "127.0.0.1:0", "--web-address", "127.0.0.1:0", "--web-max-connections", "1",
                 "--web-idle-timeout-seconds", "600", "--web-header-timeout-seconds", "600", "--web-threads", "1",
                 "--web-max-answer-bytes", "1048576", "--log-level", "warning", "--drain-seconds", "0.2"});
  ASSERT_TRUE(daemon.started());
  int web_port = 0;
  const std::string announce = "JSON API on http port ";
  while (web_port == 0) {
    const std::string l = daemon.line();
    if (l.empty()) break;
    if (const auto at = l.find(announce); at != std::string::npos) web_port = std::atoi(l.c_str() + at + announce.size());
  }
  ASSERT_GT(web_port, 0) << daemon.errors();

  const int silent = connect_loopback(web_port);
  ASSERT_GE(silent, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // accepted first, so the oldest
  const int asking = connect_loopback(web_port);
  ASSERT_GE(asking, 0);
  const std::string request = "GET /v1/robots HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n";
  ASSERT_EQ(::send(asking, request.data(), request.size(), MSG_NOSIGNAL), static_cast<ssize_t>(request.size()));
  std::string answer;
  char buffer[4096];
  for (ssize_t n; (n = ::recv(asking, buffer, sizeof buffer, 0)) > 0;) answer.append(buffer, static_cast<std::size_t>(n));
  EXPECT_THAT(answer, ::testing::StartsWith("HTTP/1.1 200"));
  EXPECT_TRUE(closed_within(silent, std::chrono::seconds(60))) << "the silent connection was not evicted";
  ::close(silent);
  ::close(asking);

  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(), 0);
}

// A limit out of range, and NaN or infinity in any floating-point flag (CLI11's range check
// compares, and NaN compares false with both bounds), end geotrajd at start-up naming the flag.
TEST(GeotrajdFlags, ABadOrNonFiniteValueIsRefusedByName) {
  for (const auto& [flag, value] :
       {std::pair{"--web-threads", "0"}, std::pair{"--web-max-connections", "0"},
        std::pair{"--web-max-answer-bytes", "10"}, std::pair{"--web-request-timeout-seconds", "nan"},
        std::pair{"--web-idle-timeout-seconds", "inf"}, std::pair{"--drain-seconds", "nan"},
        std::pair{"--max-live-rate-hz", "nan"}, std::pair{"--default-deadline-seconds", "-nan"},
        std::pair{"--keepalive-seconds", "inf"}}) {
    Daemon daemon({"--address", "127.0.0.1:0", "--web-address", "127.0.0.1:0", flag, value});
    ASSERT_TRUE(daemon.started());
    const auto code = daemon.wait(std::chrono::seconds(60));
    ASSERT_TRUE(code.has_value()) << flag << " " << value << " was accepted: geotrajd serves";
    EXPECT_NE(*code, 0) << flag << " " << value;
    EXPECT_THAT(daemon.errors(), ::testing::HasSubstr(flag)) << value;
  }
}

}  // namespace
}  // namespace geotraj::testing
