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
//
// And against TOPP-RA (Pham and Pham's reachability analysis, its C++ version) when its
// source folder is given (GEOTRAJ_TOPPRA_SOURCE_DIR): with the seidel solver, the joint
// velocity and acceleration constraints (the latter by interpolation, their default) and the
// constant-acceleration parametrizer, (1) on a cubic spline through the waypoints, as its
// users give it a path (it passes every waypoint but not their polyline: q_excess and
// off_polyline say how far it strays), and (2) on geotraj's own path, handed over as a
// cubic Hermite spline through q(sigma) and q'(sigma) at the points of geotraj's grid, so
// that both time the same path.
//
// Within joint torques (BM_GeotrajJointPathTorque, BM_ToppraGeotrajPathTorque): the Panda
// carrying its rated 3 kg (5 cm out along the tool) with its shoulder (joint 1) limited
// (shoulder_Nm) so that the torque binds; geotraj's sweep with its torque rows (three
// inverse-dynamics calls per grid point) against TOPP-RA's JointTorque constraint (its
// computeInverseDynamics given our recursive Newton-Euler on the same model, interpolated as
// its acceleration constraint), on geotraj's path and grid as in (2). tau_usage: the largest
// |tau| / maxTorque over samples at 1 kHz (inverse dynamics of each library's own q, q_dot,
// q_ddot; above 1 is a limit exceeded).
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "core/planning/joint_path.hpp"
#include "core/robot/dynamics.hpp"
#include "optim/timing/joint_path_jerk.hpp"
#include "planner/robots.hpp"

#ifdef GEOTRAJ_BENCH_KUNZ
#include <list>

#include "Path.h"
#include "Trajectory.h"
#endif

#ifdef GEOTRAJ_BENCH_TOPPRA
#include <cstdio>
#include <exception>
#include <memory>
#include <string>

#include <toppra/algorithm/toppra.hpp>
#include <toppra/constraint/joint_torque.hpp>
#include <toppra/constraint/linear_joint_acceleration.hpp>
#include <toppra/constraint/linear_joint_velocity.hpp>
#include <toppra/geometric_path/piecewise_poly_path.hpp>
#include <toppra/parametrizer/const_accel.hpp>
#include <toppra/solver/seidel.hpp>
#endif

namespace {

using namespace geotraj;
using Waypoints = std::vector<std::vector<double>>;

const core::ValidRobot& panda() {
  static const core::ValidRobot robot = *core::ValidRobot::check(*planner::find_builtin_robot("panda"));
  return robot;
}

// The Panda with its rated payload and its shoulder limited to `shoulder` N m (its own: 87),
// so that the torque binds: 50 on set 0, 60 on set 1 (whose gravity load reaches 50.6).
const core::ValidRobot& loaded_panda(long shoulder) {
  static std::map<long, core::ValidRobot> robots;
  auto it = robots.find(shoulder);
  if (it == robots.end()) {
    core::RobotModel m = panda().model();
    m.payload.mass = 3.0;
    m.payload.center_of_mass = Eigen::Vector3d(0.0, 0.0, 0.05);
    m.limits[1].max_torque = static_cast<double>(shoulder);
    it = robots.emplace(shoulder, *core::ValidRobot::check(std::move(m))).first;
  }
  return it->second;
}

// The largest |tau_j| / maxTorque of the loaded Panda `m` over a motion given by its joints,
// velocities and accelerations at time t, sampled at 1 kHz.
double torque_usage(const core::RobotModel& m, double duration,
                    const std::function<void(double, core::JointVector&, core::JointVector&, core::JointVector&)>& state_at) {
  core::JointVector q, qd, qdd, tau;
  double usage = 0.0;
  for (double t = 0.0; t <= duration; t += 1e-3) {
    state_at(t, q, qd, qdd);
    core::inverse_dynamics(m, q, qd, qdd, core::dynamics_options(m), tau);
    for (std::size_t j = 0; j < m.dof(); ++j)
      if (m.limits[j].max_torque) usage = std::max(usage, std::abs(tau(static_cast<Eigen::Index>(j))) / *m.limits[j].max_torque);
  }
  return usage;
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
// geotraj's time-optimal sweep within the loaded Panda's torques as well (geotraj's grid, the
// grid-error sweep and the sample check at check_hz included: 2 kHz, the default, or 0, the
// cycle rate's 1 kHz, the samples streamed; -1: no sample check, the timing alone, as
// TOPP-RA's is measured).
void BM_GeotrajJointPathTorque(benchmark::State& state) {
  const core::JointPathSpec spec = spec_of(state.range(0), static_cast<double>(state.range(1)) / 100.0);
  const core::ValidRobot& robot = loaded_panda(state.range(3));
  const core::JointPath path = *core::build_joint_path(robot, spec);
  core::JointPathOptions options;
  options.check_rate_hz = static_cast<double>(std::max<long>(0, state.range(2)));
  options.verify_samples = state.range(2) >= 0;
  std::optional<core::JointPathPlan> plan;
  for (auto _ : state) {
    auto timed = core::plan_joint_path(robot, path, fastest(), options);
    if (!timed) {
      state.SkipWithError(timed.error().front().description.c_str());
      return;
    }
    plan = std::move(*timed);
    benchmark::DoNotOptimize(plan->duration_s);
  }
  state.counters["duration_s"] = plan->duration_s;
  state.counters["refinements"] = plan->refinements;
  state.counters["tau_usage"] = torque_usage(robot, plan->duration_s, [&](double t, core::JointVector& q,
                                                                          core::JointVector& qd, core::JointVector& qdd) {
    core::MoveSample s;
    core::ProfileCursor cursor;
    std::size_t hint = 0;
    core::joint_path_at(*plan, t, cursor, hint, s);
    q = s.q, qd = s.q_dot, qdd = s.q_ddot;
  });
  const auto free = core::plan_joint_path(panda(), path, fastest());
  if (free) state.counters["free_s"] = free->duration_s;  // the same path without the payload and the limit
}
BENCHMARK(BM_GeotrajJointPathTorque)
    ->ArgNames({"set", "dev_cm", "check_hz", "shoulder_Nm"})
    ->Args({0, 5, 2000, 50})
    ->Args({0, 5, 0, 50})
    ->Args({0, 5, -1, 50})
    ->Args({1, 5, 2000, 60})
    ->Args({1, 5, 0, 60})
    ->Args({1, 5, -1, 60})
    ->Unit(benchmark::kMillisecond);

BENCHMARK(BM_GeotrajJointPathJerk)
    ->ArgNames({"set", "dev_cm"})
    ->Args({0, 5})
    ->Args({1, 5})
    ->Unit(benchmark::kMillisecond);

#ifdef GEOTRAJ_BENCH_KUNZ
// Kunz and Stilman's time-optimal trajectory generation at its default 1 ms step.
// Their inputs for the benchmark's set: the waypoints and the Panda's limits.
struct KunzInputs {
  std::list<Eigen::VectorXd> points;
  Eigen::VectorXd v{7}, a{7};
};

KunzInputs kunz_inputs(const benchmark::State& state) {
  KunzInputs in;
  for (const auto& w : waypoints(state.range(0))) in.points.push_back(Eigen::Map<const Eigen::VectorXd>(w.data(), 7));
  for (std::size_t j = 0; j < 7; ++j) {
    in.v(static_cast<Eigen::Index>(j)) = panda()->limits[j].max_velocity;
    in.a(static_cast<Eigen::Index>(j)) = panda()->limits[j].max_acceleration;
  }
  return in;
}

void BM_KunzStilman(benchmark::State& state) {
  const double deviation = static_cast<double>(state.range(1)) / 100.0;
  const auto [points, v, a] = kunz_inputs(state);
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

// The same with its limits scaled down until its samples at 1 kHz stay within the Panda's
// (by second differences): its duration when it keeps the limits, as geotraj's sweep does.
// The time is of the last, scaled run; `limit_scale` is the acceleration limits' factor.
void BM_KunzStilmanWithinLimits(benchmark::State& state) {
  const double deviation = static_cast<double>(state.range(1)) / 100.0;
  auto [points, v, a] = kunz_inputs(state);
  const Eigen::VectorXd a_full = a;
  // The largest factor of the acceleration limits (to 0.1 %) whose result stays within the
  // limits (to 0.1 %; its velocities are within theirs), by bisection. Its overshoots do not
  // shrink in proportion (they come from its integration step and its blends' ends): the
  // factor found is where the bisection ends, not the largest that would do.
  std::optional<Trajectory> trajectory;
  auto within = [&](double scale) {
    a = scale * a_full;
    trajectory.emplace(Path(points, deviation), v, a, 1e-3);
    if (!trajectory->isValid()) return false;
    count(state, trajectory->getDuration(), [&](double t) { return trajectory->getPosition(t); });
    return state.counters["v_usage"] <= 1.001 && state.counters["a_usage"] <= 1.001;  // the figures' 0.1 %
  };
  double lo = 0.5, hi = 1.0;
  if (within(hi)) {
    lo = hi;
  } else if (!within(lo)) {
    state.SkipWithError("not within the limits at half of them");
    return;
  }
  while (hi - lo > 1e-3) {
    const double mid = 0.5 * (lo + hi);
    (within(mid) ? lo : hi) = mid;
  }
  within(lo);
  for (auto _ : state) {
    trajectory.emplace(Path(points, deviation), v, a, 1e-3);
    benchmark::DoNotOptimize(trajectory->getDuration());
  }
  count(state, trajectory->getDuration(), [&](double t) { return trajectory->getPosition(t); });
  state.counters["limit_scale"] = lo;
}
BENCHMARK(BM_KunzStilmanWithinLimits)->Apply(every_set);
#endif

#ifdef GEOTRAJ_BENCH_TOPPRA
using ToppraTrajectory = std::shared_ptr<toppra::parametrizer::ConstAccel>;

// TOPP-RA on `path` with `gridpoints` as its users call it: the joint velocity and
// acceleration constraints at the Panda's limits (accelerations by interpolation, their
// default), the seidel solver, at rest at both ends, then the constant-acceleration
// parametrizer (the classical one, which their documentation says meets the constraints and
// the boundary conditions). Empty with `error` set if it fails.
// TOPP-RA's joint-torque constraint on the loaded Panda: our inverse dynamics (the same model
// and payload; its own a, b, c from three calls per grid point, as ours).
class PandaTorque final : public toppra::constraint::JointTorque {
 public:
  PandaTorque(const core::RobotModel& model, const toppra::Vector& limit)
      : JointTorque(-limit, limit, toppra::Vector()), model_(&model) {}
  void computeInverseDynamics(const toppra::Vector& q, const toppra::Vector& v, const toppra::Vector& a,
                              toppra::Vector& tau) override {
    core::inverse_dynamics(*model_, q, v, a, core::dynamics_options(*model_), tau_);
    tau = Eigen::VectorXd(tau_);
  }

 private:
  const core::RobotModel* model_;
  core::JointVector tau_;
};

ToppraTrajectory toppra_timing(const toppra::GeometricPathPtr& path, const toppra::Vector& gridpoints,
                               std::string& error, const core::RobotModel* torques = nullptr) {
  toppra::Vector v(7), a(7);
  for (std::size_t j = 0; j < 7; ++j) {
    v(static_cast<Eigen::Index>(j)) = panda()->limits[j].max_velocity;
    a(static_cast<Eigen::Index>(j)) = panda()->limits[j].max_acceleration;
  }
  auto velocity = std::make_shared<toppra::constraint::LinearJointVelocity>(-v, v);
  auto acceleration = std::make_shared<toppra::constraint::LinearJointAcceleration>(-a, a);
  acceleration->discretizationType(toppra::DiscretizationType::Interpolation);
  toppra::LinearConstraintPtrs constraints{velocity, acceleration};
  if (torques) {
    toppra::Vector limit(7);  // the Panda's own (87 and 12 N m), the shoulder's as loaded_panda sets it
    for (std::size_t j = 0; j < 7; ++j) limit(static_cast<Eigen::Index>(j)) = *torques->limits[j].max_torque;
    auto torque = std::make_shared<PandaTorque>(*torques, limit);
    torque->discretizationType(toppra::DiscretizationType::Interpolation);
    constraints.push_back(torque);
  }
  toppra::algorithm::TOPPRA algorithm(constraints, path);
  algorithm.solver(std::make_shared<toppra::solver::Seidel>());
  algorithm.setGridpoints(gridpoints);
  if (algorithm.computePathParametrization(0.0, 0.0) != toppra::ReturnCode::OK) {
    error = "TOPP-RA failed: " + algorithm.getErrorMessage();
    return nullptr;
  }
  const auto& data = algorithm.getParameterizationData();
  auto trajectory = std::make_shared<toppra::parametrizer::ConstAccel>(path, data.gridpoints, data.parametrization);
  if (!trajectory->validate()) {
    const toppra::Vector sd = data.parametrization.cwiseSqrt();
    char range[64];
    std::snprintf(range, sizeof range, "%.3g to %.3g", sd.segment(1, sd.size() - 2).minCoeff(), sd.maxCoeff());
    error = std::string("TOPP-RA's parametrizer refuses its result (path velocity ") + range + " between the ends)";
    return nullptr;
  }
  return trajectory;
}

double toppra_duration(const ToppraTrajectory& trajectory) { return trajectory->pathInterval()[1]; }

// The figures of count() for a TOPP-RA trajectory.
void count_toppra(benchmark::State& state, const ToppraTrajectory& trajectory) {
  count(state, toppra_duration(trajectory), [&](double t) { return Eigen::VectorXd(trajectory->eval_single(t)); });
}

// 1. TOPP-RA on a cubic spline through the waypoints (zero velocity at both ends: clamped;
// their C++ spline has no not-a-knot end), its knots at the waypoints' cumulative joint-space
// distance (knots = 1) or evenly spaced in [0, 1] as in their quickstart (knots = 0), on a
// uniform grid of N intervals (100: the C++ default). Timed: the spline, the constraints,
// the reachability analysis and the parametrizer. Also reported from the samples at 1 kHz:
// the largest excursion of a joint beyond its position limits (q_excess [rad]) and the
// largest distance of the motion from the polyline of the waypoints (off_polyline,
// Euclidean over the joints [rad]).
void BM_ToppraSpline(benchmark::State& state) {
  const Waypoints& w = waypoints(state.range(0));
  const auto intervals = static_cast<Eigen::Index>(state.range(1));
  const bool chord = state.range(2) != 0;
  toppra::Vectors positions;
  toppra::Vector knots(static_cast<Eigen::Index>(w.size()));
  for (std::size_t i = 0; i < w.size(); ++i) {
    positions.push_back(Eigen::Map<const Eigen::VectorXd>(w[i].data(), 7));
    const double step = i == 0 ? 0.0 : chord ? (positions[i] - positions[i - 1]).norm() : 1.0;
    knots(static_cast<Eigen::Index>(i)) = i == 0 ? 0.0 : knots(static_cast<Eigen::Index>(i) - 1) + step;
  }
  if (!chord) knots /= knots(knots.size() - 1);
  ToppraTrajectory trajectory;
  std::string error;
  for (auto _ : state) {
    trajectory.reset();
    try {
      auto spline = std::make_shared<toppra::PiecewisePolyPath>(toppra::PiecewisePolyPath::CubicSpline(
          positions, knots, {toppra::BoundaryCond("clamped"), toppra::BoundaryCond("clamped")}));
      const toppra::Bound interval = spline->pathInterval();
      trajectory = toppra_timing(spline, toppra::Vector::LinSpaced(intervals + 1, interval[0], interval[1]), error);
    } catch (const std::exception& e) {
      error = e.what();
    }
    if (!trajectory) {
      state.SkipWithError(error.c_str());
      return;
    }
    benchmark::DoNotOptimize(toppra_duration(trajectory));
  }
  count_toppra(state, trajectory);
  state.counters["grid_points"] = static_cast<double>(intervals + 1);
  // Beyond the position limits, and away from the polyline.
  const auto& limits = panda()->limits;
  double excess = 0.0, off = 0.0;
  for (double t = 0.0; t <= toppra_duration(trajectory); t += 1e-3) {
    const Eigen::VectorXd q = trajectory->eval_single(t);
    for (Eigen::Index j = 0; j < 7; ++j) {
      const auto& l = limits[static_cast<std::size_t>(j)];
      excess = std::max({excess, q(j) - l.max_position, l.min_position - q(j)});
    }
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i + 1 < positions.size(); ++i) {
      const Eigen::VectorXd d = positions[i + 1] - positions[i];
      const double f = std::clamp(d.dot(q - positions[i]) / std::max(d.squaredNorm(), 1e-300), 0.0, 1.0);
      nearest = std::min(nearest, (positions[i] + f * d - q).norm());
    }
    off = std::max(off, nearest);
  }
  state.counters["q_excess"] = excess;
  state.counters["off_polyline"] = off;
}
BENCHMARK(BM_ToppraSpline)
    ->ArgNames({"set", "N", "knots"})
    ->Args({0, 100, 1})
    ->Args({0, 1000, 1})
    ->Args({0, 100, 0})
    ->Args({1, 100, 1})
    ->Args({1, 1000, 1})
    ->Args({1, 100, 0})
    ->Args({2, 100, 1})
    ->Args({2, 1000, 1})
    ->Args({2, 4000, 1})
    ->Unit(benchmark::kMillisecond);

// The sigmas of geotraj's grid of a path without interior rests (plan_joint_path's default
// JointPathOptions: each blend kBlendGridIntervals intervals crowded towards its ends, the
// lines 400 by their share of the length, at least kMinLineIntervals each).
std::vector<double> geotraj_grid(const core::JointPath& path) {
  const core::JointPathOptions options;
  double lines = 0.0;
  for (const auto& seg : path.segments)
    if (seg.kind == core::JointPathSegment::Kind::kLine) lines += seg.sigma1 - seg.sigma0;
  std::vector<double> sigmas{0.0};
  for (const auto& seg : path.segments) {
    const double span = seg.sigma1 - seg.sigma0;
    const bool blend = seg.kind == core::JointPathSegment::Kind::kBlend;
    const std::size_t k =
        blend ? options.blend_intervals
              : std::max<std::size_t>(core::kMinLineIntervals,
                                      static_cast<std::size_t>(std::ceil(static_cast<double>(options.line_intervals) *
                                                                         span / std::max(lines, 1e-300))));
    for (std::size_t i = 1; i <= k; ++i) {
      const double x = static_cast<double>(i) / static_cast<double>(k);
      const double f = blend ? 0.5 * (1.0 - std::cos(std::numbers::pi * x)) : x;
      const double sigma = i == k ? seg.sigma1 : seg.sigma0 + span * f;
      if (sigma > sigmas.back()) sigmas.push_back(sigma);
    }
  }
  sigmas.back() = path.length;
  return sigmas;
}

// geotraj's grid of `path` (geotraj_grid) with q and q' at each point: the data of the cubic
// Hermite spline TOPP-RA times geotraj's path on.
struct GridSpline {
  std::vector<double> sigmas;
  toppra::Vectors positions, tangents;
};
GridSpline grid_spline(const core::JointPath& path) {
  GridSpline out;
  out.sigmas = geotraj_grid(path);
  core::JointPathPoint point;
  std::size_t hint = 0;
  for (const double sigma : out.sigmas) {
    core::evaluate(path, sigma, point, hint);
    out.positions.push_back(Eigen::VectorXd(point.q));
    out.tangents.push_back(Eigen::VectorXd(point.q_s));
  }
  return out;
}

// TOPP-RA on the Hermite spline through `spline` on `gridpoints` (within the torques of
// `torques` where given) at every iteration, the spline built in the timing; null, the
// benchmark skipped with TOPP-RA's error, where it fails.
ToppraTrajectory time_each_iteration(benchmark::State& state, const GridSpline& spline, const toppra::Vector& gridpoints,
                                     const core::RobotModel* torques) {
  ToppraTrajectory trajectory;
  std::string error;
  for (auto _ : state) {
    trajectory.reset();
    try {
      auto hermite = std::make_shared<toppra::PiecewisePolyPath>(
          toppra::PiecewisePolyPath::CubicHermiteSpline(spline.positions, spline.tangents, spline.sigmas));
      trajectory = toppra_timing(hermite, gridpoints, error, torques);
    } catch (const std::exception& e) {
      error = e.what();
    }
    if (!trajectory) {
      state.SkipWithError(error.c_str());
      return nullptr;
    }
    benchmark::DoNotOptimize(toppra_duration(trajectory));
  }
  return trajectory;
}

// 2. TOPP-RA timing geotraj's path (built as BM_GeotrajJointPath builds it, outside the
// timing): a cubic Hermite spline through q(sigma) and q'(sigma) at the points of geotraj's
// grid (exact on the lines; hermite_err: its largest distance from a blend [rad]), timed on that
// grid (grid = 0) or on a uniform grid of as many points (grid = 1). Timed: the Hermite
// spline from those points, the constraints, the reachability analysis and the parametrizer.
// geotraj_s: plan_joint_path's duration on the same path (BM_GeotrajJointPath's).
void BM_ToppraGeotrajPath(benchmark::State& state) {
  const core::JointPathSpec spec = spec_of(state.range(0), static_cast<double>(state.range(1)) / 100.0);
  const core::JointPath path = *core::build_joint_path(panda(), spec);
  if (path.rests.size() != 2) {
    state.SkipWithError("the path rests between its ends");
    return;
  }
  const GridSpline spline = grid_spline(path);
  const std::vector<double>& sigmas = spline.sigmas;
  const toppra::Vectors &positions = spline.positions, &tangents = spline.tangents;
  const bool uniform = state.range(2) != 0;
  const auto n = static_cast<Eigen::Index>(sigmas.size());
  const toppra::Vector gridpoints = uniform ? toppra::Vector(toppra::Vector::LinSpaced(n, 0.0, path.length))
                                            : toppra::Vector(Eigen::Map<const Eigen::VectorXd>(sigmas.data(), n));
  const ToppraTrajectory trajectory = time_each_iteration(state, spline, gridpoints, nullptr);
  if (!trajectory) return;
  count_toppra(state, trajectory);
  core::JointPathPoint point;
  std::size_t hint = 0;
  state.counters["grid_points"] = static_cast<double>(n);
  // How closely the Hermite spline follows the path: the largest difference of q at the
  // middles of its pieces [rad].
  const toppra::PiecewisePolyPath hermite = toppra::PiecewisePolyPath::CubicHermiteSpline(positions, tangents, sigmas);
  double hermite_error = 0.0;
  for (std::size_t i = 0; i + 1 < sigmas.size(); ++i) {
    const double mid = 0.5 * (sigmas[i] + sigmas[i + 1]);
    core::evaluate(path, mid, point, hint);
    const Eigen::VectorXd difference = hermite.eval_single(mid) - Eigen::VectorXd(point.q);
    hermite_error = std::max(hermite_error, difference.cwiseAbs().maxCoeff());
  }
  state.counters["hermite_err"] = hermite_error;
  const auto plan = core::plan_joint_path(panda(), path, fastest());
  if (plan) state.counters["geotraj_s"] = plan->duration_s;
}
// 3. The same within the loaded Panda's torques as well (its JointTorque constraint), on
// geotraj's grid: duration, tau_usage at 1 kHz, and geotraj_s, geotraj's duration within the
// same limits (BM_GeotrajJointPathTorque's plan).
void BM_ToppraGeotrajPathTorque(benchmark::State& state) {
  const core::JointPathSpec spec = spec_of(state.range(0), static_cast<double>(state.range(1)) / 100.0);
  const core::ValidRobot& robot = loaded_panda(state.range(2));
  const core::JointPath path = *core::build_joint_path(robot, spec);
  if (path.rests.size() != 2) {
    state.SkipWithError("the path rests between its ends");
    return;
  }
  const GridSpline spline = grid_spline(path);
  const std::vector<double>& sigmas = spline.sigmas;
  const toppra::Vector gridpoints = Eigen::Map<const Eigen::VectorXd>(sigmas.data(), static_cast<Eigen::Index>(sigmas.size()));
  const ToppraTrajectory trajectory = time_each_iteration(state, spline, gridpoints, &robot.model());
  if (!trajectory) return;
  state.counters["duration_s"] = toppra_duration(trajectory);
  state.counters["tau_usage"] = torque_usage(robot, toppra_duration(trajectory), [&](double t, core::JointVector& q,
                                                                                     core::JointVector& qd,
                                                                                     core::JointVector& qdd) {
    const toppra::Vectors x = trajectory->eval(toppra::Vector::Constant(1, t), 0);
    const toppra::Vectors v = trajectory->eval(toppra::Vector::Constant(1, t), 1);
    const toppra::Vectors a = trajectory->eval(toppra::Vector::Constant(1, t), 2);
    q = x[0], qd = v[0], qdd = a[0];
  });
  state.counters["grid_points"] = static_cast<double>(sigmas.size());
  const auto plan = core::plan_joint_path(robot, path, fastest());
  if (plan) state.counters["geotraj_s"] = plan->duration_s;
}
BENCHMARK(BM_ToppraGeotrajPathTorque)
    ->ArgNames({"set", "dev_cm", "shoulder_Nm"})
    ->Args({0, 5, 50})
    ->Args({1, 5, 60})
    ->Unit(benchmark::kMillisecond);

BENCHMARK(BM_ToppraGeotrajPath)
    ->ArgNames({"set", "dev_cm", "grid"})
    ->Args({0, 5, 0})
    ->Args({0, 10, 0})
    ->Args({1, 5, 0})
    ->Args({1, 10, 0})
    ->Args({2, 5, 0})
    ->Args({0, 5, 1})
    ->Args({1, 5, 1})
    ->Args({2, 5, 1})
    ->Unit(benchmark::kMillisecond);
#endif

}  // namespace

BENCHMARK_MAIN();
