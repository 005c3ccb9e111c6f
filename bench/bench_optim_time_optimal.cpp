// Time-optimal timing of the PA-10 along the thesis's demo path C: the exact sweep given the
// grid data (100 and 1,000 grid intervals per portion), the grid construction (IK at every
// grid point), and the jerk-limited NLP (100 and 1,000 intervals; joint jerk limits of
// 4 a_max; counters: iterations, its duration and the exact one [s]) with the default solver
// (BM_JerkNlp: the banded interior point method, Ipopt only as its fallback) and with Ipopt
// forced (BM_JerkNlpIpopt, JerkSolver::kIpopt). Per-portion figures;
// demo path C has two portions (a cusp at frame 2). BM_JerkPlan: the whole jerk-limited plan
// end to end (grids, exact sweep with its sample check, the NLP on both portions, the sample
// check of the result and its re-solves; 200 intervals per portion, 100 Hz).
#include <string>

#include <benchmark/benchmark.h>

#include "core/geometry/path.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/time_optimal.hpp"
#include "optim/timing/time_optimal_jerk.hpp"
#include "thesis_paths.hpp"

namespace {

using namespace geotraj;

struct Setup {
  core::Path path;
  core::OrientationPlan orientation;
  core::RobotModel robot = *core::find_builtin_robot("pa10");
  core::MotionPlan portions;
  Setup() {
    path = *core::build_path(testing::thesis_demo_path('C'));
    orientation = *core::plan_orientation(path);
    core::MotionSpec m;
    m.duration_s = 1.0;
    portions = *core::plan_motion(path, m);
  }
  std::vector<std::vector<core::GridPoint>> grids(std::size_t n) const {
    return *core::time_optimal_grids(path, orientation, portions.portions, &robot, core::home_configuration(robot), n);
  }
};

const Setup& setup() {
  static const Setup s;
  return s;
}

void BM_Sweep(benchmark::State& state) {
  const auto grids = setup().grids(static_cast<std::size_t>(state.range(0)));
  const auto lim = core::time_optimal_limits(core::MotionSpec{}, &setup().robot);
  for (auto _ : state) {
    auto sol = core::solve_time_optimal(grids[0], lim);
    benchmark::DoNotOptimize(sol);
  }
}
BENCHMARK(BM_Sweep)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);

void BM_Grid(benchmark::State& state) {
  for (auto _ : state) {
    auto g = setup().grids(static_cast<std::size_t>(state.range(0)));
    benchmark::DoNotOptimize(g);
  }
}
BENCHMARK(BM_Grid)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond);

void jerk_nlp(benchmark::State& state, optim::JerkSolver solver) {
  const auto grids = setup().grids(static_cast<std::size_t>(state.range(0)));
  core::RobotModel robot = setup().robot;
  const auto lim = core::time_optimal_limits(core::MotionSpec{}, &robot);
  const auto exact = *core::solve_time_optimal(grids[0], lim);
  optim::JerkTimingOptions opt;
  opt.joint_jerk.resize(7);
  for (int j = 0; j < 7; ++j) opt.joint_jerk(j) = 4.0 * lim.joint_acceleration(j);
  opt.time_budget_s = 60.0;
  opt.solver = solver;
  optim::JerkTiming r;
  for (auto _ : state) {
    r = optim::optimise_jerk_timing(grids[0], lim, exact, opt);
    benchmark::DoNotOptimize(r);
  }
  if (r.report.status != optim::OptimizerStatus::kConverged) state.SkipWithError(r.report.message.c_str());
  state.counters["iterations"] = r.report.iterations;
  state.counters["duration_s"] = r.duration;
  state.counters["exact_s"] = exact.duration;
  // 1 when Ipopt ran (forced, or as the banded method's fallback).
  state.counters["ipopt"] = r.report.message.find("Ipopt") != std::string::npos ? 1 : 0;
}
void BM_JerkNlp(benchmark::State& state) { jerk_nlp(state, optim::JerkSolver::kAuto); }
void BM_JerkNlpIpopt(benchmark::State& state) { jerk_nlp(state, optim::JerkSolver::kIpopt); }
BENCHMARK(BM_JerkNlp)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond)->Iterations(1)->Repetitions(5);
BENCHMARK(BM_JerkNlpIpopt)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond)->Iterations(1)->Repetitions(5);

void BM_JerkPlan(benchmark::State& state) {
  core::RobotModel robot = setup().robot;
  for (auto& l : robot.limits) l.max_jerk = 4.0 * l.max_acceleration;
  core::MotionSpec spec;
  spec.cycle_rate_hz = 100.0;
  optim::JerkTimingOptions opt;
  opt.time_budget_s = 60.0;
  core::Expected<optim::JerkLimitedPlan> r;
  for (auto _ : state) {
    r = optim::plan_time_optimal_jerk(setup().path, setup().orientation, spec, &robot,
                                      core::home_configuration(robot), optim::jerk_exact_options(), opt);
    benchmark::DoNotOptimize(r);
  }
  if (!r) {
    state.SkipWithError(r.error()[0].description.c_str());
    return;
  }
  state.counters["iterations"] = r->report.iterations;
  state.counters["refinements"] = r->refinements;
  state.counters["duration_s"] = r->motion.duration_s;
}
BENCHMARK(BM_JerkPlan)->Unit(benchmark::kMillisecond)->Iterations(1)->Repetitions(5);

}  // namespace

BENCHMARK_MAIN();
