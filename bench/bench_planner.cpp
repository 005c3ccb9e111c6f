// How soon the planner's budget stops long work (a cancelled optimisation stops its
// CPU within 50 ms). Each iteration starts one kind of long work (tests/planner/long_work.hpp:
// the breakpoint optimiser on Table B.1, the PA-10's joint-space pass over 600,000 samples,
// an analysis of 10^6 points), lets it run 100 ms, requests the stop and times the wait until
// the planner returns (manual time: only that wait). The same for a passed deadline: the
// time from the deadline to the return. docs/performance.md has the figures.
// BM_FastestPa10: the PA-10 along the thesis's paths time-optimal (optimize.timing.timeOptimal, 100 Hz),
// with the self-motion chosen sample by sample (0) or serving the timing (1:
// optimize.redundancy, acceleration; the path timed again along the joints chosen): the
// whole plan's time, the motion's duration as a counter.
#include <benchmark/benchmark.h>

#include <chrono>
#include <future>
#include <stdexcept>
#include <stop_token>
#include <thread>

#include "long_work.hpp"

namespace {

using geotraj::testing::LongWork;
using Clock = std::chrono::steady_clock;

void BM_CancelLatency(benchmark::State& state) {
  const auto work = static_cast<LongWork>(state.range(0));
  const auto request = geotraj::testing::long_request(work);
  for (auto _ : state) {
    std::stop_source stop;
    geotraj::planner::Budget budget;
    budget.stop = stop.get_token();
    auto result = std::async(std::launch::async, [&] { return geotraj::testing::run_long_work(work, request, budget); });
    if (result.wait_for(std::chrono::milliseconds(100)) != std::future_status::timeout) {
      throw std::runtime_error("the work ended before it could be cancelled");
    }
    const auto requested = Clock::now();
    stop.request_stop();
    const auto error = result.get();
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - requested).count());
    if (!error || error->kind != geotraj::planner::ErrorKind::kStopped) throw std::runtime_error("not stopped");
  }
  state.SetLabel(geotraj::testing::name(work));
}

void BM_DeadlineLatency(benchmark::State& state) {
  const auto work = static_cast<LongWork>(state.range(0));
  const auto request = geotraj::testing::long_request(work);
  for (auto _ : state) {
    geotraj::planner::Budget budget;
    budget.deadline = Clock::now() + std::chrono::milliseconds(100);
    const auto error = geotraj::testing::run_long_work(work, request, budget);
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - budget.deadline).count());
    if (!error || error->kind != geotraj::planner::ErrorKind::kDeadlineExceeded) throw std::runtime_error("ran on");
  }
  state.SetLabel(geotraj::testing::name(work));
}

void BM_FastestPa10(benchmark::State& state) {
  const char which = static_cast<char>('A' + state.range(0));
  geotraj::planner::Request request;
  request.geometry = geotraj::testing::thesis_demo_path(which, geotraj::core::BlendMethod::kPolynomial,
                                                        geotraj::core::UnspecifiedConstraints::kSmoothest);
  geotraj::core::MotionSpec motion;
  motion.duration_s = 0.0;  // as fast as the limits allow
  motion.cycle_rate_hz = 100.0;
  request.motion = motion;
  request.robot = geotraj::testing::pa10();
  geotraj::planner::Optimize optimize;
  optimize.time_optimal = true;  // the sweep of thesis 6.4
  if (state.range(1) != 0) {
    optimize.redundancy = geotraj::optim::RedundancyWeights{};
    optimize.redundancy->acceleration = 1.0;
  }
  request.optimize = optimize;
  double duration = 0.0;
  for (auto _ : state) {
    auto plan = geotraj::planner::plan(request, {}, {}, geotraj::planner::Use::kStream);
    if (!plan || !plan->trajectory) {
      state.SkipWithError("not planned");
      return;
    }
    duration = geotraj::core::duration(*plan->trajectory);
  }
  state.SetLabel(std::string("path ") + which + (state.range(1) != 0 ? ", self-motion serving the timing" : ""));
  state.counters["duration_s"] = duration;
}

void kinds(benchmark::internal::Benchmark* b) {
  for (const auto work : geotraj::testing::kLongWork) b->Arg(static_cast<int>(work));
}

BENCHMARK(BM_CancelLatency)->Apply(kinds)->UseManualTime()->Iterations(5)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DeadlineLatency)->Apply(kinds)->UseManualTime()->Iterations(5)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FastestPa10)->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
