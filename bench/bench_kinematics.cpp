// Kinematics and IK (core/robot/kinematics.hpp, core/robot/ik.hpp, core/planning/joint_motion.hpp), one thread:
//  - forward kinematics, FK with the Jacobian, and J_dot q_dot per call, every built-in arm
//    (PA-10, UR5, Panda, iiwa 14, UR5e), at 64 random configurations within the limits,
//    cycled; beside them Orocos KDL's ChainFkSolverPos_recursive and ChainJntToJacSolver on
//    the same chains and configurations (checked equal to ours first);
//  - the IK of every sample of the thesis's demo path C (10 s, 100 Hz, 1001 samples) on the
//    PA-10 from its home, warm-started: JointTracker::track (positions by the second-order
//    predictor and Newton, velocities, accelerations, midpoint certificate, manipulability),
//    solve_ik alone (seeded with the previous solution, no predictor), and Orocos KDL's
//    ChainIkSolverPos_NR_JL (Debian's liborocos-kdl, with ChainIkSolverVel_pinv and
//    ChainFkSolverPos_recursive, the same chain built from the DH table, seeded with the
//    previous solution) on the same poses. KDL's eps = 1e-9 applies to each twist component
//    (a norm up to sqrt(3) e-9, slightly looser than our 1e-9 m and 1e-9 rad norms).
//  - cold IK (search_ik from the home configuration, restarts uniform within the limits) of
//    2,000 random reachable poses per arm (the FK of configurations uniform within the
//    limits), each solve timed alone: counters `solved` (fraction), `median_us`, `p99_us`,
//    `worst_us`, `mean_attempts`; the argument is the Newton iterations per attempt.
// The counter `per_sample` is the time per sample [s] (CPU time over the samples of an
// iteration); `not_converged` counts failed samples. BM_TrackPathCWorstSample times every
// sample alone and reports the median, 99th percentile and worst.
// Run: build/bench/bench_kinematics --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <algorithm>
#include <cmath>
#include <chrono>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#if GEOTRAJ_BENCH_KDL
#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_nr_jl.hpp>
#include <kdl/chainiksolvervel_pinv.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>

#include "kdl_chain.hpp"
#endif

#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/trajectory.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/robots.hpp"
#include "thesis_paths.hpp"

namespace {

using namespace geotraj;

// 0 PA-10, 1 UR5 (DH tables); 2 Panda, 3 iiwa 14, 4 UR5e (URDF: general chains).
const core::RobotModel& robot(int which) {
  static const char* const names[] = {"pa10", "ur5", "panda", "iiwa14", "ur5e"};
  return *planner::find_builtin_robot(names[which]);
}

std::vector<core::JointVector> random_configurations(const core::RobotModel& m) {
  std::mt19937_64 rng(20240611);
  std::vector<core::JointVector> out;
  for (int k = 0; k < 64; ++k) {
    core::JointVector q(static_cast<Eigen::Index>(m.dof()));
    for (std::size_t i = 0; i < m.dof(); ++i) {
      q(static_cast<Eigen::Index>(i)) =
          std::uniform_real_distribution<double>(m.limits[i].min_position, m.limits[i].max_position)(rng);
    }
    out.push_back(q);
  }
  return out;
}

// Argument: 0 = PA-10, 1 = UR5.
void BM_ForwardKinematics(benchmark::State& state) {
  const auto& m = robot(static_cast<int>(state.range(0)));
  const auto qs = random_configurations(m);
  std::size_t k = 0;
  for (auto _ : state) {
    auto X = core::forward_kinematics(m, qs[k++ % qs.size()]);
    benchmark::DoNotOptimize(X);
  }
  state.SetLabel(m.name);
}
BENCHMARK(BM_ForwardKinematics)->DenseRange(0, 4);

void BM_ForwardKinematicsJacobian(benchmark::State& state) {
  const auto& m = robot(static_cast<int>(state.range(0)));
  const auto qs = random_configurations(m);
  Eigen::Isometry3d X;
  core::JointJacobian J;
  std::size_t k = 0;
  for (auto _ : state) {
    core::forward_kinematics(m, qs[k++ % qs.size()], X, J);
    benchmark::DoNotOptimize(X);
    benchmark::DoNotOptimize(J);
  }
  state.SetLabel(m.name);
}
BENCHMARK(BM_ForwardKinematicsJacobian)->DenseRange(0, 4);

#if GEOTRAJ_BENCH_KDL
// The chain of robot.hpp in KDL: a DH model from its table as the KDL cross-check builds it
// (tests/core/robot/kdl_chain.hpp, KDL's DH frames). A general chain (URDF) the way KDL runs
// it fastest: one segment per joint (its motion, then the next joint's origin; the last one
// ends in flange * tool), a joint about or along a coordinate axis as KDL's RotX/Y/Z or
// TransX/Y/Z (scale -1 for a negative axis), any other as RotAxis/TransAxis. (The
// cross-check's general chain, as KDL's URDF parser writes it, has two segments a joint.)
KDL::Joint kdl_joint(const core::Joint& j) {
  const bool turns = core::turns(j.type);
  for (int k = 0; k < 3; ++k) {
    if (std::abs(j.axis(k)) != 1.0) continue;  // a unit axis along x, y or z
    constexpr KDL::Joint::JointType rot[] = {KDL::Joint::RotX, KDL::Joint::RotY, KDL::Joint::RotZ};
    constexpr KDL::Joint::JointType trans[] = {KDL::Joint::TransX, KDL::Joint::TransY, KDL::Joint::TransZ};
    return KDL::Joint(turns ? rot[k] : trans[k], j.axis(k));
  }
  return KDL::Joint("", KDL::Vector::Zero(), KDL::Vector(j.axis.x(), j.axis.y(), j.axis.z()),
                    turns ? KDL::Joint::RotAxis : KDL::Joint::TransAxis);
}

KDL::Chain kdl_chain(const core::RobotModel& m) {
  if (m.dh) return test::dh_to_kdl_chain(m);
  KDL::Chain chain;
  chain.addSegment(KDL::Segment(KDL::Joint(KDL::Joint::Fixed), test::to_kdl(m.base * m.joints.front().origin)));
  for (std::size_t i = 0; i < m.dof(); ++i) {
    const Eigen::Isometry3d tip = i + 1 < m.dof() ? m.joints[i + 1].origin : m.flange * m.tool;
    chain.addSegment(KDL::Segment(kdl_joint(m.joints[i]), test::to_kdl(tip)));
  }
  return chain;
}

// Orocos KDL's forward kinematics on the same chain (kdl_chain), the same 64 configurations:
// ChainFkSolverPos_recursive (argument 1: 0, the pose alone) and with ChainJntToJacSolver
// (1: the pose and the Jacobian, the tool point's, in the base frame, rows [v; omega]: ours).
// The solvers are built once; the joint values are KDL arrays made beforehand. Before the
// timing, every configuration's pose and Jacobian are checked against ours (1e-12).
void BM_KdlForwardKinematics(benchmark::State& state) {
  const auto& m = robot(static_cast<int>(state.range(0)));
  const bool with_jacobian = state.range(1) == 1;
  const KDL::Chain chain = kdl_chain(m);
  KDL::ChainFkSolverPos_recursive fk(chain);
  KDL::ChainJntToJacSolver jac(chain);
  std::vector<KDL::JntArray> qs;
  double error = 0.0;
  for (const auto& q : random_configurations(m)) {
    qs.push_back(test::to_kdl(q));
    KDL::Frame X;
    KDL::Jacobian J(chain.getNrOfJoints());
    fk.JntToCart(qs.back(), X);
    jac.JntToJac(qs.back(), J);
    Eigen::Isometry3d X_ours;
    core::JointJacobian J_ours;
    core::forward_kinematics(m, q, X_ours, J_ours);
    error = std::max({error, (test::from_kdl(X).matrix() - X_ours.matrix()).cwiseAbs().maxCoeff(),
                      (J.data - J_ours).cwiseAbs().maxCoeff()});
  }
  if (!(error <= 1e-12)) state.SkipWithError("KDL's chain does not match the model");
  KDL::Frame X;
  KDL::Jacobian J(chain.getNrOfJoints());
  std::size_t k = 0;
  for (auto _ : state) {
    const KDL::JntArray& q = qs[k++ % qs.size()];
    fk.JntToCart(q, X);
    benchmark::DoNotOptimize(X);
    if (with_jacobian) {
      jac.JntToJac(q, J);
      benchmark::DoNotOptimize(J.data.data());
    }
  }
  state.counters["max_difference"] = error;
  state.SetLabel(m.name + (with_jacobian ? ", KDL pose + Jacobian" : ", KDL pose"));
}
BENCHMARK(BM_KdlForwardKinematics)->ArgsProduct({{0, 1, 2, 3, 4}, {0, 1}});
#endif

void BM_JacobianDotQdot(benchmark::State& state) {
  const auto& m = robot(static_cast<int>(state.range(0)));
  const auto qs = random_configurations(m);
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& q = qs[k % qs.size()];
    const auto& q_dot = qs[(k + 1) % qs.size()];
    ++k;
    auto a = core::jacobian_dot_qdot(m, q, q_dot);
    benchmark::DoNotOptimize(a);
  }
  state.SetLabel(m.name);
}
BENCHMARK(BM_JacobianDotQdot)->DenseRange(0, 4);

// The Cartesian samples of demo path C, 10 s at 100 Hz (the thesis's rate).
const std::vector<core::CartesianState>& path_c_samples() {
  static const std::vector<core::CartesianState> samples = [] {
    const core::Path path = *core::build_path(testing::thesis_demo_path('C'));
    core::MotionSpec spec;
    spec.duration_s = 10.0;
    const core::MotionPlan plan = *core::plan_motion(path, spec);
    const core::OrientationPlan orientation = *core::plan_orientation(path);
    core::MotionSampler sampler(path, plan);
    std::vector<core::CartesianState> out;
    core::MotionSample s;
    while (sampler.next(s)) out.push_back(core::cartesian_state(path, orientation, s));
    return out;
  }();
  return samples;
}

void per_sample_counters(benchmark::State& state, std::size_t samples, std::size_t failures) {
  state.counters["per_sample"] = benchmark::Counter(static_cast<double>(samples),
                                                    benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["not_converged"] = static_cast<double>(failures);
}

void BM_TrackPathC(benchmark::State& state) {
  const auto& m = robot(0);
  const auto& xs = path_c_samples();
  core::JointTracker tracker(m, core::home_configuration(m));
  core::JointSample s;
  std::size_t samples = 0, failures = 0;
  for (auto _ : state) {
    tracker.reset(core::home_configuration(m));
    for (const auto& x : xs) {
      failures += tracker.track(x, s) ? 0 : 1;
      benchmark::DoNotOptimize(s);
    }
    samples += xs.size();
  }
  per_sample_counters(state, samples, failures);
  state.SetLabel("pa10, JointTracker::track");
}
BENCHMARK(BM_TrackPathC)->Unit(benchmark::kMicrosecond);

// The stream a client gets: TrajectorySampler over path C with the PA-10 (the path's sample,
// the orientation, the tracker's continuation: JointTracker::follow with the samples' rule),
// at 100 Hz, where every sample follows in one stride, and at 2 Hz, where strides of 0.5 s
// are walked through the motion's states between samples (Arg: the rate [Hz]).
void BM_StreamPathC(benchmark::State& state) {
  const auto& m = robot(0);
  const core::Path path = *core::build_path(testing::thesis_demo_path('C'));
  core::MotionSpec spec;
  spec.duration_s = 10.0;
  spec.cycle_rate_hz = static_cast<double>(state.range(0));
  const core::Trajectory trajectory(std::in_place_type<core::PathMotion>,
                                    core::PathMotion{path, *core::plan_motion(path, spec), *core::plan_orientation(path)});
  core::TrajectorySample s;
  std::size_t samples = 0, failures = 0;
  for (auto _ : state) {
    core::TrajectorySampler sampler(trajectory, &m, core::home_configuration(m));
    while (sampler.next(s)) {
      failures += s.joints.converged ? 0 : 1;
      ++samples;
      benchmark::DoNotOptimize(s);
    }
  }
  per_sample_counters(state, samples, failures);
  state.SetLabel("pa10, TrajectorySampler with the IK");
}
BENCHMARK(BM_StreamPathC)->Arg(100)->Arg(2)->Unit(benchmark::kMicrosecond);

// The same, each sample timed on its own (steady_clock, ~20 ns of overhead per sample):
// the median, 99th percentile and worst sample [s], the first (cold) sample included.
void BM_TrackPathCWorstSample(benchmark::State& state) {
  const auto& m = robot(0);
  const auto& xs = path_c_samples();
  core::JointTracker tracker(m, core::home_configuration(m));
  core::JointSample s;
  std::vector<double> times;
  times.reserve(xs.size() * 64);
  for (auto _ : state) {
    tracker.reset(core::home_configuration(m));
    for (const auto& x : xs) {
      const auto start = std::chrono::steady_clock::now();
      tracker.track(x, s);
      benchmark::DoNotOptimize(s);
      const auto stop = std::chrono::steady_clock::now();
      times.push_back(std::chrono::duration<double>(stop - start).count());
    }
  }
  std::sort(times.begin(), times.end());
  state.counters["median_sample"] = times[times.size() / 2];
  state.counters["p99_sample"] = times[times.size() * 99 / 100];
  state.counters["worst_sample"] = times.back();
  state.SetLabel("pa10, JointTracker::track, per-sample times");
}
BENCHMARK(BM_TrackPathCWorstSample)->Unit(benchmark::kMicrosecond);

void BM_SolveIkPathC(benchmark::State& state) {
  const auto& m = robot(0);
  const auto& xs = path_c_samples();
  std::size_t samples = 0, failures = 0;
  for (auto _ : state) {
    core::JointVector q = core::home_configuration(m);
    for (const auto& x : xs) {
      const core::IkResult r = core::solve_ik(m, x.X_WT, q);
      failures += r.converged ? 0 : 1;
      q = r.q;
      benchmark::DoNotOptimize(q);
    }
    samples += xs.size();
  }
  per_sample_counters(state, samples, failures);
  state.SetLabel("pa10, solve_ik from the previous solution");
}
BENCHMARK(BM_SolveIkPathC)->Unit(benchmark::kMicrosecond);

#if GEOTRAJ_BENCH_KDL
void BM_KdlNrJlPathC(benchmark::State& state) {
  const auto& m = robot(0);
  const auto& xs = path_c_samples();
  const KDL::Chain chain = kdl_chain(m);
  const unsigned n = chain.getNrOfJoints();
  KDL::JntArray q_min(n), q_max(n), q(n), q_out(n);
  for (unsigned i = 0; i < n; ++i) {
    q_min(i) = m.limits[i].min_position;
    q_max(i) = m.limits[i].max_position;
  }
  KDL::ChainFkSolverPos_recursive fk(chain);
  KDL::ChainIkSolverVel_pinv ik_vel(chain);
  KDL::ChainIkSolverPos_NR_JL ik(chain, q_min, q_max, fk, ik_vel, 100, 1e-9);
  std::vector<KDL::Frame> targets;
  for (const auto& x : xs) targets.push_back(test::to_kdl(x.X_WT));
  const core::JointVector home = core::home_configuration(m);
  std::size_t samples = 0, failures = 0;
  for (auto _ : state) {
    for (unsigned i = 0; i < n; ++i) q(i) = home(i);
    for (const auto& target : targets) {
      failures += ik.CartToJnt(q, target, q_out) < 0 ? 1 : 0;
      q = q_out;
      benchmark::DoNotOptimize(q_out.data.data());
    }
    samples += targets.size();
  }
  per_sample_counters(state, samples, failures);
  state.SetLabel("pa10, KDL ChainIkSolverPos_NR_JL from the previous solution");
}
BENCHMARK(BM_KdlNrJlPathC)->Unit(benchmark::kMicrosecond);
#endif

// Cold IK of random reachable poses. Arguments: arm (0 = PA-10, 1 = UR5), Newton
// iterations per attempt.
void BM_ColdIk(benchmark::State& state) {
  const auto& m = robot(static_cast<int>(state.range(0)));
  constexpr int kPoses = 2000;
  std::mt19937_64 rng(20261203);
  std::vector<Eigen::Isometry3d> targets;
  for (int k = 0; k < kPoses; ++k) {
    core::JointVector q(static_cast<Eigen::Index>(m.dof()));
    for (std::size_t i = 0; i < m.dof(); ++i) {
      q(static_cast<Eigen::Index>(i)) =
          std::uniform_real_distribution<double>(m.limits[i].min_position, m.limits[i].max_position)(rng);
    }
    targets.push_back(core::forward_kinematics(m, q));
  }
  const core::JointVector home = core::home_configuration(m);
  core::IkSearchOptions options;
  options.newton.max_iterations = static_cast<int>(state.range(1));
  std::vector<double> us;
  double solved = 0.0, attempts = 0.0;
  for (auto _ : state) {
    us.clear();
    solved = attempts = 0.0;
    for (const auto& target : targets) {
      const auto t0 = std::chrono::steady_clock::now();
      const core::IkSearchResult r = core::search_ik(m, target, home, options);
      us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
      benchmark::DoNotOptimize(r.closest.q.data());
      solved += r.solutions.empty() ? 0.0 : 1.0;
      attempts += r.attempts;
    }
  }
  std::sort(us.begin(), us.end());
  state.counters["solved"] = solved / kPoses;
  state.counters["median_us"] = us[us.size() / 2];
  state.counters["p99_us"] = us[us.size() * 99 / 100];
  state.counters["worst_us"] = us.back();
  state.counters["mean_attempts"] = attempts / kPoses;
  state.SetLabel(std::string(m.name) + ", search_ik from home, " + std::to_string(state.range(1)) + " iterations an attempt");
}
BENCHMARK(BM_ColdIk)->ArgsProduct({{0, 1, 2, 3, 4}, {10, 20, 30, 50}})->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
