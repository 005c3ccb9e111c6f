// How soon the planner's budget stops long work (a cancelled optimisation stops its
// CPU within 50 ms). Each iteration starts one kind of long work (tests/planner/long_work.hpp:
// the breakpoint optimiser on Table B.1, the PA-10's joint-space pass over 600,000 samples,
// an analysis of 10^6 points), lets it run 100 ms, requests the stop and times the wait until
// the planner returns (manual time: only that wait). The same for a passed deadline: the
// time from the deadline to the return. docs/performance.md has the figures.
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

void kinds(benchmark::internal::Benchmark* b) {
  for (const auto work : geotraj::testing::kLongWork) b->Arg(static_cast<int>(work));
}

BENCHMARK(BM_CancelLatency)->Apply(kinds)->UseManualTime()->Iterations(5)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DeadlineLatency)->Apply(kinds)->UseManualTime()->Iterations(5)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
