// The service under load, in process on 127.0.0.1:<ephemeral>: 200 concurrent
// StreamSamples calls (callback API, no thread per stream) and 1,000 PlanTrajectory calls
// from 8 workers end without an error; memory stays flat over repeated rounds and the
// metrics agree with what the clients saw; beyond --max-streams, streams are refused with
// RESOURCE_EXHAUSTED while those admitted finish. Throughput goes to the test's properties
// (ctest --output-junit, or the XML of --gtest_output) and to stdout.
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>

#include "tests/reliability/reliability.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

constexpr int kStreams = 200;
constexpr std::size_t kPathASamples = 1001;  // plan_demo_path_a.json: 10 s at 100 Hz
constexpr int kConnections = 4;              // client TCP connections the streams spread over

std::chrono::system_clock::time_point in(std::chrono::seconds s) { return std::chrono::system_clock::now() + s; }

// Every RPC of `method` the metrics count, whatever its code.
double all_calls(const std::string& exposition, const std::string& method) {
  double sum = 0.0;
  std::istringstream lines(exposition);
  const std::string prefix = "geotraj_rpc_calls_total{method=\"" + method + "\",";
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(prefix, 0) == 0) sum += std::strtod(line.c_str() + line.rfind(' ') + 1, nullptr);
  }
  return sum;
}

class LoadTest : public ConfiguredServerTest {
 protected:
  struct StreamRound {
    int ok = 0;
    int complete = 0;  // OK, every sample, in order
    std::vector<std::string> errors;
    double seconds = 0.0;
  };

  // `count` concurrent streams of `request` over kConnections connections; waits for all.
  StreamRound stream_round(const v1::PlanRequest& request, int count, std::size_t expected_samples) {
    std::vector<std::shared_ptr<grpc::Channel>> channels;
    std::vector<std::unique_ptr<v1::TrajectoryService::Stub>> stubs;
    for (int c = 0; c < kConnections; ++c) {
      channels.push_back(own_channel(c));
      stubs.push_back(v1::TrajectoryService::NewStub(channels.back()));
    }
    Latch latch(count);
    std::vector<std::unique_ptr<StreamReader>> readers;
    const auto started = std::chrono::steady_clock::now();
    for (int i = 0; i < count; ++i) {
      readers.push_back(std::make_unique<StreamReader>(*stubs[i % kConnections], request, in(std::chrono::seconds(150))));
      readers.back()->start([&latch] { latch.count_down(); });
    }
    StreamRound round;
    if (!latch.wait(std::chrono::seconds(170))) {
      ADD_FAILURE() << "streams did not finish within 170 s";
      std::abort();  // the readers are still in use by gRPC: no way to unwind safely
    }
    round.seconds = seconds_since(started);
    for (const auto& r : readers) {
      if (r->status().ok()) ++round.ok;
      if (r->status().ok() && r->received() == expected_samples && r->in_order()) ++round.complete;
      if (!r->status().ok()) round.errors.push_back(std::to_string(r->status().error_code()) + " " + r->status().error_message());
    }
    return round;
  }

  // `total` PlanTrajectory calls of `request` from `workers` threads (blocking stubs, one
  // channel each); returns the failures' messages, and the elapsed time in `seconds`.
  std::vector<std::string> plan_round(const v1::PlanRequest& request, int total, int workers, double& seconds) {
    std::mutex mutex;
    std::vector<std::string> errors;
    std::vector<std::thread> threads;
    const auto started = std::chrono::steady_clock::now();
    for (int w = 0; w < workers; ++w) {
      threads.emplace_back([&, w] {
        auto stub = v1::TrajectoryService::NewStub(own_channel(100 + w));
        for (int i = w; i < total; i += workers) {
          grpc::ClientContext context;
          context.set_deadline(in(std::chrono::seconds(60)));
          v1::PlanResponse response;
          const auto status = stub->PlanTrajectory(&context, request, &response);
          if (!status.ok() || response.motion().sample_count() != kPathASamples) {
            std::lock_guard lock(mutex);
            errors.push_back("call " + std::to_string(i) + " at " + std::to_string(seconds_since(started)) + " s: code " +
                             std::to_string(status.error_code()) + " " + status.error_message() + ", " +
                             std::to_string(response.motion().sample_count()) + " samples");
          }
        }
      });
    }
    for (auto& t : threads) t.join();
    seconds = seconds_since(started);
    return errors;
  }

  // Both gauges back to 0 (a stream's server side finishes just after its client has the
  // status, so poll).
  void expect_idle() {
    const bool idle = eventually(
        [this] {
          const auto text = server::metrics_exposition(running_);
          return metric(text, "geotraj_active_streams") == 0.0 && metric(text, "geotraj_active_unary_calls") == 0.0;
        },
        std::chrono::seconds(10));
    EXPECT_TRUE(idle) << server::metrics_exposition(running_);
  }

  void record(const std::string& key, double value) {
    char text[64];
    std::snprintf(text, sizeof text, "%.1f", value);
    RecordProperty(key, text);
    std::printf("[ figure   ] %s = %s\n", key.c_str(), text);
    std::fflush(stdout);
  }
};

// (a) 200 streams of path A (1001 samples each), as fast as possible, all at once.
TEST_F(LoadTest, TwoHundredConcurrentStreamsComplete) {
  start(quiet_options());
  const auto request = demo_request('a');
  const auto round = stream_round(request, kStreams, kPathASamples);
  EXPECT_EQ(round.ok, kStreams) << ::testing::PrintToString(round.errors);
  EXPECT_EQ(round.complete, kStreams) << "streams with every sample, in order";
  record("streams_per_s", kStreams / round.seconds);
  record("samples_per_s", kStreams * static_cast<double>(kPathASamples) / round.seconds);
  record("round_s", round.seconds);
  expect_idle();
  const auto text = server::metrics_exposition(running_);
  EXPECT_EQ(calls_total(text, "StreamSamples", "OK"), kStreams);
  EXPECT_EQ(metric(text, "geotraj_samples_streamed_total"), kStreams * static_cast<double>(kPathASamples));
}

// (b) 1,000 plans of path A with its motion summary, from 8 concurrent workers.
TEST_F(LoadTest, ThousandPlansFromEightWorkers) {
  start(quiet_options());
  double seconds = 0.0;
  const auto errors = plan_round(demo_request('a'), 1000, 8, seconds);
  EXPECT_THAT(errors, ::testing::IsEmpty());
  record("plans_per_s", 1000 / seconds);
  expect_idle();
  const auto text = server::metrics_exposition(running_);
  EXPECT_EQ(calls_total(text, "PlanTrajectory", "OK"), 1000);
  EXPECT_EQ(all_calls(text, "PlanTrajectory"), 1000);
}

// (c) Memory: after two warm-up rounds (gRPC's and the allocator's pools, the connections),
// five more rounds of 200 streams and 200 plans leave the heap in use (mallinfo2: what
// malloc handed out and was not given back) where it was. Bound: 2 MB. Measured in Release:
// about 1.0 MB in use after the warm-up, +0.13 to +0.18 MB after the five rounds; a leak of
// 1 kB per call (2,000 calls) fails it, one leaked batch per stream (~50 kB) by far. The
// resident set is printed beside it (after malloc_trim, about 30 MB; untrimmed 72-115 MB)
// but not bounded: thread stacks and free pages move it by up to 7 MB from one round to the
// next on a loaded machine, with no leak. Not checked under AddressSanitizer
// (kAddressSanitizer), whose allocator is not glibc's and whose LeakSanitizer reports leaks
// at exit instead.
TEST_F(LoadTest, MemoryStaysFlatAndMetricsAgree) {
  start(quiet_options());
  const auto request = demo_request('a');
  constexpr int kWarmUps = 2;
  constexpr int kRounds = 5;
  constexpr int kPlans = 200;
  auto one_round = [&] {
    const auto streams = stream_round(request, kStreams, kPathASamples);
    EXPECT_EQ(streams.complete, kStreams) << ::testing::PrintToString(streams.errors);
    double seconds = 0.0;
    EXPECT_THAT(plan_round(request, kPlans, 8, seconds), ::testing::IsEmpty());
  };
  for (int r = 0; r < kWarmUps; ++r) one_round();
  expect_idle();
  const long long untrimmed = rss_bytes();
  const long long before = trimmed_rss_bytes();
  const long long heap_before = heap_in_use_bytes();
  std::printf("[ figure   ] rss after warm-up = %.1f MB (untrimmed %.1f MB), heap in use %.2f MB\n", megabytes(before),
              megabytes(untrimmed), megabytes(heap_before));
  for (int r = 0; r < kRounds; ++r) {
    one_round();
    const long long round_untrimmed = rss_bytes();
    std::printf("[ figure   ] rss after round %d = %.1f MB (untrimmed %.1f MB), heap in use %.2f MB\n", r + 1,
                megabytes(trimmed_rss_bytes()), megabytes(round_untrimmed), megabytes(heap_in_use_bytes()));
  }
  expect_idle();
  const long long after = trimmed_rss_bytes();
  const long long heap_after = heap_in_use_bytes();
  record("rss_before_mb", megabytes(before));
  record("rss_after_mb", megabytes(after));
  record("heap_in_use_before_mb", megabytes(heap_before));
  record("heap_in_use_after_mb", megabytes(heap_after));
  if (!kAddressSanitizer) {
    EXPECT_LT(heap_after - heap_before, 2ll * 1024 * 1024)
        << "the heap in use grew from " << megabytes(heap_before) << " MB to " << megabytes(heap_after) << " MB";
  }

  const auto text = server::metrics_exposition(running_);
  const double rounds = kWarmUps + kRounds;
  EXPECT_EQ(calls_total(text, "StreamSamples", "OK"), rounds * kStreams);
  EXPECT_EQ(all_calls(text, "StreamSamples"), rounds * kStreams);
  EXPECT_EQ(calls_total(text, "PlanTrajectory", "OK"), rounds * kPlans);
  EXPECT_EQ(all_calls(text, "PlanTrajectory"), rounds * kPlans);
  EXPECT_EQ(metric(text, "geotraj_samples_streamed_total"), rounds * kStreams * static_cast<double>(kPathASamples));
  EXPECT_EQ(metric(text, "geotraj_active_streams"), 0.0);
  EXPECT_EQ(metric(text, "geotraj_active_unary_calls"), 0.0);
}

// (d) With --max-streams 50, 80 simultaneous real-time streams (3 s each, so all 80 arrive
// while the first are still running): exactly 30 are refused at once, naming the flag; the
// 50 admitted deliver their whole motion.
TEST_F(LoadTest, StreamCapRefusesTheExcessAndServesTheRest) {
  auto options = quiet_options();
  options.limits.max_streams = 50;
  start(options);
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(3.0);  // 301 samples at 100 Hz
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);

  Latch latch(80);
  std::vector<std::unique_ptr<StreamReader>> readers;
  for (int i = 0; i < 80; ++i) {
    readers.push_back(std::make_unique<StreamReader>(*stub_, request, in(std::chrono::seconds(60))));
    readers.back()->start([&latch] { latch.count_down(); });
  }
  ASSERT_TRUE(latch.wait(std::chrono::seconds(90))) << "streams did not finish";
  int ok = 0, exhausted = 0;
  for (const auto& r : readers) {
    if (r->status().ok()) {
      ++ok;
      EXPECT_EQ(r->received(), 301u);
      EXPECT_TRUE(r->in_order());
    } else {
      EXPECT_EQ(r->status().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << r->status().error_message();
      EXPECT_THAT(r->status().error_message(), HasSubstr("--max-streams"));
      EXPECT_EQ(r->received(), 0u);
      ++exhausted;
    }
  }
  EXPECT_EQ(ok, 50);
  EXPECT_EQ(exhausted, 30);
  expect_idle();
  const auto text = server::metrics_exposition(running_);
  EXPECT_EQ(calls_total(text, "StreamSamples", "OK"), 50);
  EXPECT_EQ(metric(text, "geotraj_rpc_rejected_total{method=\"StreamSamples\",reason=\"capacity\"}"), 30.0);
}

}  // namespace
}  // namespace geotraj::testing
