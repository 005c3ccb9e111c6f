// Whole-path redundancy resolution (optim/redundancy/redundancy.hpp) on the thesis's
// demonstration arm: the PA-10 along paths A, B and C of Table 7.18 in the thesis's 10 s at
// 100 Hz (1,001 samples), from the sample-by-sample joints (JointTracker's null-space
// term), with the acceleration criterion, the least-squares optimum alone and with the limits
// as constraints. Counters: the peak joint acceleration usage measured on the joints (second
// differences per limit) before and after, iterations, reweighting rounds.
// Run: build/bench/bench_optim_redundancy --benchmark_repetitions=3
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/trajectory.hpp"
#include "core/robot/robot.hpp"
#include "optim/redundancy/redundancy.hpp"
#include "thesis_paths.hpp"

namespace {

using namespace geotraj;

struct Streamed {
  std::vector<Eigen::Isometry3d> poses;
  std::vector<core::JointVector> joints;
  double dt = 0.0;
};

Streamed stream(const core::RobotModel& robot, char which, double rate_hz) {
  // The service's reading of the frames (the default: the smoothest), as in
  // client/grpcurl/plan_demo_path_*.json.
  const core::Path path = *core::build_path(
      testing::thesis_demo_path(which, core::BlendMethod::kPolynomial, core::UnspecifiedConstraints::kSmoothest));
  core::MotionSpec spec;
  spec.duration_s = 10.0;
  spec.cycle_rate_hz = rate_hz;
  const core::Trajectory trajectory(std::in_place_type<core::PathMotion>,
                                    core::PathMotion{path, *core::plan_motion(path, spec), *core::plan_orientation(path)});
  core::TrajectorySampler sampler(trajectory, &robot, core::home_configuration(robot));
  core::TrajectorySample s;
  Streamed out;
  out.dt = 1.0 / rate_hz;
  while (sampler.next(s)) {
    out.poses.push_back(s.tool.X_WT);
    out.joints.push_back(s.joints.q);
  }
  return out;
}

double acceleration_usage(const core::RobotModel& robot, const std::vector<core::JointVector>& q, double dt) {
  double worst = 0.0;
  for (std::size_t k = 1; k + 1 < q.size(); ++k) {
    const core::JointVector d = (q[k + 1] - 2.0 * q[k] + q[k - 1]) / (dt * dt);
    for (Eigen::Index i = 0; i < d.size(); ++i)
      worst = std::max(worst, std::abs(d(i)) / robot.limits[static_cast<std::size_t>(i)].max_acceleration);
  }
  return worst;
}

// range(0): path A, B, C; range(1): 1 with the limits as constraints (the reweighting
// rounds), 0 the least-squares optimum alone.
void BM_RedundancyPa10(benchmark::State& state) {
  const core::ValidRobot robot = *core::ValidRobot::check(*core::find_builtin_robot("pa10"));
  const char which = static_cast<char>('A' + state.range(0));
  const Streamed streamed = stream(robot, which, 100.0);
  optim::RedundancyOptions options;
  options.weights.acceleration = 1.0;
  options.within_limits = state.range(1) != 0;
  optim::RedundancyResult result;
  for (auto _ : state) {
    auto r = optim::optimize_redundancy(robot, streamed.poses, streamed.dt, streamed.joints, options);
    if (!r) {
      state.SkipWithError(r.error().front().description.c_str());
      return;
    }
    result = std::move(*r);
    benchmark::DoNotOptimize(result);
  }
  state.SetLabel(std::string("path ") + which + ", " + std::to_string(streamed.poses.size()) + " samples, " +
                 (options.within_limits ? "within limits, " : "least squares, ") + optim::name(result.report.status));
  state.counters["rounds"] = result.rounds;
  state.counters["usage_before"] = acceleration_usage(robot, streamed.joints, streamed.dt);
  state.counters["usage_after"] = acceleration_usage(robot, result.q, streamed.dt);
  state.counters["iterations"] = result.report.iterations;
}
BENCHMARK(BM_RedundancyPa10)->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
