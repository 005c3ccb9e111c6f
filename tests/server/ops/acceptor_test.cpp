// The acceptor of the gRPC ports (server/ops/acceptor.hpp) on its own, with a sink that
// holds each connection as gRPC would: the connection cap, silent connections making room
// at the cap, and acceptance that stops when descriptors run out and resumes when they are
// free again, with readiness told both times. Also the readiness rule of the health state.
#include <arpa/inet.h>
#include <dirent.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <thread>
#include <vector>

#include <gmock/gmock.h>

#include "tests/server/support/raw_sockets.hpp"
#include "tests/support/sanitizers.hpp"
#include "server/ops/acceptor.hpp"
#include "server/rpc/health.hpp"

namespace geotraj::testing {
namespace {

// Holds every connection handed to it, as gRPC does, until told to close them.
class HoldingSink final : public grpc::experimental::ExternalConnectionAcceptor {
 public:
  void HandleNewConnection(NewConnectionParameters* p) override {
    const std::lock_guard lock(mutex_);
    fds_.push_back(p->fd);
  }
  std::size_t count() const {
    const std::lock_guard lock(mutex_);
    return fds_.size();
  }
  void close_all() {
    const std::lock_guard lock(mutex_);
    for (int fd : fds_) ::close(fd);
    fds_.clear();
  }

 private:
  mutable std::mutex mutex_;
  std::vector<int> fds_;
};

template <typename Done>
bool eventually(Done done, std::chrono::seconds limit = std::chrono::seconds(10)) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < until) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return done();
}

int open_descriptors() {
  int n = 0;
  if (DIR* dir = ::opendir("/proc/self/fd")) {
    while (::readdir(dir) != nullptr) ++n;
    ::closedir(dir);
  }
  return n;
}

class AcceptorTest : public ::testing::Test {
 protected:
  void start(std::size_t max_connections) {
    auto listening = server::Acceptor::listen("127.0.0.1:0", "test address");
    ASSERT_TRUE(listening) << listening.error();
    acceptor_ = std::move(*listening);
    auto sink = std::make_unique<HoldingSink>();
    sink_ = sink.get();
    acceptor_->start(std::move(sink),
                     {"test", max_connections,
                      [this](bool accepting) {
                        (accepting ? recovered_ : failed_).fetch_add(1);
                      }},
                     metrics_, logger_);
  }
  void TearDown() override {
    if (acceptor_) acceptor_->stop();
    if (sink_ != nullptr) sink_->close_all();
    for (int fd : clients_) ::close(fd);
  }

  server::Metrics metrics_;
  server::Logger logger_{server::LogFormat::kText, server::LogLevel::kError, nullptr};
  std::unique_ptr<server::Acceptor> acceptor_;
  HoldingSink* sink_ = nullptr;  // owned by the acceptor
  std::vector<int> clients_;
  std::atomic<int> failed_{0}, recovered_{0};
};

TEST_F(AcceptorTest, BeyondTheCapAConnectionIsClosedOnArrival) {
  start(3);
  for (int i = 0; i < 3; ++i) {
    clients_.push_back(connect_loopback(acceptor_->port()));
    ASSERT_EQ(::send(clients_.back(), "PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n", 24, 0), 24);  // not silent
  }
  ASSERT_TRUE(eventually([&] { return sink_->count() == 3; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  const int fourth = connect_loopback(acceptor_->port());
  ASSERT_GE(fourth, 0);
  EXPECT_TRUE(closed_within(fourth, std::chrono::seconds(5)));
  ::close(fourth);
  EXPECT_EQ(sink_->count(), 3u);
  EXPECT_THAT(metrics_.exposition(),
              ::testing::HasSubstr("geotraj_connections_refused_total{listener=\"test\",reason=\"max_connections\"} 1"));
}

TEST_F(AcceptorTest, AtTheCapSilentConnectionsMakeRoom) {
  start(3);
  for (int i = 0; i < 3; ++i) clients_.push_back(connect_loopback(acceptor_->port()));
  ASSERT_TRUE(eventually([&] { return sink_->count() == 3; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(400));  // past the grace
  const int fourth = connect_loopback(acceptor_->port());
  ASSERT_GE(fourth, 0);
  clients_.push_back(fourth);
  EXPECT_TRUE(eventually([&] { return sink_->count() == 4; })) << "the new connection was not taken";
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(closed_within(clients_[static_cast<std::size_t>(i)], std::chrono::seconds(5)));
}

TEST_F(AcceptorTest, OutOfDescriptorsAcceptancePausesAndResumes) {
  if (geotraj::testing::kAddressSanitizer) {
    // UBSan's checks of a virtual call read memory through a pipe, which needs descriptors:
    // with none left they report every such call as invalid. Release and TSan run this.
    GTEST_SKIP() << "the sanitizers' runtime needs descriptors of its own";
  }
  start(100000);
  rlimit saved{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &saved), 0);
  rlimit low = saved;
  low.rlim_cur = static_cast<rlim_t>(open_descriptors() + 40);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
  // Each connection takes two descriptors here (the client's and the one accepted) until
  // none is left; the backlog still takes connections, which the acceptor sheds.
  for (int i = 0; i < 60; ++i) {
    const int fd = connect_loopback(acceptor_->port());
    if (fd >= 0) clients_.push_back(fd);
  }
  EXPECT_TRUE(eventually([&] { return failed_.load() >= 1; })) << "no descriptor exhaustion was seen";
  EXPECT_FALSE(acceptor_->accepting());
  // Descriptors free again: acceptance resumes, readiness is told, new clients get in.
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &saved), 0);
  sink_->close_all();
  for (int fd : clients_) ::close(fd);
  clients_.clear();
  EXPECT_TRUE(eventually([&] { return recovered_.load() >= 1 && acceptor_->accepting(); }));
  // The listen backlog may still hold connections queued during the exhaustion (closed by
  // their clients since); the acceptor takes them first. Count once it has drained.
  std::size_t before = sink_->count();
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  auto quiet_since = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() < give_up &&
         std::chrono::steady_clock::now() - quiet_since < std::chrono::milliseconds(500)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (const std::size_t now = sink_->count(); now != before) {
      before = now;
      quiet_since = std::chrono::steady_clock::now();
    }
  }
  clients_.push_back(connect_loopback(acceptor_->port()));
  EXPECT_TRUE(eventually([&] { return sink_->count() >= before + 1; })) << "a new client was not taken";
}

TEST(HealthState, ReadinessIsNotServingWhileAPortCannotAccept) {
  server::HealthState state;
  state.set_readiness_name("geotraj.readiness");
  state.set("", true);
  state.set("geotraj.readiness", true);
  state.set_accepting("grpc", false);
  EXPECT_EQ(state.get("geotraj.readiness"), false);
  EXPECT_EQ(state.get(""), true);  // liveness: the process serves
  EXPECT_EQ(state.get("no.such.service"), std::nullopt);
  state.set_accepting("health", false);
  state.set_accepting("health", true);  // one port recovers, the other still cannot accept
  EXPECT_EQ(state.get("geotraj.readiness"), false);
  state.set_accepting("grpc", true);
  EXPECT_EQ(state.get("geotraj.readiness"), true);
}

}  // namespace
}  // namespace geotraj::testing
