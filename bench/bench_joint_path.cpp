// Joint paths through waypoints (core/planning/joint_path.hpp, optim/timing/joint_path_jerk.hpp)
// on the Panda, against Kunz and Stilman's time-optimal trajectory generation (their public
// code, the algorithm of MoveIt's time-optimal trajectory generation) when its source folder
// is given (GEOTRAJ_KUNZ_SOURCE_DIR, docs/performance.md): the same waypoints, the same
// velocity and acceleration limits and the same deviation at the waypoints (theirs: the
// circular blend's distance from the waypoint; ours: the G2 blend's). Each benchmark plans
// from the waypoints (path and timing; ours includes the sample check at 2 kHz) and reports,
// from samples at 1 kHz, the duration [s], the largest step of a joint acceleration between
// samples as a fraction of its limit (acc_step), and the largest velocity and acceleration by
// differences of the positions as a fraction of their limits (v_usage, a_usage: above 1 is a
// limit exceeded).
#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "core/planning/joint_path.hpp"
#include "optim/timing/joint_path_jerk.hpp"
#include "planner/robots.hpp"

#ifdef GEOTRAJ_BENCH_KUNZ
#include <list>

#include "Path.h"
#include "Trajectory.h"
#endif

namespace {

using namespace geotraj;
using Waypoints = std::vector<std::vector<double>>;

const core::ValidRobot& panda() {
  static const core::ValidRobot robot = *core::ValidRobot::check(*planner::find_builtin_robot("panda"));
  return robot;
}

// 0: nine waypoints of a pick and place (client/grpcurl/plan_joint_path_panda.json); 1:
// eight waypoints drawn within the middle half of the limits; 2: 200 small steps (a dense
// sampling planner's output, 0.05 rad apart on a random walk).
const Waypoints& waypoints(long set) {
  static const std::vector<Waypoints> sets = [] {
    std::vector<Waypoints> out(3);
    out[0] = {{0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785},   {0.35, -0.45, 0.1, -2.2, 0.05, 1.8, 1.1},
              {0.42, -0.1, 0.12, -2.35, 0.02, 2.25, 1.2},      {0.42, 0.05, 0.12, -2.45, 0.02, 2.5, 1.2},
              {0.3, -0.3, 0.05, -2.3, 0.0, 2.0, 1.0},          {-0.3, -0.35, -0.05, -2.25, 0.0, 1.95, 0.4},
              {-0.45, 0.0, -0.1, -2.4, -0.02, 2.4, 0.3},       {-0.3, -0.4, -0.05, -2.2, 0.0, 1.85, 0.5},
              {0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785}};
    std::mt19937 rng(2024);
    const auto& limits = panda()->limits;
    for (int i = 0; i < 8; ++i) {
      std::vector<double> w;
      for (const auto& l : limits) {
        const double mid = 0.5 * (l.min_position + l.max_position), half = 0.25 * (l.max_position - l.min_position);
        w.push_back(std::uniform_real_distribution<double>(mid - half, mid + half)(rng));
      }
      out[1].push_back(w);
    }
    std::vector<double> q = out[0][0];
    std::normal_distribution<double> step(0.0, 1.0);
    for (int i = 0; i < 200; ++i) {
      out[2].push_back(q);
      std::vector<double> d(q.size());
      double norm = 0.0;
      for (double& x : d) x = step(rng), norm += x * x;
      for (std::size_t j = 0; j < q.size(); ++j) {
        const auto& l = limits[j];
        q[j] = std::clamp(q[j] + 0.05 * d[j] / std::sqrt(norm), l.min_position + 0.1, l.max_position - 0.1);
      }
    }
    return out;
  }();
  return sets[static_cast<std::size_t>(set)];
}

// The figures of a motion given by its positions at 1 kHz.
void count(benchmark::State& state, double duration, const std::function<Eigen::VectorXd(double)>& position) {
  const auto& limits = panda()->limits;
  const double h = 1e-3;
  const auto n = static_cast<std::size_t>(std::floor(duration / h));
  std::vector<Eigen::VectorXd> q;
  for (std::size_t k = 0; k <= n; ++k) q.push_back(position(static_cast<double>(k) * h));
  double v_usage = 0.0, a_usage = 0.0, step = 0.0;
  Eigen::VectorXd a_prev;
  for (std::size_t k = 1; k + 1 < q.size(); ++k) {
    const Eigen::VectorXd a = (q[k + 1] - 2.0 * q[k] + q[k - 1]) / (h * h);
    for (Eigen::Index j = 0; j < a.size(); ++j) {
      const auto& l = limits[static_cast<std::size_t>(j)];
      v_usage = std::max(v_usage, std::abs(q[k + 1](j) - q[k](j)) / h / l.max_velocity);
      a_usage = std::max(a_usage, std::abs(a(j)) / l.max_acceleration);
      if (a_prev.size() > 0) step = std::max(step, std::abs(a(j) - a_prev(j)) / l.max_acceleration);
    }
    a_prev = a;
  }
  state.counters["duration_s"] = duration;
  state.counters["v_usage"] = v_usage;
  state.counters["a_usage"] = a_usage;
  state.counters["acc_step"] = step;
}

core::JointPathSpec spec_of(long set, double deviation) {
  core::JointPathSpec spec;
  spec.blend_tolerance = deviation;
  for (const auto& w : waypoints(set)) spec.waypoints.push_back({w, false});
  return spec;
}

core::MotionSpec fastest() {
  core::MotionSpec m;
  m.cycle_rate_hz = 1000.0;
  return m;
}

Eigen::VectorXd at(const core::JointPathPlan& plan, double t) {
  core::MoveSample s;
  core::ProfileCursor cursor;
  std::size_t hint = 0;
  core::joint_path_at(plan, t, cursor, hint, s);
  return Eigen::VectorXd(s.q);
}

// The sets and deviations [cm of rad] both libraries plan.
void every_set(benchmark::internal::Benchmark* b) {
  b->ArgNames({"set", "dev_cm"})->Args({0, 5})->Args({0, 10})->Args({1, 5})->Args({1, 10})->Args({2, 5});
  b->Unit(benchmark::kMillisecond);
}

// Plans the set and deviation of the benchmark's arguments from its waypoints (the path,
// then `time`) at every iteration, and reports the last plan's figures.
void plan_each_iteration(benchmark::State& state,
                         const std::function<core::Expected<core::JointPathPlan>(core::JointPath)>& time) {
  const core::JointPathSpec spec = spec_of(state.range(0), static_cast<double>(state.range(1)) / 100.0);
  std::optional<core::JointPathPlan> plan;
  for (auto _ : state) {
    auto timed = time(*core::build_joint_path(panda(), spec));
    if (!timed) {
      state.SkipWithError(timed.error().front().description.c_str());
      return;
    }
    plan = std::move(*timed);
    benchmark::DoNotOptimize(plan->duration_s);
  }
  count(state, plan->duration_s, [&](double t) { return at(*plan, t); });
  state.counters["refinements"] = plan->refinements;
  state.counters["grid_points"] = static_cast<double>(plan->grid_points);
}

// geotraj's time-optimal sweep (G2 blends; the sample check at 2 kHz included).
void BM_GeotrajJointPath(benchmark::State& state) {
  plan_each_iteration(state, [](core::JointPath path) { return core::plan_joint_path(panda(), std::move(path), fastest()); });
}
BENCHMARK(BM_GeotrajJointPath)->Apply(every_set);

// geotraj's jerk-limited timing under the Panda's jerk limits (acceleration continuous).
void BM_GeotrajJointPathJerk(benchmark::State& state) {
  plan_each_iteration(state, [](core::JointPath path) -> core::Expected<core::JointPathPlan> {
    auto timed = optim::plan_joint_path_jerk(core::with_default_jerk(panda()), std::move(path), fastest());
    if (!timed) return tl::make_unexpected(timed.error());
    return std::move(timed->plan);
  });
}
BENCHMARK(BM_GeotrajJointPathJerk)
    ->ArgNames({"set", "dev_cm"})
    ->Args({0, 5})
    ->Args({1, 5})
    ->Unit(benchmark::kMillisecond);

#ifdef GEOTRAJ_BENCH_KUNZ
// Kunz and Stilman's time-optimal trajectory generation at its default 1 ms step.
void BM_KunzStilman(benchmark::State& state) {
  const double deviation = static_cast<double>(state.range(1)) / 100.0;
  std::list<Eigen::VectorXd> points;
  for (const auto& w : waypoints(state.range(0))) points.push_back(Eigen::Map<const Eigen::VectorXd>(w.data(), 7));
  Eigen::VectorXd v(7), a(7);
  for (std::size_t j = 0; j < 7; ++j) {
    v(static_cast<Eigen::Index>(j)) = panda()->limits[j].max_velocity;
    a(static_cast<Eigen::Index>(j)) = panda()->limits[j].max_acceleration;
  }
  std::optional<Trajectory> trajectory;
  for (auto _ : state) {
    trajectory.emplace(Path(points, deviation), v, a, 1e-3);
    if (!trajectory->isValid()) {
      state.SkipWithError("their trajectory generation failed");
      return;
    }
    benchmark::DoNotOptimize(trajectory->getDuration());
  }
  count(state, trajectory->getDuration(), [&](double t) { return trajectory->getPosition(t); });
}
BENCHMARK(BM_KunzStilman)->Apply(every_set);
#endif

}  // namespace

BENCHMARK_MAIN();
