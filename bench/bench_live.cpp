// Live execution (core/live/execution.hpp) and its 1-D building block (rate_profile.hpp): what
// Execute spends per call and per controller cycle. The plans are the grpcurl examples planned
// as Execute plans them (request_input_from_proto, planner::admit; jerk-limited timing for a robot with jerk
// limits; planner::reserve_room with the default reserve 0.1; planner::plan for a stream),
// both timed by the robot's limits: the PA-10 along the thesis's path C
// (client/grpcurl/plan_pa10_path_c.json with durationS 0, time-optimal, and without its
// reportOnly, which Execute refuses: its 10 s trapezoid breaks the PA-10's acceleration
// limits) and the Panda along path C (client/grpcurl/plan_panda_path_c.json: time-optimal
// within its jerk limits, with the joint approach from home).
//   BM_LiveStart         LiveExecution::start: the peaks pass (the plan sampled with IK at the
//                        check rate, 2 kHz) and the speed factor's bounds; per call.
//   BM_LiveNext          LiveExecution::next, one set point: at full speed (arg 0) and with
//                        every cycle inside a speed change (arg 1: the override flips between
//                        100 % and 40 % whenever the speed factor reaches it); cycle rate arg 2.
//                        The plan restarts, untimed, when it completes.
//   BM_LiveNextCycles    the same, each cycle timed on its own (steady_clock, ~20 ns of overhead
//                        per cycle): median, 99th percentile and worst cycle [s].
//   BM_RateProfilePlan   RateProfile::plan over 1,024 random (v0, a0, v1, a_max, j_max).
//   BM_JogIntoLimitCycles Jogger::next while a Panda joint at full speed brakes for its position
//                        limit (the bisection for the braking moment: the jog's costliest cycle),
//                        per-cycle times; bench_jog has the free joint and Cartesian jogs.
// Counters: allocations (allocation_counter, tests/support): per cycle over the whole loop
// (restarts excluded), and in the per-cycle variants the cycles in which next() allocated and
// the plan time of the first; the plan time of the worst cycle.
// Run: build/bench/bench_live --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "allocation_counter.hpp"
#include "core/live/execution.hpp"
#include "core/live/jog.hpp"
#include "core/live/rate_profile.hpp"
#include "core/robot/robot.hpp"
#include "planner/planner.hpp"
#include "planner/robots.hpp"
#include "server/wire/convert.hpp"

namespace {

using namespace geotraj;
using Clock = std::chrono::steady_clock;

// --- the plans, as Execute makes them --------------------------------------------------------

struct LivePlan {
  planner::Plan plan;
  const core::RobotModel* model = nullptr;
  core::JointVector seed;
  core::MotionSpec motion;  // whose cycle rate and Cartesian limits live execution keeps
};

enum Arm { kPa10 = 0, kPanda = 1 };

const char* arm_name(long arm) { return arm == kPa10 ? "pa10, path C" : "panda, path C"; }

// Planned once per (arm, cycle rate) and kept: a live execution refers to its plan.
const LivePlan& live_plan(long arm, double cycle_hz) {
  static std::map<std::pair<long, double>, std::unique_ptr<LivePlan>> plans;
  auto& slot = plans[{arm, cycle_hz}];
  if (slot) return *slot;
  const std::string file = std::string(GEOTRAJ_SOURCE_DIR) + "/client/grpcurl/" +
                           (arm == kPa10 ? "plan_pa10_path_c.json" : "plan_panda_path_c.json");
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  v1::PlanRequest request;
  if (!in || !google::protobuf::util::JsonStringToMessage(text.str(), &request).ok()) {
    throw std::runtime_error("cannot read " + file);
  }
  request.mutable_robot()->set_report_only(false);  // Execute keeps the limits
  request.mutable_motion()->set_duration_s(0.0);      // timed by the limits (the Panda's is already)
  request.mutable_motion()->set_cycle_rate_hz(cycle_hz);
  const server::RobotCatalog catalog{planner::builtin_robots()};
  auto input = planner::admit(server::request_input_from_proto(request, server::ServiceLimits{}), catalog, planner::Use::kStream);
  if (!input) throw std::runtime_error(file + ": " + input.error().front().description);
  planner::reserve_room(*input, 0.1);  // as Execute, with ExecuteOptions.accelerationReserve's default
  auto planned = planner::plan(*input, planner::Budget{}, planner::Limits{}, planner::Use::kStream);
  if (!planned) throw std::runtime_error(file + ": not planned");
  slot = std::make_unique<LivePlan>();
  slot->plan = std::move(*planned);
  slot->model = slot->plan.robot ? &slot->plan.robot->model.model() : nullptr;
  slot->seed = slot->plan.robot ? slot->plan.robot->seed : core::JointVector();
  slot->motion = core::motion_spec(*slot->plan.trajectory);
  return *slot;
}

core::LiveExecution start(const LivePlan& p) {
  auto live = core::LiveExecution::start(*p.plan.trajectory, p.model, p.seed, core::live_limits(p.model),
                                         p.motion.cycle_rate_hz);
  if (!live) throw std::runtime_error(live.error().front().description);
  return std::move(*live);
}

// --- LiveExecution::start ---------------------------------------------------------------------

void BM_LiveStart(benchmark::State& state) {
  const LivePlan& p = live_plan(state.range(0), 1000.0);
  for (auto _ : state) {
    auto live = start(p);
    benchmark::DoNotOptimize(live);
  }
  auto live = start(p);
  const core::FactorBounds b = live.bounds(1.0);
  const core::StopPrediction stop = core::predict_stop(1.0, 0.0, b);
  state.counters["plan_s"] = live.plan_duration();
  state.counters["check_samples"] = std::ceil(live.plan_duration() * 2000.0) + 1.0;  // 2 kHz from 1 kHz
  state.counters["factor_acceleration"] = b.acceleration;
  state.counters["factor_jerk"] = b.jerk;
  state.counters["stop_from_full_s"] = stop.time_s;
  state.SetLabel(std::string(arm_name(state.range(0))) + ", 1000 Hz; binding " +
                 live.rows()[b.acceleration_row].name);
}
BENCHMARK(BM_LiveStart)->Arg(kPa10)->Arg(kPanda)->Unit(benchmark::kMillisecond);

// --- LiveExecution::next ----------------------------------------------------------------------

// One cycle of the script: at arg 1, flip the override whenever the speed factor has reached it.
void drive(core::LiveExecution& live, bool changing, const core::LiveSample& s) {
  if (changing && s.speed_factor == live.override_fraction()) {
    live.set_override(live.override_fraction() == 1.0 ? 0.4 : 1.0);
  }
}

std::string next_label(const benchmark::State& state) {
  return std::string(arm_name(state.range(0))) + (state.range(1) == 1 ? ", inside a speed change" : ", full speed") +
         ", " + std::to_string(state.range(2)) + " Hz";
}

void BM_LiveNext(benchmark::State& state) {
  const LivePlan& p = live_plan(state.range(0), static_cast<double>(state.range(2)));
  const bool changing = state.range(1) == 1;
  auto live = start(p);
  core::LiveSample s;
  long cycles = 0, restart_allocations = 0;
  const long before = testing::allocation_count();
  for (auto _ : state) {
    if (!live.next(s)) {
      state.PauseTiming();
      const long restart = testing::allocation_count();
      live = start(p);
      restart_allocations += testing::allocation_count() - restart;
      state.ResumeTiming();
      continue;
    }
    drive(live, changing, s);
    benchmark::DoNotOptimize(s);
    ++cycles;
  }
  const long allocations = testing::allocation_count() - before - restart_allocations;
  state.counters["allocations_per_cycle"] =
      static_cast<double>(allocations) / static_cast<double>(std::max(1L, cycles));
  state.SetLabel(next_label(state));
}

void BM_LiveNextCycles(benchmark::State& state) {
  const LivePlan& p = live_plan(state.range(0), static_cast<double>(state.range(2)));
  const bool changing = state.range(1) == 1;
  auto live = start(p);
  core::LiveSample s;
  std::vector<double> times;
  times.reserve(1 << 20);
  long allocating = 0;           // cycles in which next() allocated
  double first_allocation = -1;  // the plan time of the first such cycle [s]
  double worst = 0.0, worst_tau = 0.0;  // the slowest cycle [s] and its plan time [s]
  for (auto _ : state) {
    const long before = testing::allocation_count();
    const auto t0 = Clock::now();
    const bool more = live.next(s);
    const auto t1 = Clock::now();
    if (testing::allocation_count() != before && more) {
      ++allocating;
      if (first_allocation < 0) first_allocation = s.plan_time;
    }
    if (!more) {
      state.PauseTiming();
      live = start(p);
      state.ResumeTiming();
      continue;
    }
    drive(live, changing, s);
    benchmark::DoNotOptimize(s);
    const double time = std::chrono::duration<double>(t1 - t0).count();
    if (time > worst) {
      worst = time;
      worst_tau = s.plan_time;
    }
    if (times.size() < times.capacity()) times.push_back(time);
  }
  state.counters["allocating_cycles"] = static_cast<double>(allocating);
  state.counters["first_allocation_tau"] = first_allocation;
  state.counters["worst_cycle_tau"] = worst_tau;
  std::sort(times.begin(), times.end());
  if (!times.empty()) {
    state.counters["median_cycle"] = times[times.size() / 2];
    state.counters["p99_cycle"] = times[times.size() * 99 / 100];
    state.counters["worst_cycle"] = times.back();
  }
  state.SetLabel(next_label(state) + ", per-cycle times");
}

void next_args(benchmark::internal::Benchmark* b) {
  for (long arm : {kPa10, kPanda}) {
    for (long changing : {0, 1}) {
      for (long rate : {100, 1000}) b->Args({arm, changing, rate});
    }
  }
}
BENCHMARK(BM_LiveNext)->Apply(next_args);
BENCHMARK(BM_LiveNextCycles)->Apply(next_args);

// --- RateProfile::plan ------------------------------------------------------------------------

void BM_RateProfilePlan(benchmark::State& state) {
  struct Case {
    double v0, a0, v1, a_max, j_max;
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Case> cases(1024);
  for (Case& c : cases) {  // as tests/core/live/execution_test.cpp's random changes
    const double a_max = 0.1 + 5.0 * std::abs(u(rng));
    const double j_max = 0.5 + 50.0 * std::abs(u(rng));
    const double v0 = u(rng), v1 = u(rng), a0 = a_max * u(rng);
    c = {v0, a0, v1, a_max, j_max};
  }
  std::size_t k = 0;
  for (auto _ : state) {
    const Case& c = cases[k++ & 1023];
    const core::RateProfile p = core::RateProfile::plan(c.v0, c.a0, c.v1, c.a_max, c.j_max);
    benchmark::DoNotOptimize(p);
  }
  state.SetLabel("random (v0, a0, v1, a_max, j_max), fixed seed");
}
BENCHMARK(BM_RateProfilePlan);

// RateProfile::at, the other half of a cycle's speed change.
void BM_RateProfileAt(benchmark::State& state) {
  const core::RateProfile p = core::RateProfile::plan(1.0, 0.0, 0.0, 0.36, 1574.0);
  double t = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(p.at(t));
    t += 1e-3;
    if (t > p.duration()) t = 0.0;
  }
  state.SetLabel("the Panda's stop from full speed, 1 ms steps");
}
BENCHMARK(BM_RateProfileAt);

// --- Jogger::next at a position limit -----------------------------------------------------------

// The Panda's joint 4 (home -2.356 rad, limits [-3.0718, -0.0698] rad) at full speed, back and
// forth between its limits: most cycles cruise, and about 0.18 s per crossing brakes for a limit.
void BM_JogIntoLimitCycles(benchmark::State& state) {
  const core::RobotModel& m = *planner::find_builtin_robot("panda");  // URDF-built: the planner's catalogue
  const Eigen::Index joint = 3;
  const auto rate = static_cast<double>(state.range(0));
  core::JogOptions options;
  options.cycle_rate_hz = rate;
  options.velocity_scale = 1.0;  // command 1 = max_velocity (2.175 rad/s)
  core::Jogger jog(m, core::home_configuration(m), options);
  core::JogCommand command;
  command.joints = core::JointVector::Zero(7);
  double direction = 1.0;
  command.joints(joint) = direction;
  jog.command(command);
  core::JogSample s;
  std::vector<double> braking, cruising;
  braking.reserve(1 << 20);
  cruising.reserve(1 << 20);
  long cycles = 0;
  long allocating = 0, first_allocation = -1;  // cycles in which next() allocated; the first's index
  for (auto _ : state) {
    const long before_cycle = testing::allocation_count();
    const auto t0 = Clock::now();
    jog.next(s);
    const auto t1 = Clock::now();
    if (testing::allocation_count() != before_cycle) {
      ++allocating;
      if (first_allocation < 0) first_allocation = cycles;
    }
    ++cycles;
    auto& times = s.limited[joint] ? braking : cruising;
    if (times.size() < times.capacity()) times.push_back(std::chrono::duration<double>(t1 - t0).count());
    if (s.limited[joint] && s.at_rest) {  // on the limit: turn back
      direction = -direction;
      command.joints(joint) = direction;
      jog.command(command);
    }
  }
  const auto report = [&](std::vector<double>& times, const std::string& name) {
    if (times.empty()) return;
    std::sort(times.begin(), times.end());
    state.counters[name + "_median"] = times[times.size() / 2];
    state.counters[name + "_p99"] = times[times.size() * 99 / 100];
    state.counters[name + "_worst"] = times.back();
  };
  report(braking, "braking");
  report(cruising, "cruising");
  const std::size_t all = std::max<std::size_t>(1, braking.size() + cruising.size());
  state.counters["braking_share"] = static_cast<double>(braking.size()) / static_cast<double>(all);
  state.counters["allocating_cycles"] = static_cast<double>(allocating);
  state.counters["first_allocating_cycle"] = static_cast<double>(first_allocation);
  state.SetLabel("panda joint 4 at velocityScale 1, limit to limit, " + std::to_string(state.range(0)) +
                 " Hz, per-cycle times");
}
BENCHMARK(BM_JogIntoLimitCycles)->Arg(100)->Arg(1000);

}  // namespace

BENCHMARK_MAIN();
