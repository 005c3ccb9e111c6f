// Jogging (core/live/jog.hpp): the cost of one controller cycle, Jogger::next, on the PA-10.
// Cartesian jogs in W and in the tool frame (arg 0: 0 world, 1 tool) at 100 Hz and 1 kHz
// (arg 1), and a joint jog for comparison. The command flips sign every 0.5 s, so the arm
// keeps ramping (the per-joint profiles replanned, the braking checks) and stays near home.
// Counters: allocations per cycle (must be 0), and, in the per-cycle-timed variant, the
// median, 99th percentile and worst cycle [s].
// Run: build/bench/bench_jog --benchmark_repetitions=5
#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "allocation_counter.hpp"
#include "core/live/jog.hpp"
#include "core/robot/robot.hpp"

namespace {

using namespace geotraj;

core::JogCommand cartesian(bool tool, double sign) {
  core::JogCommand c;
  core::Vector6d t;
  t << 0.5, 0.3, -0.2, 0.2, -0.3, 0.4;
  c.twist = sign * t;
  c.frame = tool ? core::JogFrame::kTool : core::JogFrame::kWorld;
  return c;
}

core::JogCommand joints(double sign) {
  core::JogCommand c;
  c.joints = core::JointVector(7);
  c.joints << 0.5, -0.4, 0.3, -0.2, 0.6, -0.5, 0.4;
  c.joints *= sign;
  return c;
}

core::JogOptions options(double rate_hz) {
  core::JogOptions o;
  o.cycle_rate_hz = rate_hz;
  return o;
}

std::string label(bool tool, double rate_hz) {
  return std::string("pa10, Cartesian, ") + (tool ? "tool frame, " : "world, ") + std::to_string(static_cast<int>(rate_hz)) +
         " Hz";
}

void BM_JogCartesian(benchmark::State& state) {
  const auto& m = *core::find_builtin_robot("pa10");
  const bool tool = state.range(0) == 1;
  const auto rate = static_cast<double>(state.range(1));
  const auto flip = static_cast<long>(rate / 2.0);
  core::Jogger jog(m, core::home_configuration(m), options(rate));
  core::JogSample s;
  jog.next(s);
  long k = 0;
  const long before = testing::allocation_count();
  for (auto _ : state) {
    if (k % flip == 0) jog.command(cartesian(tool, (k / flip) % 2 == 0 ? 1.0 : -1.0));
    jog.next(s);
    benchmark::DoNotOptimize(s);
    ++k;
  }
  state.counters["allocations_per_cycle"] =
      static_cast<double>(testing::allocation_count() - before) / static_cast<double>(std::max(1L, k));
  state.SetLabel(label(tool, rate));
}
BENCHMARK(BM_JogCartesian)->ArgsProduct({{0, 1}, {100, 1000}});

// The same, each cycle timed on its own (steady_clock, ~20 ns of overhead per cycle).
void BM_JogCartesianWorstCycle(benchmark::State& state) {
  const auto& m = *core::find_builtin_robot("pa10");
  const bool tool = state.range(0) == 1;
  const auto rate = static_cast<double>(state.range(1));
  const auto flip = static_cast<long>(rate / 2.0);
  core::Jogger jog(m, core::home_configuration(m), options(rate));
  core::JogSample s;
  std::vector<double> times;
  times.reserve(1 << 20);
  long k = 0;
  for (auto _ : state) {
    if (k % flip == 0) jog.command(cartesian(tool, (k / flip) % 2 == 0 ? 1.0 : -1.0));
    const auto start = std::chrono::steady_clock::now();
    jog.next(s);
    benchmark::DoNotOptimize(s);
    const auto stop = std::chrono::steady_clock::now();
    if (times.size() < times.capacity()) times.push_back(std::chrono::duration<double>(stop - start).count());
    ++k;
  }
  std::sort(times.begin(), times.end());
  state.counters["median_cycle"] = times[times.size() / 2];
  state.counters["p99_cycle"] = times[times.size() * 99 / 100];
  state.counters["worst_cycle"] = times.back();
  state.SetLabel(label(tool, rate) + ", per-cycle times");
}
BENCHMARK(BM_JogCartesianWorstCycle)->Args({0, 1000})->Args({1, 1000});

void BM_JogJoints(benchmark::State& state) {
  const auto& m = *core::find_builtin_robot("pa10");
  const double rate = 1000.0;
  const long flip = 500;
  core::Jogger jog(m, core::home_configuration(m), options(rate));
  core::JogSample s;
  long k = 0;
  for (auto _ : state) {
    if (k % flip == 0) jog.command(joints((k / flip) % 2 == 0 ? 1.0 : -1.0));
    jog.next(s);
    benchmark::DoNotOptimize(s);
    ++k;
  }
  state.SetLabel("pa10, joints, 1000 Hz");
}
BENCHMARK(BM_JogJoints);

}  // namespace

BENCHMARK_MAIN();
