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

#include "grpc/health/v1/health.grpc.pb.h"
#include "test_server.hpp"

namespace geotraj::testing {
namespace {

// A geotrajd child process with its standard output on a pipe.
class Daemon {
 public:
  Daemon() {
    int fds[2];
    if (::pipe(fds) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], STDOUT_FILENO);
      ::close(fds[0]);
      ::close(fds[1]);
      ::setenv("GEOTRAJ_ADDRESS", "127.0.0.1:0", 1);
      // Connected clients (this test's channel) are disconnected when the grace ends.
      ::setenv("GEOTRAJ_DRAIN_SECONDS", "0.2", 1);
      ::execl(GEOTRAJD, GEOTRAJD, static_cast<char*>(nullptr));
      std::_Exit(127);
    }
    ::close(fds[1]);
    out_ = ::fdopen(fds[0], "r");
  }
  ~Daemon() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    if (out_ != nullptr) std::fclose(out_);
  }

  /// The next line of its standard output ("" at end of file).
  std::string line() {
    char buf[512];
    if (out_ == nullptr || std::fgets(buf, sizeof buf, out_) == nullptr) return "";
    return buf;
  }
  void signal(int sig) { ::kill(pid_, sig); }
  /// Its exit code, or -1 when a signal ended it.
  int wait() {
    int status = 0;
    ::waitpid(pid_, &status, 0);
    reaped_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  bool started() const { return pid_ > 0 && out_ != nullptr; }

 private:
  pid_t pid_ = -1;
  FILE* out_ = nullptr;
  bool reaped_ = false;
};

// The port of the log line "geotrajd: serving ... on HOST:PORT (...)".
int port_of(const std::string& line) {
  const auto paren = line.find(" (");
  const auto colon = line.rfind(':', paren);
  if (paren == std::string::npos || colon == std::string::npos) return 0;
  return std::atoi(line.substr(colon + 1, paren - colon - 1).c_str());
}

class GeotrajdTest : public ::testing::TestWithParam<int> {};

TEST_P(GeotrajdTest, ServesAndStopsOnSignal) {
  Daemon daemon;
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
