// Sequences and blended corners (core/planning/corner_blend.hpp, planner::plan with
// PlanRequest.sequence): the cost of blending the corners of a chain of lines (each blend
// measured on the built curve), and of planning the UR5 pick-and-place chain of
// client/grpcurl/sequence_blended_ur5.json end to end (the blended chain on the exact
// time-optimal sweep within the joint limits, the joint-space pass over every sample).
// Run: build/bench/bench_sequence --benchmark_repetitions=3
#include <benchmark/benchmark.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "core/planning/corner_blend.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "planner/planner.hpp"

namespace {

using namespace geotraj;
using Eigen::Vector3d;

core::BlendLine line(const Vector3d& a, const Vector3d& b) {
  core::BlendLine l;
  l.p0 = a;
  l.p1 = b;
  return l;
}

// A zigzag of `corners` + 1 lines, every corner blended within 5 mm.
void BM_BlendChain(benchmark::State& state) {
  const auto corners = static_cast<std::size_t>(state.range(0));
  std::vector<core::BlendPiece> pieces;
  std::vector<double> tolerances(corners, 0.005);
  std::vector<std::string> names;
  for (std::size_t i = 0; i <= corners; ++i) {
    const double y0 = (i % 2 == 0) ? 0.0 : 0.1, y1 = (i % 2 == 0) ? 0.1 : 0.0;
    pieces.emplace_back(line({0.1 * static_cast<double>(i), y0, 0}, {0.1 * static_cast<double>(i + 1), y1, 0}));
    names.push_back("sequence[" + std::to_string(i) + "]");
  }
  for (auto _ : state) {
    auto chain = core::blend_chain(pieces, tolerances, names);
    if (!chain) throw std::runtime_error(chain.error().front().description);
    benchmark::DoNotOptimize(chain);
  }
  state.SetLabel(std::to_string(corners) + " corners of 5 mm");
}
BENCHMARK(BM_BlendChain)->Arg(2)->Arg(10)->Unit(benchmark::kMicrosecond);

// sequence_blended_ur5.json: a line, then three lines blended within 2 cm, as fast as the
// UR5's joints and 0.25 m/s, 1 m/s^2 allow, at 500 Hz.
void BM_PlanBlendedSequenceUr5(benchmark::State& state) {
  const core::RobotModel* model = core::find_builtin_robot("ur5");
  auto robot = std::make_shared<planner::Robot>(core::ValidRobot::check(*model).value(), core::home_configuration(*model));
  const Eigen::Quaterniond down(0, 0, 1, 0);
  const Vector3d points[] = {{-0.3, -0.25, 0.45}, {-0.3, -0.25, 0.3}, {-0.1, -0.45, 0.3}, {-0.1, -0.45, 0.45}};
  core::MotionSpec motion;
  motion.max_speed = 0.25;
  motion.max_acceleration = 1.0;
  motion.cycle_rate_hz = 500.0;
  planner::Request request;
  request.robot = robot;
  request.motion = motion;
  const Eigen::Isometry3d home = core::forward_kinematics(*model, robot->seed);
  core::ToolPose at{home.translation(), Eigen::Quaterniond(home.linear())};
  for (int i = 0; i < 4; ++i) {
    planner::Step step;
    core::ToolPose goal{points[i], down};
    step.geometry = core::LinearMoveSpec{at, goal};
    step.motion = motion;
    step.start_given = i == 0;
    step.blend_tolerance = (i == 1 || i == 2) ? 0.02 : 0.0;
    request.sequence.push_back(step);
    at = goal;
  }
  for (auto _ : state) {
    auto plan = planner::plan(request, planner::Budget{}, planner::Limits{});
    if (!plan) throw std::runtime_error("the sequence did not plan");
    benchmark::DoNotOptimize(plan);
  }
  state.SetLabel("ur5, 4 lines, 2 blended corners, time-optimal, 500 Hz");
}
BENCHMARK(BM_PlanBlendedSequenceUr5)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
