// Motion along a path (core/motion/motion.hpp): samples per second of MotionSampler on the
// thesis's demonstration path C (10 s move, 100 Hz and 1 kHz) for each time
// parameterization, the cost of plan_motion (with a duration, and minimum-time, which
// samples the curvature), and of a fastest joint move, beside Ruckig's offline calculation of
// the same move when built with -DGEOTRAJ_RUCKIG_SOURCE_DIR (docs/performance.md, "Peers in
// one process"). Run: build/bench/bench_motion --benchmark_repetitions=5
// The items-per-second counter is samples per second on one core.
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>

#include <benchmark/benchmark.h>
#if GEOTRAJ_BENCH_RUCKIG
#include <ruckig/ruckig.hpp>
#endif

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

// Every sample of `plan` on `path`, once per iteration; items: samples.
void sample_all(benchmark::State& state, const core::Path& path, const core::MotionPlan& plan) {
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
}

// Arguments: cycle rate [Hz], time parameterization (enum value).
void BM_MotionSampler(benchmark::State& state) {
  const auto& path = demo_path();
  core::MotionSpec spec;
  spec.duration_s = 10;
  spec.cycle_rate_hz = static_cast<double>(state.range(0));
  spec.time_parameterization = static_cast<core::TimeParameterization>(state.range(1));
  sample_all(state, path, *core::plan_motion(path, spec));
  static const char* names[] = {"ARC_LENGTH", "LINEAR", "SMOOTH", "TAYLOR_1ST", "TAYLOR_2ND"};
  state.SetLabel(names[state.range(1)]);
}
BENCHMARK(BM_MotionSampler)
    ->ArgsProduct({{100, 1000}, {0, 1, 2, 3, 4}})
    ->Unit(benchmark::kMicrosecond);

// A path of pieces sampled as the key frames' path C is above (1 kHz, arc length): the weld
// seam with transitions (line, quarter arc, line; 3 pieces, 2 transitions) in 2 s, and 100
// turns of a helix between two lines in 60 s. Argument: 0 = seam, 1 = helix.
void BM_MotionSamplerPieces(benchmark::State& state) {
  constexpr double kPi = 3.141592653589793;
  core::PathSpec spec;
  core::KeyFrame start;
  start.N_W = Eigen::Vector3d::UnitY();
  spec.start = start;
  spec.transition_tolerance = 1e-4;
  core::PathPiece line, curved;
  line.length_m = state.range(0) == 0 ? 0.1 : 0.05;
  if (state.range(0) == 0) {
    curved.shape = core::PieceShape::kArc;
    curved.radius = 0.04;
    curved.length_m = 0.5 * kPi * 0.04;
  } else {
    curved.shape = core::PieceShape::kHelix;
    curved.radius = 0.05;
    curved.pitch = 0.02;
    curved.length_m = 100.0 * 2.0 * kPi * std::hypot(0.05, 0.02 / (2.0 * kPi));
  }
  spec.pieces = {line, curved, line};
  const auto path = *core::build_path(spec);
  core::MotionSpec motion;
  motion.duration_s = state.range(0) == 0 ? 2.0 : 60.0;
  motion.cycle_rate_hz = 1000;
  sample_all(state, path, *core::plan_motion(path, motion));
  state.SetLabel(state.range(0) == 0 ? "seam" : "100-turn helix");
}
BENCHMARK(BM_MotionSamplerPieces)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

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
// Joints 0 and 1 are the tightest in velocity, acceleration and jerk (normalised by their
// travel), so the straight line in joint space is also the synchronised time-optimal move:
// the counter duration_s [s] must match Ruckig's.
constexpr std::size_t kMoveJoints = 7;
const core::JointMoveSpec& pa10_move() {
  static const core::JointMoveSpec move{{0.0, 0.3, 0.0, 1.2, 0.0, 0.6, 0.0}, {0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8}};
  return move;
}

// The PA-10 as the move sees it: its own limits (argument 0, no jerk limit), or with the
// default jerk bound of every joint (1: max_acceleration / kDefaultJerkRampS).
// Checked once, as where a model enters the service (core::ValidRobot).
const core::ValidRobot& pa10_for_move(bool jerk) {
  static const core::ValidRobot plain = core::ValidRobot::check(*core::find_builtin_robot("pa10")).value();
  static const core::ValidRobot with_jerk = core::with_default_jerk(plain);
  return jerk ? with_jerk : plain;
}

const char* move_label(bool jerk) { return jerk ? "PA-10, fastest double S" : "PA-10, fastest trapezoid"; }

void BM_PlanJointMove(benchmark::State& state) {
  const bool jerk = state.range(0) == 1;
  const core::ValidRobot& model = pa10_for_move(jerk);
  core::MotionSpec motion;
  motion.duration_s = 0.0;
  if (jerk) motion.profile = core::ProfileShape::kSCurve;
  for (auto _ : state) {
    auto plan = core::plan_joint_move(model, pa10_move(), motion);
    benchmark::DoNotOptimize(plan);
  }
  const auto plan = core::plan_joint_move(model, pa10_move(), motion);
  if (!plan) state.SkipWithError("plan_joint_move failed");
  state.counters["duration_s"] = plan ? plan->duration_s : 0.0;
  state.SetLabel(move_label(jerk));
}
BENCHMARK(BM_PlanJointMove)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

#if GEOTRAJ_BENCH_RUCKIG
// The same move by Ruckig's offline calculation (Ruckig<7>::calculate: the input checked, every
// joint's time-optimal profile, the synchronisation), from rest to rest with the same
// per-joint limits: the trapezoid with an infinite jerk limit (Ruckig's second-order
// profiles), the double S with the same jerk bounds. Arguments: profile (0 trapezoid, 1
// double S), Ruckig's synchronisation (0 Time, its default: every joint on its own profile
// shape, finishing together; 1 Phase: one shape scaled, a straight line in joint space as
// plan_joint_move's).
void BM_RuckigJointMove(benchmark::State& state) {
  const bool jerk = state.range(0) == 1;
  const core::RobotModel& model = pa10_for_move(jerk);
  ruckig::Ruckig<kMoveJoints> otg;
  ruckig::InputParameter<kMoveJoints> input;
  for (std::size_t i = 0; i < kMoveJoints; ++i) {
    input.current_position[i] = pa10_move().start[i];
    input.target_position[i] = pa10_move().goal[i];
    input.max_velocity[i] = model.limits[i].max_velocity;
    input.max_acceleration[i] = model.limits[i].max_acceleration;
    input.max_jerk[i] = jerk ? core::jerk_bound(model.limits[i]) : std::numeric_limits<double>::infinity();
  }
  input.synchronization = state.range(1) == 1 ? ruckig::Synchronization::Phase : ruckig::Synchronization::Time;
  ruckig::Trajectory<kMoveJoints> trajectory;
  for (auto _ : state) {
    const ruckig::Result result = otg.calculate(input, trajectory);
    benchmark::DoNotOptimize(result);
    benchmark::DoNotOptimize(trajectory);
  }
  if (otg.calculate(input, trajectory) != ruckig::Result::Working) state.SkipWithError("Ruckig found no trajectory");
  state.counters["duration_s"] = trajectory.get_duration();
  state.SetLabel(std::string(move_label(jerk)) + (state.range(1) == 1 ? ", Ruckig, phase sync" : ", Ruckig, time sync"));
}
BENCHMARK(BM_RuckigJointMove)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMicrosecond);
#endif

}  // namespace

BENCHMARK_MAIN();
