// Time-optimal timing (time_optimal.hpp):
//  - the sweep against an independent dynamic programme over a discretised b on small
//    random grids (the DP's answer is feasible for the same discrete problem, so it is never
//    faster, and it approaches the sweep as its b levels get finer);
//  - closed form: a straight line under maxSpeed and maxAcceleration is the minimum-time
//    trapezoid (exact when the ramp ends on a grid point), through the whole pipeline;
//  - the thesis's demo path C on the PA-10: every limit holds at every grid point and at
//    every streamed sample (MotionSampler + JointTracker, checked here independently), the
//    speed is zero at the cusp, the binding report covers the motion, the duration drops as
//    the limits grow; the duration is printed next to the thesis's fixed 10 s;
//  - the claim behind the grid: q_ss is the arc-length derivative of q_s (central
//    differences), and q_dot = q_s s_dot at the samples;
//  - unfollowable paths: a point that admits only zero speed, and an IK failure, are named.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/motion/speed_profile.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/time_optimal.hpp"

#include <stop_token>
#include "test_support.hpp"
#include "thesis_paths.hpp"

namespace geotraj::test {
namespace {

using core::GridPoint;
using core::JointVector;
using core::TimeOptimalLimits;
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A random grid of n points over [0, L] with `joints` joints.
std::vector<GridPoint> random_grid(std::mt19937_64& rng, std::size_t n, double L, int joints) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<GridPoint> g(n);
  // Smooth data: a few random harmonics per joint.
  std::vector<std::array<double, 4>> c(static_cast<std::size_t>(joints));
  for (auto& a : c) a = {U(rng), U(rng), 2.0 * U(rng), U(rng)};
  for (std::size_t i = 0; i < n; ++i) {
    const double s = L * static_cast<double>(i) / static_cast<double>(n - 1);
    g[i].s = s;
    g[i].q_s.resize(joints);
    g[i].q_ss.resize(joints);
    for (int j = 0; j < joints; ++j) {
      const auto& a = c[static_cast<std::size_t>(j)];
      const double w = 3.0 + a[2];
      g[i].q_s(j) = a[0] + a[1] * std::sin(w * s + a[3]);
      g[i].q_ss(j) = a[1] * w * std::cos(w * s + a[3]);
    }
    g[i].kappa = 2.0 + std::sin(5.0 * s);
  }
  return g;
}

/// The independent reference: a dynamic programme over b in K + 1 levels [0, b_cap] at each
/// point, transitions between levels of neighbouring points checked against every limit at
/// both ends (the same discrete problem), minimum total time 2 ds / (sqrt b + sqrt b'). The
/// levels span at most b_max where given (the range an optimum can use: finer levels there).
double dp_time(const std::vector<GridPoint>& g, const TimeOptimalLimits& lim, int K, double b_max = kInf) {
  const std::size_t n = g.size();
  double b_cap = 0.0;
  std::vector<double> cap(n, kInf);
  for (std::size_t i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < g[i].q_s.size(); ++j)
      if (g[i].q_s(j) != 0.0) cap[i] = std::min(cap[i], std::pow(lim.joint_velocity(j) / g[i].q_s(j), 2));
    cap[i] = std::min(cap[i], lim.speed * lim.speed);
    if (g[i].kappa > 0.0) cap[i] = std::min(cap[i], lim.centripetal / g[i].kappa);
    b_cap = std::max(b_cap, cap[i]);
  }
  b_cap = std::min(b_cap, b_max);
  const double db = b_cap / K;
  auto ok_acc = [&](const GridPoint& p, double u, double b) {
    for (Eigen::Index j = 0; j < p.q_s.size(); ++j)
      if (std::abs(p.q_s(j) * u + p.q_ss(j) * b) > lim.joint_acceleration(j) * (1 + 1e-12)) return false;
    for (Eigen::Index j = 0; j < lim.joint_torque.size() && p.tau_a.size() == lim.joint_torque.size(); ++j)
      if (std::abs(p.tau_a(j) * u + p.tau_b(j) * b + p.tau_c(j)) > lim.joint_torque(j) * (1 + 1e-12)) return false;
    return std::abs(u) <= lim.tangential * (1 + 1e-12);
  };
  std::vector<double> f(static_cast<std::size_t>(K + 1), kInf), nf(static_cast<std::size_t>(K + 1));
  f[0] = 0.0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    std::fill(nf.begin(), nf.end(), kInf);
    const double ds = g[i + 1].s - g[i].s;
    for (int m = 0; m <= K; ++m) {
      if (f[static_cast<std::size_t>(m)] == kInf) continue;
      const double b0 = m * db;
      for (int m1 = 0; m1 <= K; ++m1) {
        const double b1 = m1 * db;
        if (b1 > cap[i + 1] * (1 + 1e-12) || (m == 0 && m1 == 0)) continue;
        if (i + 2 == n && m1 != 0) continue;  // rest at the end
        const double u = (b1 - b0) / (2 * ds);
        if (!ok_acc(g[i], u, b0) || !ok_acc(g[i + 1], u, b1)) continue;
        const double t = f[static_cast<std::size_t>(m)] + 2 * ds / (std::sqrt(b0) + std::sqrt(b1));
        nf[static_cast<std::size_t>(m1)] = std::min(nf[static_cast<std::size_t>(m1)], t);
      }
    }
    std::swap(f, nf);
  }
  return f[0];
}

TimeOptimalLimits two_joint_limits() {
  TimeOptimalLimits lim;
  lim.joint_velocity.resize(2);
  lim.joint_acceleration.resize(2);
  lim.joint_velocity << 1.0, 1.5;
  lim.joint_acceleration << 2.0, 3.0;
  lim.speed = 1.2;
  lim.tangential = 4.0;
  lim.centripetal = 3.0;
  return lim;
}

// The DP over K = 200 and K = 800 levels: never faster than the sweep (to rounding) and
// within 1 % at K = 800 (b levels 1/800 of the cap: an O(db / b) loss where the optimum
// rides a limit, times the few intervals where the DP cannot follow it), closer at 800 than
// at 200.
TEST(TimeOptimalSweep, MatchesDynamicProgrammeOnSmallGrids) {
  std::mt19937_64 rng(20240611);
  for (int c = 0; c < 6; ++c) {
    const auto g = random_grid(rng, 25, 1.0, 2);
    const auto lim = two_joint_limits();
    const auto sol = core::solve_time_optimal(g, lim);
    ASSERT_TRUE(sol) << sol.error()[0].description;
    const double coarse = dp_time(g, lim, 200), fine = dp_time(g, lim, 800);
    std::printf("case %d: sweep %.6f s, DP(200) %.6f s, DP(800) %.6f s\n", c, sol->duration, coarse, fine);
    EXPECT_GE(fine, sol->duration * (1 - 1e-9)) << "case " << c;
    EXPECT_GE(coarse, sol->duration * (1 - 1e-9)) << "case " << c;
    EXPECT_LE(fine, sol->duration * 1.01) << "case " << c;
    EXPECT_LE(fine, coarse * (1 + 1e-12)) << "case " << c;
  }
}

// The same with joint torques (the asymmetric rows, time_optimal.hpp): random smooth torque
// terms with a gravity load c(s) within 60 % of the limit, the DP's transitions checked
// against tau = a u + b s_dot^2 + c at both ends as well: the sweep's duration is the DP's
// limit from below, and some interval is at a torque limit.
TEST(TimeOptimalSweep, WithTorquesMatchesDynamicProgrammeOnSmallGrids) {
  std::mt19937_64 rng(20261207);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int c = 0; c < 6; ++c) {
    auto g = random_grid(rng, 25, 1.0, 2);
    const double a0 = 2.0 + U(rng), b0 = U(rng), c0 = 0.6 * U(rng), w = 2.0 + U(rng);
    for (auto& p : g) {
      p.tau_a = JointVector::Constant(2, a0 + 0.5 * std::sin(w * p.s));
      p.tau_b = JointVector::Constant(2, b0 * std::cos(w * p.s));
      p.tau_c = JointVector::Constant(2, c0 * std::cos(0.5 * w * p.s));
      p.tau_a(1) *= -0.7;
    }
    auto lim = two_joint_limits();
    lim.joint_torque = JointVector::Constant(2, 1.0);
    const auto sol = core::solve_time_optimal(g, lim);
    ASSERT_TRUE(sol) << sol.error()[0].description;
    const auto without = core::solve_time_optimal(g, two_joint_limits());
    ASSERT_TRUE(without);
    // The DP's levels up to 1.2 times the sweep's largest b: finer where the optimum is.
    const double b_max = 1.2 * *std::max_element(sol->b.begin(), sol->b.end());
    const double coarse = dp_time(g, lim, 200, b_max), fine = dp_time(g, lim, 800, b_max);
    std::printf("case %d: sweep %.6f s (%.6f s without torques), DP(200) %.6f s, DP(800) %.6f s\n", c,
                sol->duration, without->duration, coarse, fine);
    EXPECT_GE(fine, sol->duration * (1 - 1e-9)) << "case " << c;
    EXPECT_LE(fine, sol->duration * 1.01) << "case " << c;
    EXPECT_LE(fine, coarse * (1 + 1e-12)) << "case " << c;
    EXPECT_GT(sol->duration, without->duration) << "case " << c << ": the torque binds";
    bool binds = false;
    for (const auto& st : sol->binding) binds = binds || (st.kind == core::BindingKind::kJointTorque && st.usage > 0.999);
    EXPECT_TRUE(binds) << "case " << c;
  }
}

// Every limit at both ends of every interval, b = 0 at the ends, the profile's times.
TEST(TimeOptimalSweep, LimitsHoldAtEveryGridPoint) {
  std::mt19937_64 rng(7);
  const auto g = random_grid(rng, 60, 1.5, 2);
  const auto lim = two_joint_limits();
  const auto sol = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(sol);
  EXPECT_EQ(sol->b.front(), 0.0);
  EXPECT_EQ(sol->b.back(), 0.0);
  const double tol = 1e-9;
  for (std::size_t i = 0; i + 1 < g.size(); ++i) {
    const double u = sol->u[i];
    EXPECT_NEAR(sol->b[i + 1], sol->b[i] + 2 * (g[i + 1].s - g[i].s) * u, 1e-12);
    EXPECT_LE(std::abs(u), lim.tangential * (1 + tol));
    for (std::size_t e = i; e <= i + 1; ++e) {
      const double b = sol->b[e];
      EXPECT_LE(std::sqrt(b), lim.speed * (1 + tol));
      EXPECT_LE(g[e].kappa * b, lim.centripetal * (1 + tol));
      for (int j = 0; j < 2; ++j) {
        EXPECT_LE(std::abs(g[e].q_s(j)) * std::sqrt(b), lim.joint_velocity(j) * (1 + tol));
        EXPECT_LE(std::abs(g[e].q_s(j) * u + g[e].q_ss(j) * b), lim.joint_acceleration(j) * (1 + tol));
      }
    }
  }
  // The profile reaches each grid point at the right arc length.
  core::ProfileCursor cur;
  for (const auto& piece : sol->profile.pieces) {
    const auto st = core::evaluate(sol->profile, piece.t0, cur);
    EXPECT_NEAR(st.s, piece.s0, 1e-12);
  }
  EXPECT_NEAR(core::evaluate(sol->profile, sol->duration).s, g.back().s, 1e-12);
  // The binding report covers [0, L] back to back, each stretch at its limit somewhere.
  ASSERT_FALSE(sol->binding.empty());
  EXPECT_EQ(sol->binding.front().s_start, 0.0);
  EXPECT_EQ(sol->binding.back().s_end, g.back().s);
  for (std::size_t k = 0; k + 1 < sol->binding.size(); ++k)
    EXPECT_EQ(sol->binding[k].s_end, sol->binding[k + 1].s_start);
  for (const auto& st : sol->binding) {
    std::printf("  %s\n", core::describe(st).c_str());
    EXPECT_GT(st.usage, 0.999) << core::describe(st);
    EXPECT_LE(st.usage, 1 + tol) << core::describe(st);
  }
}

// Larger limits, shorter motion (monotone in each limit).
TEST(TimeOptimalSweep, DurationDecreasesAsLimitsGrow) {
  std::mt19937_64 rng(11);
  const auto g = random_grid(rng, 80, 1.0, 2);
  double previous = kInf;
  for (double f : {0.5, 1.0, 2.0, 4.0}) {
    auto lim = two_joint_limits();
    lim.joint_velocity *= f;
    lim.joint_acceleration *= f;
    lim.speed *= f;
    lim.tangential *= f;
    lim.centripetal *= f;
    const auto sol = core::solve_time_optimal(g, lim);
    ASSERT_TRUE(sol);
    EXPECT_LT(sol->duration, previous) << "factor " << f;
    previous = sol->duration;
  }
}

// Closed form: straight line, speed and acceleration only: the minimum-time trapezoid. The
// ramp ends at s = v^2 / (2 a) = 0.2 m, a grid point (50 intervals over 1 m), so the grid
// solution is exact: T = L / v + v / a.
TEST(TimeOptimalSweep, StraightLineIsTheMinimumTimeTrapezoid) {
  std::vector<GridPoint> g(51);
  for (std::size_t i = 0; i < g.size(); ++i) g[i].s = static_cast<double>(i) / 50.0;
  TimeOptimalLimits lim;
  lim.speed = 1.0;
  lim.tangential = lim.centripetal = 2.5;
  const auto sol = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(sol);
  const auto ref = core::min_time_trapezoid(1.0, 1.0, 2.5);
  ASSERT_TRUE(ref);
  EXPECT_NEAR(sol->duration, ref->duration, 1e-12);
  EXPECT_NEAR(sol->duration, 1.4, 1e-12);
  ASSERT_EQ(sol->binding.size(), 3u);  // accelerate, cruise, brake
  EXPECT_EQ(sol->binding[0].kind, core::BindingKind::kTangentialAcceleration);
  EXPECT_EQ(sol->binding[1].kind, core::BindingKind::kCartesianSpeed);
  EXPECT_EQ(sol->binding[2].kind, core::BindingKind::kTangentialAcceleration);
  // The intervals next to the ramp ends bind both limits (a tie): one interval either way.
  EXPECT_NEAR(sol->binding[1].s_start, 0.2, 0.02 + 1e-12);
  EXPECT_NEAR(sol->binding[1].s_end, 0.8, 0.02 + 1e-12);
}

// Closed form with a torque: one joint, q = s, of inertia 2 kg m^2 under a constant load of
// 3 N m and a 5 N m limit: tau = 2 s_ddot + 3 within +-5 accelerates at most (5 - 3) / 2 = 1
// and brakes at most (5 + 3) / 2 = 4 m/s^2: the asymmetric bang-bang over 1 m switches at
// s = 4 / (1 + 4) = 0.8 m (a grid point), T = sqrt(2 0.8 / 1) + sqrt(2 0.2 / 4).
TEST(TimeOptimalSweep, ATorqueWithAGravityLoadIsTheAsymmetricBangBang) {
  std::vector<GridPoint> g(51);
  for (std::size_t i = 0; i < g.size(); ++i) {
    g[i].s = static_cast<double>(i) / 50.0;
    g[i].q_s = JointVector::Constant(1, 1.0);
    g[i].q_ss = JointVector::Zero(1);
    g[i].tau_a = JointVector::Constant(1, 2.0);
    g[i].tau_b = JointVector::Zero(1);
    g[i].tau_c = JointVector::Constant(1, 3.0);
  }
  TimeOptimalLimits lim;
  lim.joint_velocity = lim.joint_acceleration = JointVector::Constant(1, kInf);
  lim.joint_torque = JointVector::Constant(1, 5.0);
  const auto sol = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(sol) << sol.error().front().description;
  EXPECT_NEAR(sol->duration, std::sqrt(1.6) + std::sqrt(0.1), 1e-12);
  for (const auto& st : sol->binding) {
    EXPECT_EQ(st.kind, core::BindingKind::kJointTorque);
    EXPECT_LE(st.value, 5.0 * (1.0 + 1e-12));
  }
  for (std::size_t i = 0; i < sol->u.size(); ++i)  // the torque of every interval, from its s_ddot
    EXPECT_LE(std::abs(2.0 * sol->u[i] + 3.0), 5.0 * (1.0 + 1e-12)) << "interval " << i;
  // A load beyond the limit: no speed at all, named.
  for (auto& p : g) p.tau_c(0) = 6.0;
  const auto held = core::solve_time_optimal(g, lim);
  ASSERT_FALSE(held);
  EXPECT_NE(held.error().front().description.find("against gravity"), std::string::npos)
      << held.error().front().description;
}

// The same through the whole pipeline: a straight path, no robot.
TEST(TimeOptimalPlan, StraightPathThroughThePipeline) {
  core::PathSpec spec;
  spec.frames = {Frame({0, 0, 0}, {1, 0, 0}), Frame({0.5, 0, 0}, {1, 0, 0}), Frame({1, 0, 0}, {1, 0, 0})};
  const auto path = build_or_fail(spec);
  core::MotionSpec m;
  m.max_speed = 1.0;
  m.max_acceleration = 2.5;
  core::TimeOptimalOptions opt;
  opt.grid_intervals = 50;
  const auto plan = core::plan_time_optimal(path, core::OrientationPlan{}, m, nullptr, JointVector(), opt);
  ASSERT_TRUE(plan) << plan.error()[0].description;
  EXPECT_NEAR(plan->motion.duration_s, 1.4, 1e-9);
  EXPECT_EQ(plan->refinements, 0);
  EXPECT_LE(plan->motion.peak_speed, 1.0 + 1e-12);
  EXPECT_LE(plan->motion.peak_acceleration, 2.5 + 1e-12);
  EXPECT_EQ(plan->motion.sample_count, 141u);  // 1.4 s at 100 Hz: t = 0 .. 1.4
  core::MotionSampler sampler(path, plan->motion);
  core::MotionSample ms;
  double last = -1.0;
  while (sampler.next(ms)) {
    EXPECT_GE(ms.s, last - 1e-12);
    EXPECT_LE(ms.speed, 1.0 + 1e-9);
    last = ms.s;
  }
  EXPECT_NEAR(last, 1.0, 1e-12);
}

// ---------------------------------------------------------------------------------------
// The PA-10 along the thesis's demo path C.

struct Pa10C {
  core::Path path;
  core::OrientationPlan orientation;
  const core::RobotModel* robot = core::find_builtin_robot("pa10");
  JointVector seed;
  Pa10C() : path(build_or_fail(testing::thesis_demo_path('C'))) {
    auto o = core::plan_orientation(path);
    EXPECT_TRUE(o);
    orientation = *o;
    seed = core::home_configuration(*robot);
  }
};

/// The largest value / limit over every sample of the plan, streamed and tracked here.
double stream_usage(const Pa10C& c, const core::TimeOptimalPlan& plan, const core::RobotModel& robot) {
  core::MotionSampler sampler(c.path, plan.motion);
  core::JointTracker tracker(robot, c.seed);
  core::MotionSample ms;
  core::JointSample js;
  double worst = 0.0;
  while (sampler.next(ms)) {
    EXPECT_TRUE(tracker.track(core::cartesian_state(c.path, c.orientation, ms), js)) << "t " << ms.t;
    for (Eigen::Index j = 0; j < js.q_dot.size(); ++j) {
      const auto& l = robot.limits[static_cast<std::size_t>(j)];
      worst = std::max({worst, std::abs(js.q_dot(j)) / l.max_velocity, std::abs(js.q_ddot(j)) / l.max_acceleration});
    }
  }
  return worst;
}

TEST(TimeOptimalPlan, Pa10DemoPathC) {
  Pa10C c;
  core::MotionSpec m;
  const auto plan = core::plan_time_optimal(c.path, c.orientation, m, c.robot, c.seed);
  ASSERT_TRUE(plan) << plan.error()[0].description;
  std::printf("PA-10, demo path C: time-optimal %.4f s (thesis: 10 s fixed), %zu samples, %d refinements, "
              "worst sample usage %.9f\n",
              plan->motion.duration_s, plan->motion.sample_count, plan->refinements, plan->worst_sample_usage);
  for (const auto& st : plan->binding) std::printf("  portion %zu: %s\n", st.portion, core::describe(st).c_str());
  EXPECT_LT(plan->motion.duration_s, 10.0);
  ASSERT_EQ(plan->motion.portions.size(), 2u);  // the cusp at frame 2
  // Rest at the cusp: zero speed at the end of portion 0 and the start of portion 1.
  for (const auto& por : plan->motion.portions) {
    EXPECT_EQ(core::evaluate(por.profile, 0.0).v, 0.0);
    EXPECT_EQ(core::evaluate(por.profile, por.profile.duration).v, 0.0);
  }
  // Every streamed sample within the joint limits (independent of the planner's own check).
  EXPECT_LE(stream_usage(c, *plan, *c.robot), 1.0 + 1e-9);
  EXPECT_LE(plan->worst_sample_usage, 1.0 + 1e-9);
  // Limits hold at every grid point (both sides).
  for (std::size_t p = 0; p < plan->grids.size(); ++p) {
    const auto& g = plan->grids[p];
    const auto& sol = plan->solutions[p];
    for (std::size_t i = 0; i + 1 < g.size(); ++i)
      for (std::size_t e = i; e <= i + 1; ++e)
        for (Eigen::Index j = 0; j < 7; ++j) {
          EXPECT_LE(std::abs(g[e].q_s(j)) * std::sqrt(sol.b[e]), plan->limits.joint_velocity(j) * (1 + 1e-9));
          EXPECT_LE(std::abs(g[e].q_s(j) * sol.u[i] + g[e].q_ss(j) * sol.b[e]),
                    plan->limits.joint_acceleration(j) * (1 + 1e-9));
        }
  }
  // The binding report covers the motion back to back and names joints that bind.
  ASSERT_FALSE(plan->binding.empty());
  EXPECT_NEAR(plan->binding.back().t_end, plan->motion.duration_s, 1e-9);
  for (std::size_t k = 0; k + 1 < plan->binding.size(); ++k)
    EXPECT_NEAR(plan->binding[k].t_end, plan->binding[k + 1].t_start, 1e-12);

  // Larger joint limits: faster.
  core::RobotModel fast = *c.robot;
  for (auto& l : fast.limits) l.max_velocity *= 2, l.max_acceleration *= 2;
  const auto quicker = core::plan_time_optimal(c.path, c.orientation, m, &fast, c.seed);
  ASSERT_TRUE(quicker);
  EXPECT_LT(quicker->motion.duration_s, plan->motion.duration_s);
  // Cartesian limits on top: slower or equal.
  core::MotionSpec capped;
  capped.max_speed = 0.2;
  capped.max_acceleration = 0.5;
  const auto slower = core::plan_time_optimal(c.path, c.orientation, capped, c.robot, c.seed);
  ASSERT_TRUE(slower);
  EXPECT_GE(slower->motion.duration_s, plan->motion.duration_s);
  EXPECT_LE(slower->motion.peak_speed, 0.2 + 1e-12);
}

// The duration's grid error: |T(N) - T(N/2)| bounds how far T(N) is from the duration on a
// much finer grid (first-order convergence or better), and a finer grid is closer.
TEST(TimeOptimalPlan, DurationGridErrorBoundsTheChangeToAFinerGrid) {
  Pa10C c;
  core::MotionSpec m;
  core::TimeOptimalOptions coarse, fine;
  coarse.grid_intervals = 200;
  fine.grid_intervals = 1600;
  const auto a = core::plan_time_optimal(c.path, c.orientation, m, c.robot, c.seed, coarse);
  const auto b = core::plan_time_optimal(c.path, c.orientation, m, c.robot, c.seed, fine);
  ASSERT_TRUE(a) << a.error()[0].description;
  ASSERT_TRUE(b) << b.error()[0].description;
  const double change = std::abs(a->motion.duration_s - b->motion.duration_s);
  std::printf("200 intervals: %.6f s, estimated grid error %.6f s; 1,600: %.6f s (%.6f s)\n", a->motion.duration_s,
              a->duration_grid_error, b->motion.duration_s, b->duration_grid_error);
  EXPECT_GT(a->duration_grid_error, 0.0);
  EXPECT_LE(change, a->duration_grid_error);
  EXPECT_LT(b->duration_grid_error, a->duration_grid_error);
  EXPECT_EQ(a->check_rate_hz, 2000.0);  // 100 Hz, checked at 2 kHz between the samples
}

// The grid's claim: JointTracker at s_dot = 1, s_ddot = 0 gives q_s and q_ss = dq_s/ds
// (central differences of q_s over a 0.25 mm grid: error h^2 q_ssss / 6; near the path's
// start, where frame 1 leaves the curvature free, q_ss falls from about 640 to 220 rad/m^2
// within 2.5 mm, so the bound is relative to the local |q_ss|: 1 %).
TEST(TimeOptimalPlan, GridDerivativesAreArcLengthDerivatives) {
  Pa10C c;
  core::MotionSpec m;
  m.duration_s = 1.0;
  const auto portions = core::plan_motion(c.path, m);
  ASSERT_TRUE(portions);
  const auto grids = core::time_optimal_grids(c.path, c.orientation, portions->portions, c.robot, c.seed, 5000);
  ASSERT_TRUE(grids);
  for (const auto& g : *grids) {
    double scale = 0.0, worst = 0.0;
    for (std::size_t i = 1; i + 1 < g.size(); ++i) {
      const double h = g[i + 1].s - g[i - 1].s;
      const JointVector fd = (g[i + 1].q_s - g[i - 1].q_s) / h;
      scale = std::max(scale, g[i].q_ss.cwiseAbs().maxCoeff());
      const double local = std::max({g[i - 1].q_ss.cwiseAbs().maxCoeff(), g[i].q_ss.cwiseAbs().maxCoeff(),
                                     g[i + 1].q_ss.cwiseAbs().maxCoeff(), 1.0});
      worst = std::max(worst, (fd - g[i].q_ss).cwiseAbs().maxCoeff() / local);
    }
    EXPECT_LT(worst, 1e-2) << "largest relative difference " << worst << ", largest |q_ss| " << scale;
  }
}

// A point where the path has a corner (infinite curvature) admits only zero speed.
// The tool's angular limits on demo path A with a parallel-transport tool (omega = s_dot
// kappa B): every sample at 1 kHz within maxAngularSpeed and maxAngularAcceleration (the
// orientation's own analytic omega and alpha), one of them binding somewhere, and the
// binding stretches naming it; slower than without them.
TEST(TimeOptimalPlan, ToolAngularLimitsHoldAtEverySample) {
  core::PathSpec spec = testing::thesis_demo_path('A');
  for (auto& f : spec.frames) f.orientation_mode = core::OrientationMode::kParallelTransport;
  const core::Path path = build_or_fail(spec);
  const auto orientation = core::plan_orientation(path);
  ASSERT_TRUE(orientation) << orientation.error()[0].description;
  core::MotionSpec m;
  m.cycle_rate_hz = 1000.0;
  m.max_speed = 1.0;
  m.max_acceleration = 5.0;
  const auto free = core::plan_time_optimal(path, *orientation, m, nullptr, JointVector());
  ASSERT_TRUE(free) << free.error()[0].description;
  m.max_angular_speed = 2.0;
  m.max_angular_acceleration = 10.0;
  const auto plan = core::plan_time_optimal(path, *orientation, m, nullptr, JointVector());
  ASSERT_TRUE(plan) << plan.error()[0].description;
  core::MotionSampler sampler(path, plan->motion);
  core::MotionSample ms;
  double peak_w = 0.0, peak_a = 0.0;
  while (sampler.next(ms)) {
    const auto x = core::cartesian_state(path, *orientation, ms);
    peak_w = std::max(peak_w, x.omega_WT.norm());
    peak_a = std::max(peak_a, x.alpha_WT.norm());
  }
  bool named = false;
  for (const auto& st : plan->binding) {
    named = named || st.kind == core::BindingKind::kAngularSpeed || st.kind == core::BindingKind::kAngularAcceleration;
  }
  std::printf("demo path A, parallel transport: %.4f s with 2 rad/s and 10 rad/s^2 (%.4f s without), peak |omega| "
              "%.6f, |alpha| %.6f\n",
              plan->motion.duration_s, free->motion.duration_s, peak_w, peak_a);
  EXPECT_LE(peak_w, 2.0 * (1 + 1e-6));
  EXPECT_LE(peak_a, 10.0 * (1 + 1e-6));
  EXPECT_GT(std::max(peak_w / 2.0, peak_a / 10.0), 0.95);
  EXPECT_TRUE(named);
  EXPECT_GT(plan->motion.duration_s, free->motion.duration_s);
}

TEST(TimeOptimalErrors, ZeroSpeedPointIsNamed) {
  std::vector<GridPoint> g(21);
  for (std::size_t i = 0; i < g.size(); ++i) g[i].s = 0.05 * static_cast<double>(i);
  g[8].kappa = kInf;
  TimeOptimalLimits lim;
  lim.speed = 1.0;
  lim.tangential = lim.centripetal = 1.0;
  const auto sol = core::solve_time_optimal(g, lim);
  ASSERT_FALSE(sol);
  EXPECT_EQ(sol.error()[0].field, "motion");
  EXPECT_NE(sol.error()[0].description.find("s = 0.4 m"), std::string::npos) << sol.error()[0].description;
  EXPECT_NE(sol.error()[0].description.find("centripetal"), std::string::npos) << sol.error()[0].description;
}

// A joint with no velocity left where it must move: zero speed only, the joint named.
TEST(TimeOptimalErrors, JointThatCannotMoveIsNamed) {
  std::vector<GridPoint> g(11);
  for (std::size_t i = 0; i < g.size(); ++i) {
    g[i].s = 0.1 * static_cast<double>(i);
    g[i].q_s = JointVector::Constant(2, 1.0);
    g[i].q_ss = JointVector::Zero(2);
  }
  g[4].q_s(1) = 1e200;  // a singular point: joint 1 would need an unbounded rate
  TimeOptimalLimits lim;
  lim.joint_velocity = JointVector::Constant(2, 1.0);
  lim.joint_acceleration = JointVector::Constant(2, 1.0);
  const auto sol = core::solve_time_optimal(g, lim);
  ASSERT_FALSE(sol);
  EXPECT_NE(sol.error()[0].description.find("joint 1"), std::string::npos) << sol.error()[0].description;
}

// A path out of the robot's reach: the IK fails, the error names s and u.
TEST(TimeOptimalErrors, UnreachablePathIsNamed) {
  Pa10C c;
  core::RobotModel far = *c.robot;
  far.base.translation() = Eigen::Vector3d(5.0, 0.0, 0.0);
  const auto plan = core::plan_time_optimal(c.path, c.orientation, core::MotionSpec{}, &far, c.seed);
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error()[0].field, "motion");
  EXPECT_NE(plan.error()[0].description.find("IK fails at s = "), std::string::npos) << plan.error()[0].description;
  EXPECT_NE(plan.error()[0].description.find("u = "), std::string::npos);
}

TEST(TimeOptimalErrors, CartesianOnlyNeedsAnAcceleration) {
  Pa10C c;
  core::MotionSpec m;
  m.max_speed = 1.0;
  const auto plan = core::plan_time_optimal(c.path, c.orientation, m, nullptr, JointVector());
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error()[0].field, "motion.maxAcceleration");
}

}  // namespace
}  // namespace geotraj::test

namespace geotraj::test {
namespace {

// A cancelled call stops the sweep and its sample checks (TimeOptimalOptions::stop).
TEST(TimeOptimalPlan, AStopRequestEndsIt) {
  Pa10C c;
  std::stop_source stop;
  stop.request_stop();
  core::TimeOptimalOptions options;
  options.stop = stop.get_token();
  const auto plan = core::plan_time_optimal(c.path, c.orientation, core::MotionSpec{}, c.robot, c.seed, options);
  ASSERT_FALSE(plan);
  EXPECT_NE(plan.error()[0].description.find("stopped"), std::string::npos);
}

}  // namespace
}  // namespace geotraj::test
