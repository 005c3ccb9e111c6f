// Live calls do not starve the server: with 64 or 200 Jogs at 10 kHz
// asked for at once, health checks on the gRPC port answer within their 1 s deadline and
// another robot's 250 Hz Jog keeps its cadence. The server makes set points on its pacing
// threads (not gRPC's) and admits live calls within --max-live-rate-hz and a --max-streams
// slot per kHz; the Jogs beyond are refused at once with RESOURCE_EXHAUSTED. The figures
// (health p50/p99/max, the other robot's lateness) go to stdout ("[ measured ]") and the
// test's properties; docs/reliability.md quotes them. Label slow: each test takes ~8 s.
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

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const auto i = static_cast<std::size_t>(std::min<double>(values.size() - 1, p * static_cast<double>(values.size())));
  return values[i];
}

v1::JogRequest jog_start(double rate_hz, std::uint32_t per_batch = 0) {
  v1::JogRequest first;
  first.mutable_start()->mutable_robot()->set_name("panda");
  first.mutable_start()->set_cycle_rate_hz(rate_hz);
  first.mutable_start()->set_deadman_s(2.0);
  if (per_batch > 0) first.mutable_start()->set_samples_per_batch(per_batch);
  return first;
}

// One Jog on the callback API (no thread per call): reads every batch, sends a heartbeat
// every 100 ms (from the reads), records the first batch and how it ended.
class FastJog final : public grpc::ClientBidiReactor<v1::JogRequest, v1::SampleBatch> {
 public:
  FastJog(v1::TrajectoryService::Stub& stub, double rate_hz, Latch& done) : first_(jog_start(rate_hz)), done_(&done) {
    context_.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    beat_.mutable_heartbeat();
    stub.async()->Jog(&context_, this);
    writing_ = true;
    StartWrite(&first_);
    StartRead(&batch_);
    StartCall();
  }
  void OnWriteDone(bool) override { writing_ = false; }
  void OnReadDone(bool ok) override {
    if (!ok) return;
    streaming_ = true;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_beat_ > std::chrono::milliseconds(100) && !writing_.exchange(true)) {
      last_beat_ = now;
      StartWrite(&beat_);
    }
    StartRead(&batch_);
  }
  void OnDone(const grpc::Status& status) override {
    status_ = status;
    done_->count_down();
  }
  void cancel() { context_.TryCancel(); }
  bool streaming() const { return streaming_; }
  const grpc::Status& status() const { return status_; }  // after the latch

 private:
  grpc::ClientContext context_;
  v1::JogRequest first_;
  v1::JogRequest beat_;
  v1::SampleBatch batch_;
  std::atomic<bool> writing_{false};
  std::atomic<bool> streaming_{false};
  std::chrono::steady_clock::time_point last_beat_ = std::chrono::steady_clock::now();
  grpc::Status status_;
  Latch* done_;
};

class LiveLoadTest : public ConfiguredServerTest {
 protected:
  // `fast` Jogs at 10 kHz asked for while another robot jogs at 250 Hz (one set point per
  // batch) and health is checked every 20 ms for 5 s.
  void measure(int fast, server::ServerOptions options, const char* label) {
    ASSERT_NO_FATAL_FAILURE(start(options));
    // The other robot, on its own connection, reading on this thread's partner.
    auto other_stub = v1::TrajectoryService::NewStub(own_channel(100));
    grpc::ClientContext other_context;
    other_context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    auto other = other_stub->Jog(&other_context);
    ASSERT_TRUE(other->Write(jog_start(250.0, 1)));
    Lateness lateness;
    std::atomic<bool> stop_other{false};
    std::atomic<bool> other_streaming{false};
    std::thread reader([&] {
      v1::SampleBatch batch;
      auto last_beat = std::chrono::steady_clock::now();
      bool stopped = false;
      while (other->Read(&batch)) {
        other_streaming = true;
        const auto now = std::chrono::steady_clock::now();
        for (const auto& s : batch.samples()) lateness.arrived(s.t(), now);
        v1::JogRequest message;
        if (stop_other && !stopped) {
          stopped = true;
          message.mutable_stop();
          other->Write(message);
        } else if (now - last_beat > std::chrono::milliseconds(100)) {
          last_beat = now;
          message.mutable_heartbeat();
          other->Write(message);
        }
      }
    });

    // The other robot is admitted first (its start could otherwise reach the server after
    // the fast Jogs had taken the whole live budget, on a loaded machine).
    const auto admitted_by = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (!other_streaming && std::chrono::steady_clock::now() < admitted_by) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    // The fast Jogs, over 4 connections.
    std::vector<std::unique_ptr<v1::TrajectoryService::Stub>> stubs;
    for (int c = 0; c < 4; ++c) stubs.push_back(v1::TrajectoryService::NewStub(own_channel(c)));
    Latch done(fast);
    std::vector<std::unique_ptr<FastJog>> jogs;
    for (int i = 0; i < fast; ++i) jogs.push_back(std::make_unique<FastJog>(*stubs[i % 4], 10'000.0, done));

    std::vector<double> health_ms;
    int unanswered = 0;
    auto health = grpc::health::v1::Health::NewStub(own_channel(200));
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (std::chrono::steady_clock::now() < until) {
      grpc::ClientContext context;
      context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(1));
      grpc::health::v1::HealthCheckRequest check;
      check.set_service(server::kReadinessService);
      grpc::health::v1::HealthCheckResponse response;
      const auto t0 = std::chrono::steady_clock::now();
      const auto status = health->Check(&context, check, &response);
      if (!status.ok() || response.status() != grpc::health::v1::HealthCheckResponse::SERVING) ++unanswered;
      health_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    int admitted = 0;
    for (const auto& j : jogs) admitted += j->streaming() ? 1 : 0;
    for (auto& j : jogs) j->cancel();
    ASSERT_TRUE(done.wait(std::chrono::seconds(60)));
    stop_other = true;
    reader.join();
    const auto other_status = other->Finish();

    int refused = 0, other_codes = 0;
    for (const auto& j : jogs) {
      if (j->status().error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED) {
        ++refused;
        EXPECT_THAT(j->status().error_message(), ::testing::ContainsRegex("--max-live-rate-hz|--max-streams"));
      } else if (j->status().error_code() != grpc::StatusCode::CANCELLED) {
        ++other_codes;
      }
    }
    std::printf("[ measured ] %s: %d Jogs at 10 kHz asked for, %d streaming, %d refused (RESOURCE_EXHAUSTED)\n", label,
                fast, admitted, refused);
    std::printf("[ measured ] %s: health, gRPC port: %zu checks, p50 %.2f ms, p99 %.2f ms, max %.2f ms\n", label,
                health_ms.size(), percentile(health_ms, 0.5), percentile(health_ms, 0.99), percentile(health_ms, 1.0));
    std::printf("[ measured ] %s: another robot's 250 Hz set points (%zu): lateness p50 %.2f ms, p99 %.2f ms, max %.2f ms\n",
                label, lateness.ms().size(), percentile(lateness.ms(), 0.5), percentile(lateness.ms(), 0.99),
                percentile(lateness.ms(), 1.0));
    RecordProperty("health_p99_ms", std::to_string(percentile(health_ms, 0.99)));
    RecordProperty("other_robot_lateness_p99_ms", std::to_string(percentile(lateness.ms(), 0.99)));
    RecordProperty("fast_jogs_streaming", std::to_string(admitted));

    EXPECT_EQ(unanswered, 0) << "health checks not answered SERVING within 1 s";
    EXPECT_TRUE(other_status.ok()) << other_status.error_message();
    EXPECT_EQ(other_codes, 0) << "fast Jogs ended otherwise than refused or cancelled";
  }
};

TEST_F(LiveLoadTest, HealthAndAnotherRobotHoldWith64FastJogs) { measure(64, quiet_options(), "64 Jogs"); }

TEST_F(LiveLoadTest, HealthAndAnotherRobotHoldWith200FastJogs) { measure(200, quiet_options(), "200 Jogs"); }

}  // namespace
}  // namespace geotraj::testing
