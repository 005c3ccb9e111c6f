// Motion along a path (core/motion/motion.hpp): samples per second of MotionSampler on the
// thesis's demonstration path C (10 s move, 100 Hz and 1 kHz) for each time
// parameterization, the cost of plan_motion (with a duration, and minimum-time, which
// samples the curvature), and of a fastest joint move. Run: build/bench/bench_motion --benchmark_repetitions=5
// The items-per-second counter is samples per second on one core.
#include <benchmark/benchmark.h>

#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/planning/moves.hpp"
#include "core/robot/robot.hpp"
#include "thesis_paths.hpp"

namespace {

using namespace geotraj;

const core::Path& demo_path() {
  static const core::Path path = *core::build_path(testing::thesis_demo_path('C'));
  return path;
}

// Arguments: cycle rate [Hz], time parameterization (enum value).
void BM_MotionSampler(benchmark::State& state) {
  const auto& path = demo_path();
  core::MotionSpec spec;
  spec.duration_s = 10;
  spec.cycle_rate_hz = static_cast<double>(state.range(0));
  spec.time_parameterization = static_cast<core::TimeParameterization>(state.range(1));
  const auto plan = *core::plan_motion(path, spec);
  core::MotionSampler sampler(path, plan);
  core::MotionSample sample;
  std::size_t samples = 0;
  for (auto _ : state) {
    sampler.reset();
    while (sampler.next(sample)) {
      benchmark::DoNotOptimize(sample);
      ++samples;
    }
  }
  state.SetItemsProcessed(static_cast<int64_t>(samples));
  static const char* names[] = {"ARC_LENGTH", "LINEAR", "SMOOTH", "TAYLOR_1ST", "TAYLOR_2ND"};
  state.SetLabel(names[state.range(1)]);
}
BENCHMARK(BM_MotionSampler)
    ->ArgsProduct({{100, 1000}, {0, 1, 2, 3, 4}})
    ->Unit(benchmark::kMicrosecond);

// Argument: 0 = 10 s trapezoid (duration shared by arc length), 1 = minimum time
// trapezoid, 2 = minimum time double S.
void BM_PlanMotion(benchmark::State& state) {
  const auto& path = demo_path();
  core::MotionSpec spec;
  if (state.range(0) == 0) {
    spec.duration_s = 10;
  } else {
    spec.max_speed = 0.5;
    spec.max_acceleration = 2;
    spec.max_jerk = 20;
    if (state.range(0) == 2) spec.profile = core::ProfileShape::kSCurve;
  }
  for (auto _ : state) {
    auto plan = core::plan_motion(path, spec);
    benchmark::DoNotOptimize(plan);
  }
  static const char* names[] = {"duration 10 s", "min-time trapezoid", "min-time double S"};
  state.SetLabel(names[state.range(0)]);
}
BENCHMARK(BM_PlanMotion)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

// A rest-to-rest joint move of the PA-10 (core/planning/moves.hpp, plan_joint_move): the
// model checked, the joints checked against its limits, the fastest trapezoid (argument 0) or
// double S (1) within every joint's limits. What a call costs the caller of a joint move, to
// set beside an online generator's (Ruckig's) time for the same seven joints.
void BM_PlanJointMove(benchmark::State& state) {
  const core::RobotModel& pa10 = *core::find_builtin_robot("pa10");
  const core::JointMoveSpec move{{0.0, 0.3, 0.0, 1.2, 0.0, 0.6, 0.0}, {0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8}};
  core::MotionSpec motion;
  motion.duration_s = 0.0;
  if (state.range(0) == 1) motion.profile = core::ProfileShape::kSCurve;
  const core::RobotModel model = state.range(0) == 1 ? core::with_default_jerk(pa10) : pa10;
  for (auto _ : state) {
    auto plan = core::plan_joint_move(model, move, motion);
    benchmark::DoNotOptimize(plan);
  }
  state.SetLabel(state.range(0) == 0 ? "PA-10, fastest trapezoid" : "PA-10, fastest double S");
}
BENCHMARK(BM_PlanJointMove)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
