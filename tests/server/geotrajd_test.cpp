// geotrajd as a process: it serves on the address it is given (here through the environment
// variables GEOTRAJ_ADDRESS, port 0, and GEOTRAJ_DRAIN_SECONDS), logs the bound port,
// reports SERVING, and exits 0 on SIGTERM and on SIGINT.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <gmock/gmock.h>

#include "tests/server/support/daemon.hpp"
#include "grpc/health/v1/health.grpc.pb.h"
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

}  // namespace
}  // namespace geotraj::testing
