// Long work does not starve the rest: with 64 optimisations in flight (two workers, the
// rest queued), health checks on the gRPC port and on the health-only port answer within
// their 1 s deadline, a 100 Hz real-time stream keeps its cadence, and the 65th
// optimisation is refused at once with RESOURCE_EXHAUSTED. The latencies (p50, p99, max)
// go to stdout and the test's properties; docs/reliability.md quotes them. The only
// assertions are the deadlines a client and a kubelet would use.
#include <algorithm>
#include <atomic>
#include <memory>
#include <thread>
#include <vector>

#include <gmock/gmock.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "tests/reliability/reliability.hpp"

namespace geotraj::testing {
namespace {

constexpr int kOptimisations = 64;

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const auto i = static_cast<std::size_t>(std::min<double>(values.size() - 1, p * static_cast<double>(values.size())));
  return values[i];
}

// A stream reader that records each sample's lateness (see Lateness).
class PacedReader final : public grpc::ClientReadReactor<v1::SampleBatch> {
 public:
  PacedReader(v1::TrajectoryService::Stub& stub, const v1::PlanRequest& request) : request_(request) {
    context_.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    stub.async()->StreamSamples(&context_, &request_, this);
    StartRead(&batch_);
    StartCall();
  }
  void OnReadDone(bool ok) override {
    if (!ok) return;
    const auto now = std::chrono::steady_clock::now();
    for (const auto& s : batch_.samples()) lateness_.arrived(s.t(), now);
    StartRead(&batch_);
  }
  void OnDone(const grpc::Status& status) override {
    status_ = status;
    done_.count_down();
  }
  bool wait() { return done_.wait(std::chrono::seconds(120)); }
  const grpc::Status& status() const { return status_; }
  std::vector<double> lateness_ms() const { return lateness_.ms(); }

 private:
  grpc::ClientContext context_;
  v1::PlanRequest request_;
  v1::SampleBatch batch_;
  grpc::Status status_;
  Lateness lateness_;
  Latch done_{1};
};

class IsolationTest : public ConfiguredServerTest {};

TEST_F(IsolationTest, HealthAndPacingHoldWith64OptimisationsInFlight) {
  auto options = quiet_options();
  options.health_address = "127.0.0.1:0";
  options.limits.max_unary_calls = kOptimisations;
  ASSERT_NO_FATAL_FAILURE(start(options));

  // 64 breakpoint optimisations of 0.5 s each (Appendix B): two run, 62 wait.
  auto slow = example<v1::PlanRequest>("appendix_b_optimized.json");
  slow.mutable_optimize()->set_time_budget_s(0.5);
  struct Call {
    grpc::ClientContext context;
    v1::PlanResponse response;
    grpc::Status status;
  };
  std::vector<std::unique_ptr<Call>> calls;
  Latch finished(kOptimisations);
  for (int i = 0; i < kOptimisations; ++i) {
    calls.push_back(std::make_unique<Call>());
    Call* c = calls.back().get();
    c->context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    stub_->async()->PlanTrajectory(&c->context, &slow, &c->response, [c, &finished](grpc::Status s) {
      c->status = std::move(s);
      finished.count_down();
    });
  }
  ASSERT_TRUE(eventually(
      [&] { return metric(server::metrics_exposition(running_), "geotraj_active_unary_calls").value_or(0) == kOptimisations; },
      std::chrono::seconds(30)));

  // The 65th is refused at once.
  {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(1));
    v1::PlanResponse response;
    const auto status = stub_->PlanTrajectory(&context, slow, &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
  }

  // Meanwhile: a 100 Hz real-time stream of 5 s, and health checks every 20 ms on both ports.
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(5.0);
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  request.set_samples_per_batch(1);
  auto stream = std::make_unique<PacedReader>(*stub_, request);
  std::vector<double> health_ms[2];
  int unanswered = 0;
  const int ports[2] = {running_.port, running_.health_port};
  std::shared_ptr<grpc::Channel> channels[2] = {
      grpc::CreateChannel("127.0.0.1:" + std::to_string(ports[0]), grpc::InsecureChannelCredentials()),
      grpc::CreateChannel("127.0.0.1:" + std::to_string(ports[1]), grpc::InsecureChannelCredentials())};
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  for (int i = 0; std::chrono::steady_clock::now() < until; ++i) {
    auto health = grpc::health::v1::Health::NewStub(channels[i % 2]);
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(1));
    grpc::health::v1::HealthCheckRequest check;
    check.set_service(server::kReadinessService);
    grpc::health::v1::HealthCheckResponse response;
    const auto t0 = std::chrono::steady_clock::now();
    const auto status = health->Check(&context, check, &response);
    if (!status.ok() || response.status() != grpc::health::v1::HealthCheckResponse::SERVING) ++unanswered;
    health_ms[i % 2].push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(stream->wait());
  EXPECT_TRUE(stream->status().ok()) << stream->status().error_message();
  EXPECT_EQ(stream->lateness_ms().size(), 501u);
  EXPECT_EQ(unanswered, 0) << "health checks not answered SERVING within 1 s";
  const auto queued = metric(server::metrics_exposition(running_), "geotraj_queued_calls").value_or(-1);

  const auto late = stream->lateness_ms();
  std::printf("[ measured ] %d optimisations in flight (%.0f still queued at the end of the window)\n",
              kOptimisations, queued);
  std::printf("[ measured ] health, gRPC port: %zu checks, p50 %.2f ms, p99 %.2f ms, max %.2f ms\n",
              health_ms[0].size(), percentile(health_ms[0], 0.5), percentile(health_ms[0], 0.99),
              percentile(health_ms[0], 1.0));
  std::printf("[ measured ] health, health port: %zu checks, p50 %.2f ms, p99 %.2f ms, max %.2f ms\n",
              health_ms[1].size(), percentile(health_ms[1], 0.5), percentile(health_ms[1], 0.99),
              percentile(health_ms[1], 1.0));
  std::printf("[ measured ] 100 Hz stream lateness: p50 %.2f ms, p99 %.2f ms, max %.2f ms\n", percentile(late, 0.5),
              percentile(late, 0.99), percentile(late, 1.0));
  RecordProperty("health_p99_ms", std::to_string(percentile(health_ms[0], 0.99)));
  RecordProperty("stream_lateness_p99_ms", std::to_string(percentile(late, 0.99)));

  ASSERT_TRUE(finished.wait(std::chrono::seconds(120)));
  for (const auto& c : calls) EXPECT_TRUE(c->status.ok()) << c->status.error_message();
}

}  // namespace
}  // namespace geotraj::testing
