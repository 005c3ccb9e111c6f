// Jerk-limited time-optimal timing (optim/timing/time_optimal_jerk.hpp), Ipopt warm-started from the
// exact sweep:
//  - with loose jerk limits (or none) it matches the exact sweep's time: same discretisation,
//    same limits, and the sweep's b is the minimum of the then convex programme;
//  - its gradient, Jacobian and Hessian agree with Ipopt's derivative checker;
//  - closed form: a straight line with maxSpeed, maxAcceleration and maxJerk is the
//    minimum-time double S (Biagiotti and Melchiorri 3.4, core::min_time_double_s);
//  - the result holds every limit at the grid points (speed, both-sided accelerations, jerks);
//  - a smoothness weight trades time for a smaller integral of the squared jerk;
//  - a tiny time budget ends with an honest kTimeLimit; the PA-10 along demo path C with
//    joint jerk limits, every streamed sample within the joint limits (the sample check and
//    its re-solves);
//  - limit_scale tightens the limits at single grid points;
//  - a degenerate limit (maxJerk 1e-10 m/s^3: a motion of hours to check sample by sample)
//    ends when its stop token is requested (the call's deadline or cancellation).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/geometry/path.hpp"
#include "core/motion/orientation.hpp"
#include "core/motion/speed_profile.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/time_optimal.hpp"
#include "jerk_grids.hpp"
#include "optim/timing/time_optimal_jerk.hpp"
#include "thesis_paths.hpp"

namespace geotraj::optim {
namespace {

using core::GridPoint;
using core::JointVector;
using jerk_test::joint_grid;
using jerk_test::joint_limits;
using jerk_test::kInf;
using jerk_test::line_grid;

/// tau_i = (t_{i-1} + t_i) / 2 of a result [s] (the rests: t_{-1} = t_N = 0).
double tau(const JerkTiming& r, std::size_t i) {
  return 0.5 * ((i > 0 ? r.dt[i - 1] : 0.0) + (i < r.dt.size() ? r.dt[i] : 0.0));
}

/// w_i, the width the NLP gives grid point i's ramp [s] (time_optimal_jerk.hpp): t_0 / 2 and
/// t_{N-1} / 2 at the rests, the smooth lower bound of min(t_{i-1}, t_i) inside.
double width(const JerkTiming& r, std::size_t i) {
  if (i == 0 || i == r.dt.size()) return tau(r, i);
  const double a = r.dt[i - 1] / 2, b = r.dt[i] / 2;
  return a + b - std::sqrt((a - b) * (a - b) + kJerkWindowSmoothing * a * b);
}

/// The grid's time, sum dt [s]: the profile lasts a quarter of the first and of the last
/// interval more (its ramps at the rests).
double grid_time(const JerkTiming& r) {
  double t = 0.0;
  for (double d : r.dt) t += d;
  return t;
}

// Every joint's jerk at every grid point of `g` under the timing `r` within `limit(j)`
// [rad/s^3]: the NLP's joint jerk rows recomputed here, q_ddd = q_s s_ddd + 3 q_ss s_d s_dd +
// q_sss(s) s_d^3 with s_d = sqrt(b), s_dd = u either side and s_ddd = du / w (on the ramp)
// or 0 (off it).
template <typename Limit>
void expect_joint_jerk_within(const std::vector<GridPoint>& g, const JerkTiming& r, Limit limit, std::size_t n) {
  const std::size_t N = g.size() - 1;
  for (std::size_t i = 0; i <= N; ++i) {
    const double v = std::sqrt(r.b[i]);
    const double u_prev = i > 0 ? r.u[i - 1] : 0.0, u_next = i < N ? r.u[i] : 0.0;
    const double jerk = (u_next - u_prev) / width(r, i);
    const std::size_t a = i == 0 ? 0 : i - 1, b = std::min(i + 1, N);
    const JointVector q_sss = (g[b].q_ss - g[a].q_ss) / (g[b].s - g[a].s);
    for (std::size_t j = 0; j < n; ++j) {
      const auto jj = static_cast<Eigen::Index>(j);
      for (const double u : {u_prev, u_next})
        for (const double s_ddd : {jerk, 0.0}) {
          const double q_ddd = g[i].q_s(jj) * s_ddd + 3 * g[i].q_ss(jj) * v * u + q_sss(jj) * v * v * v;
          EXPECT_LE(std::abs(q_ddd), limit(j) * (1 + 1e-6)) << "grid point " << i << " joint " << j;
        }
    }
  }
}

// Regression (the NLP used to end 7 % above the exact time here): with jerk limits that never
// bind, the sweep's b is feasible for the NLP (same limits in the same places) and the NLP is
// convex with that b as its minimum, so the two times agree to the solver's accuracy. Ipopt
// ends with a barrier parameter mu of about 1e-9, and a convex barrier problem's duality gap
// is at most m mu (m about 1,000 constraints here): 1e-6 s, below the 1e-6 relative (1.4e-6 s)
// allowed, and far below the 7 % of the bug and the 0.1 % of a grid change.
TEST(JerkTiming, LooseJerkMatchesTheExactSweep) {
  const auto g = joint_grid(201, 1.0);
  const auto lim = joint_limits();
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  JerkTimingOptions opt;
  opt.joint_jerk = JointVector::Constant(2, 1e6);
  opt.max_jerk = 1e6;
  const JerkTiming r = optimise_jerk_timing(g, lim, *exact, opt);
  std::printf("exact %.9f s, NLP %.9f s, %d iterations, %.1f ms, %s\n", exact->duration, r.duration,
              r.report.iterations, 1e3 * r.report.seconds, name(r.report.status));
  EXPECT_EQ(r.report.status, OptimizerStatus::kConverged) << r.report.message;
  EXPECT_NEAR(grid_time(r), exact->duration, 1e-6 * exact->duration);
  EXPECT_NEAR(r.duration, grid_time(r) + (r.dt.front() + r.dt.back()) / 4, 1e-12);
  EXPECT_NEAR(r.report.objective_before, exact->duration, 1e-12 * exact->duration);
  EXPECT_LE(r.max_constraint_violation, 1e-7);
  // And without any jerk limit (the exact problem itself).
  const JerkTiming free = optimise_jerk_timing(g, lim, *exact, {});
  EXPECT_EQ(free.report.status, OptimizerStatus::kConverged) << free.report.message;
  EXPECT_NEAR(grid_time(free), exact->duration, 1e-6 * exact->duration);
}

// Ipopt's second-order derivative checker on the gradient, Jacobian and Hessian, with every
// kind of term: Cartesian and joint jerk rows, the smoothness term, both rests. Forward
// differences with step 1e-8 [m^2/s^2] and relative tolerance 1e-4: the truncation error is
// about step / (4 b) (2e-6 at the smallest b here), the rounding error of the Hessian's
// differences of gradients about 1e-16 |gradient| / (step |entry|), up to 2e-5 for its
// smallest entries.
TEST(JerkTiming, DerivativesAgreeWithIpoptsChecker) {
  const auto g = joint_grid(21, 1.0);
  const auto lim = joint_limits();
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  JerkTimingOptions opt;
  opt.joint_jerk = JointVector::Constant(2, 5.0);
  opt.max_jerk = 10.0;
  opt.smoothness_weight = 1e-3;
  opt.max_iterations = 0;
  opt.derivative_test = true;
  ::testing::internal::CaptureStdout();
  (void)optimise_jerk_timing(g, lim, *exact, opt);
  const std::string log = ::testing::internal::GetCapturedStdout();
  EXPECT_NE(log.find("No errors detected by derivative checker"), std::string::npos) << log;
}

// A straight line, Cartesian limits only: the minimum-time double S. The NLP samples the
// limits at the grid points and spreads each acceleration step over the grid's time
// resolution, so its time is within about one interval's time of the closed form (200
// intervals: 1 %).
TEST(JerkTiming, StraightLineIsTheDoubleS) {
  const double L = 1.0, V = 1.0, A = 2.0, J = 10.0;
  const auto g = line_grid(201, L);
  core::TimeOptimalLimits lim;
  lim.speed = V;
  lim.tangential = lim.centripetal = A;
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  JerkTimingOptions opt;
  opt.max_jerk = J;
  const JerkTiming r = optimise_jerk_timing(g, lim, *exact, opt);
  const auto ref = core::min_time_double_s(L, V, A, J);
  ASSERT_TRUE(ref);
  std::printf("double S %.6f s, NLP %.6f s (trapezoid %.6f s), %d iterations, %.1f ms\n", ref->duration, r.duration,
              exact->duration, r.report.iterations, 1e3 * r.report.seconds);
  EXPECT_EQ(r.report.status, OptimizerStatus::kConverged) << r.report.message;
  // The double S is the fastest motion under these limits in continuous time: the profile
  // (continuous acceleration, finite jerk) cannot beat it, and the grid's resolution of
  // the jerk (ramps no wider than the shorter neighbouring interval, and a quarter of the
  // first and last intervals at the rests) costs a few per cent at 200 intervals.
  EXPECT_GE(r.duration, ref->duration * (1 - 1e-9));
  EXPECT_LE(r.duration, ref->duration * 1.07);
  EXPECT_GT(r.duration, exact->duration);  // the jerk limit costs time
  for (std::size_t i = 0; i < r.jerk.size(); ++i) {
    const double u_prev = i > 0 ? r.u[i - 1] : 0.0, u_next = i < r.u.size() ? r.u[i] : 0.0;
    EXPECT_NEAR(r.jerk[i], (u_next - u_prev) / width(r, i), 1e-9 * J) << "i " << i;
    EXPECT_LE(std::abs(r.jerk[i]), J * (1 + 1e-6)) << "i " << i;
  }
  // In continuous time: the profile's own pieces.
  EXPECT_LE(core::peak_jerk(r.profile), J * (1 + 1e-3));
  EXPECT_LE(core::peak_acceleration(r.profile), A * (1 + 1e-6));
  EXPECT_LE(core::peak_speed(r.profile), V * (1 + 1e-6));
  EXPECT_EQ(core::evaluate(r.profile, 0.0).a, 0.0);
  EXPECT_NEAR(core::evaluate(r.profile, r.duration).s, L, 1e-12);
  EXPECT_LT(r.report.objective_after, 1e9);
}

TEST(JerkTiming, JointJerkLimitsHoldAtTheGridPoints) {
  const auto g = joint_grid(101, 1.0);
  const auto lim = joint_limits();
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  JerkTimingOptions opt;
  opt.joint_jerk = JointVector::Constant(2, 5.0);
  const JerkTiming r = optimise_jerk_timing(g, lim, *exact, opt);
  std::printf("exact %.6f s, joint jerk 5: %.6f s, %d iterations, %.1f ms\n", exact->duration, r.duration,
              r.report.iterations, 1e3 * r.report.seconds);
  EXPECT_EQ(r.report.status, OptimizerStatus::kConverged) << r.report.message;
  EXPECT_GT(r.duration, exact->duration);
  const std::size_t N = g.size() - 1;
  for (std::size_t i = 0; i <= N; ++i) {
    const double v = std::sqrt(r.b[i]);
    const double u_prev = i > 0 ? r.u[i - 1] : 0.0, u_next = i < N ? r.u[i] : 0.0;
    const double jerk = (u_next - u_prev) / tau(r, i);
    const JointVector q_sss = (g[std::min(i + 1, N)].q_ss - g[i == 0 ? 0 : i - 1].q_ss) /
                              (g[std::min(i + 1, N)].s - g[i == 0 ? 0 : i - 1].s);
    for (int j = 0; j < 2; ++j) {
      EXPECT_LE(std::abs(g[i].q_s(j)) * v, lim.joint_velocity(j) * (1 + 1e-6));
      // Both sides of the point (the rests have one).
      const double a_max = lim.joint_acceleration(j) * (1 + 1e-6);
      if (i > 0) {
        EXPECT_LE(std::abs(g[i].q_s(j) * u_prev + g[i].q_ss(j) * r.b[i]), a_max) << "i " << i;
      }
      if (i < N) {
        EXPECT_LE(std::abs(g[i].q_s(j) * u_next + g[i].q_ss(j) * r.b[i]), a_max) << "i " << i;
      }
      const double jj = g[i].q_s(j) * jerk + 3 * g[i].q_ss(j) * v * 0.5 * (u_prev + u_next) + q_sss(j) * v * v * v;
      EXPECT_LE(std::abs(jj), 5.0 * (1 + 1e-6)) << "i " << i << " joint " << j;
    }
  }
}

TEST(JerkTiming, SmoothnessWeightTradesTime) {
  const auto g = line_grid(101, 1.0);
  core::TimeOptimalLimits lim;
  lim.speed = 1.0;
  lim.tangential = lim.centripetal = 2.0;
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  auto jerk_energy = [](const JerkTiming& r) {  // sum j^2 tau [m^2/s^5]
    double e = 0.0;
    for (std::size_t i = 0; i < r.jerk.size(); ++i) e += r.jerk[i] * r.jerk[i] * tau(r, i);
    return e;
  };
  JerkTimingOptions opt;
  opt.max_jerk = 20.0;
  const JerkTiming fast = optimise_jerk_timing(g, lim, *exact, opt);
  opt.smoothness_weight = 1e-2;
  const JerkTiming smooth = optimise_jerk_timing(g, lim, *exact, opt);
  EXPECT_EQ(fast.report.status, OptimizerStatus::kConverged) << fast.report.message;
  EXPECT_EQ(smooth.report.status, OptimizerStatus::kConverged) << smooth.report.message;
  EXPECT_GT(smooth.duration, fast.duration);
  EXPECT_LT(jerk_energy(smooth), jerk_energy(fast));
  EXPECT_NEAR(smooth.report.objective_after, grid_time(smooth) + 1e-2 * jerk_energy(smooth), 1e-9);
}

TEST(JerkTiming, TinyBudgetIsReportedAsTimeLimit) {
  const auto g = joint_grid(401, 1.0);
  const auto lim = joint_limits();
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  JerkTimingOptions opt;
  opt.joint_jerk = JointVector::Constant(2, 5.0);
  opt.time_budget_s = 1e-4;
  const JerkTiming r = optimise_jerk_timing(g, lim, *exact, opt);
  EXPECT_TRUE(r.report.status == OptimizerStatus::kTimeLimit || r.report.status == OptimizerStatus::kFailed)
      << name(r.report.status);
  EXPECT_NE(r.report.status, OptimizerStatus::kConverged);
}

// The thesis's demo path C (Table 7.18) and its orientation plan.
struct DemoPathC {
  core::Path path;
  core::OrientationPlan orientation;
};
DemoPathC demo_path_c() {
  core::Path path = core::build_path(testing::thesis_demo_path('C')).value();
  core::OrientationPlan orientation = core::plan_orientation(path).value();
  return {std::move(path), std::move(orientation)};
}

// The PA-10 with joint jerk limits of 4 maxAcceleration [rad/s^3].
core::RobotModel pa10_with_jerk_limits() {
  core::RobotModel robot = *core::find_builtin_robot("pa10");
  for (auto& l : robot.limits) l.max_jerk = 4.0 * l.max_acceleration;
  return robot;
}

TEST(JerkTiming, Pa10DemoPathCWithJointJerkLimits) {
  const DemoPathC c = demo_path_c();
  const core::RobotModel robot = pa10_with_jerk_limits();
  JerkTimingOptions opt;
  opt.time_budget_s = 30.0;
  const auto plan = plan_time_optimal_jerk(c.path, c.orientation, core::MotionSpec{}, &robot,
                                           core::home_configuration(robot), jerk_exact_options(), opt);
  ASSERT_TRUE(plan) << plan.error()[0].description;
  std::printf("PA-10, demo path C: exact %.4f s, jerk-limited %.4f s, %d iterations, %.1f ms, %s\n",
              plan->exact.motion.duration_s, plan->motion.duration_s, plan->report.iterations,
              1e3 * plan->report.seconds, name(plan->report.status));
  EXPECT_EQ(plan->report.status, OptimizerStatus::kConverged) << plan->report.message;
  EXPECT_GE(plan->motion.duration_s, plan->exact.motion.duration_s * 0.99);
  EXPECT_GT(plan->motion.sample_count, 0u);
}

// Regression: the NLP's limits held at the grid points only, and between them the PA-10's
// sampled joint accelerations along demo path C exceeded their limits by up to about 2 %
// (the service refused every jerk-limited PA-10 plan); then the profile's acceleration
// stepped at every grid point and at the start, so that the jerk of the streamed joints
// (differences of accelerations over the period) broke its limit at any rate (114 against
// 50 rad/s^3 at 100 Hz, without bound as the rate grows). Streamed at 100 Hz, 1 kHz and 10 kHz
// (MotionSampler + JointTracker, as the service streams it), every sample is now within the
// joint velocity, acceleration and jerk limits to 1e-9 relative, and the motion starts and
// ends with zero acceleration.
TEST(JerkTiming, Pa10DemoPathCEverySampleWithinTheLimitsAtAnyRate) {
  const DemoPathC c = demo_path_c();
  const core::RobotModel robot = pa10_with_jerk_limits();
  const JointVector seed = core::home_configuration(robot);
  const std::size_t n = robot.dof();
  for (const double rate : {100.0, 1000.0, 10000.0}) {
    core::MotionSpec spec;
    spec.duration_s = 0.0;
    spec.cycle_rate_hz = rate;
    JerkTimingOptions opt;
    opt.time_budget_s = 30.0;
    const auto plan = plan_time_optimal_jerk(c.path, c.orientation, spec, &robot, seed, jerk_exact_options(), opt);
    ASSERT_TRUE(plan) << plan.error()[0].description;
    EXPECT_EQ(plan->report.status, OptimizerStatus::kConverged) << plan->report.message;
    std::printf("%g Hz: %d refinements, worst sample usage %.12f, %.4f s, checked at %g Hz\n", rate,
                plan->refinements, plan->worst_sample_usage, plan->motion.duration_s, plan->check_rate_hz);
    EXPECT_LE(plan->worst_sample_usage, 1.0 + 1e-9);
    EXPECT_EQ(plan->check_rate_hz, std::max(2000.0, rate));

    // Stream it independently of the planner's own check.
    core::MotionSampler sampler(c.path, plan->motion);
    core::JointTracker tracker(robot, seed);
    core::MotionSample ms;
    core::JointSample js;
    JointVector q_ddot_prev;
    double t_prev = 0.0, worst = 0.0, worst_jerk = 0.0;
    std::size_t samples = 0;
    while (sampler.next(ms)) {
      ASSERT_TRUE(tracker.track(core::cartesian_state(c.path, c.orientation, ms), js)) << "t " << ms.t;
      if (samples == 0 || samples + 1 == plan->motion.sample_count) {
        EXPECT_EQ(ms.s_ddot, 0.0) << "the motion starts and ends without acceleration, t " << ms.t;
        EXPECT_LE(js.q_ddot.cwiseAbs().maxCoeff(), 1e-9) << "t " << ms.t;
      }
      for (std::size_t j = 0; j < n; ++j) {
        const auto jj = static_cast<Eigen::Index>(j);
        const double v = std::abs(js.q_dot(jj)) / robot.limits[j].max_velocity;
        const double a = std::abs(js.q_ddot(jj)) / robot.limits[j].max_acceleration;
        worst = std::max({worst, v, a});
        EXPECT_LE(v, 1.0 + 1e-9) << rate << " Hz, t " << ms.t << " joint " << j << " velocity";
        EXPECT_LE(a, 1.0 + 1e-9) << rate << " Hz, t " << ms.t << " joint " << j << " acceleration";
        if (samples > 0) {
          const double jerk = std::abs(js.q_ddot(jj) - q_ddot_prev(jj)) / (ms.t - t_prev) / *robot.limits[j].max_jerk;
          worst_jerk = std::max(worst_jerk, jerk);
          EXPECT_LE(jerk, 1.0 + 1e-9) << rate << " Hz, t " << ms.t << " joint " << j << " jerk";
        }
      }
      q_ddot_prev = js.q_ddot;
      t_prev = ms.t;
      ++samples;
    }
    EXPECT_EQ(samples, plan->motion.sample_count);
    EXPECT_GT(worst, 0.99) << "the limits bind somewhere: the check is not vacuous";
    EXPECT_GT(worst_jerk, 0.5) << "the jerk limit is used";

    // Between the samples: the same motion sampled at 20 kHz stays within the bounds the
    // check at 2 kHz (h = 0.5 ms) states: a velocity within a_max h / 2 of its limit, an
    // acceleration within j_max h / 2, the jerk (means over 50 us) within 1 %.
    if (rate != 100.0) continue;
    core::MotionPlan fine = plan->motion;
    fine.spec.cycle_rate_hz = 20000.0;
    fine.sample_count = core::grid_sample_count(fine.duration_s, fine.spec.cycle_rate_hz);
    const double h = 1.0 / 2000.0;
    core::MotionSampler fine_sampler(c.path, fine);
    core::JointTracker fine_tracker(robot, seed);
    samples = 0;
    double excess = 0.0;
    while (fine_sampler.next(ms)) {
      ASSERT_TRUE(fine_tracker.track(core::cartesian_state(c.path, c.orientation, ms), js)) << "t " << ms.t;
      for (std::size_t j = 0; j < n; ++j) {
        const auto jj = static_cast<Eigen::Index>(j);
        const auto& l = robot.limits[j];
        excess = std::max(excess, std::abs(js.q_dot(jj)) / (l.max_velocity + l.max_acceleration * h / 2));
        excess = std::max(excess, std::abs(js.q_ddot(jj)) / (l.max_acceleration + *l.max_jerk * h / 2));
        if (samples > 0)
          excess = std::max(excess, std::abs(js.q_ddot(jj) - q_ddot_prev(jj)) / (ms.t - t_prev) / (*l.max_jerk * 1.01));
      }
      q_ddot_prev = js.q_ddot;
      t_prev = ms.t;
      ++samples;
    }
    std::printf("  sampled at 20 kHz: worst use of the stated bounds %.6f\n", excess);
    EXPECT_LE(excess, 1.0);
  }
}

// Refinements that do not settle end in a uniform slow-down of the last result, not in an
// error: with no refinement allowed, the PA-10's first jerk-limited result along demo path C
// (its jerk 2-3 times the limit between grid points) is slowed by the worst usage, and every
// sample streamed from the result, independently of the planner's check, is within the joint
// velocity, acceleration and jerk limits. With the refinements allowed it settles unslowed.
TEST(JerkTiming, RefinementsThatDoNotSettleSlowTheLastResultUniformly) {
  const DemoPathC c = demo_path_c();
  const core::RobotModel robot = pa10_with_jerk_limits();
  const JointVector seed = core::home_configuration(robot);
  JerkTimingOptions opt;
  opt.time_budget_s = 30.0;
  core::MotionSpec spec;
  spec.duration_s = 0.0;
  const auto settled = plan_time_optimal_jerk(c.path, c.orientation, spec, &robot, seed, jerk_exact_options(), opt);
  ASSERT_TRUE(settled) << settled.error()[0].description;
  EXPECT_EQ(settled->slowed_by, 1.0);
  EXPECT_GT(settled->refinements, 0) << "the first result breaks a limit: the case tests the fallback";

  JerkTimingOptions once = opt;
  once.max_refinements = 0;
  const auto plan = plan_time_optimal_jerk(c.path, c.orientation, spec, &robot, seed, jerk_exact_options(), once);
  ASSERT_TRUE(plan) << plan.error()[0].description;
  EXPECT_EQ(plan->refinements, 0);
  EXPECT_GT(plan->slowed_by, 1.0);
  std::printf("no refinement: slowed by %.4f, %.4f s (refined: %d rounds, %.4f s)\n", plan->slowed_by,
              plan->motion.duration_s, settled->refinements, settled->motion.duration_s);
  EXPECT_LE(plan->worst_sample_usage, 1.0 + 1e-9);
  EXPECT_THAT(plan->report.message, ::testing::HasSubstr("slowed by"));
  double portions = 0.0;
  for (const auto& jt : plan->portions) portions += jt.profile.duration;
  EXPECT_NEAR(plan->motion.duration_s, portions, 1e-6);
  EXPECT_GT(plan->motion.duration_s, settled->motion.duration_s) << "slower than the refined result";

  core::MotionSampler sampler(c.path, plan->motion);
  core::JointTracker tracker(robot, seed);
  core::MotionSample ms;
  core::JointSample js;
  JointVector q_ddot_prev;
  double t_prev = 0.0, worst = 0.0;
  std::size_t samples = 0;
  while (sampler.next(ms)) {
    ASSERT_TRUE(tracker.track(core::cartesian_state(c.path, c.orientation, ms), js)) << "t " << ms.t;
    for (std::size_t j = 0; j < robot.dof(); ++j) {
      const auto jj = static_cast<Eigen::Index>(j);
      const auto& l = robot.limits[j];
      worst = std::max({worst, std::abs(js.q_dot(jj)) / l.max_velocity, std::abs(js.q_ddot(jj)) / l.max_acceleration});
      if (samples > 0) worst = std::max(worst, std::abs(js.q_ddot(jj) - q_ddot_prev(jj)) / (ms.t - t_prev) / *l.max_jerk);
    }
    q_ddot_prev = js.q_ddot;
    t_prev = ms.t;
    ++samples;
  }
  EXPECT_EQ(samples, plan->motion.sample_count);
  EXPECT_LE(worst, 1.0 + 1e-9);
  EXPECT_GT(worst, 0.3) << "slowed by the worst usage, not more: some limit is still well used";
}

// limit_scale at one grid point: that point's velocity cap scales by sigma^2 in b, the rest
// of the grid keeps its limits.
TEST(JerkTiming, LimitScaleTightensOnePoint) {
  const auto g = line_grid(101, 1.0);
  core::TimeOptimalLimits lim;
  lim.speed = 1.0;
  lim.tangential = lim.centripetal = 2.0;
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  JerkTimingOptions opt;
  opt.max_jerk = 20.0;
  const JerkTiming free = optimise_jerk_timing(g, lim, *exact, opt);
  // A path with joint limits: tighten the joint velocity at the middle point to 0.5.
  auto jg = g;
  for (auto& p : jg) {
    p.q_s = JointVector::Constant(1, 1.0);
    p.q_ss = JointVector::Constant(1, 0.0);
  }
  lim.joint_velocity = JointVector::Constant(1, 1.0);
  lim.joint_acceleration = JointVector::Constant(1, kInf);
  opt.limit_scale.assign(jg.size(), 1.0);
  opt.limit_scale[50] = 0.5;
  const JerkTiming tight = optimise_jerk_timing(jg, lim, *exact, opt);
  EXPECT_EQ(free.report.status, OptimizerStatus::kConverged) << free.report.message;
  EXPECT_EQ(tight.report.status, OptimizerStatus::kConverged) << tight.report.message;
  EXPECT_LE(tight.b[50], 0.25 * (1 + 1e-6));
  EXPECT_GT(free.b[50], 0.9);
  EXPECT_GT(tight.duration, free.duration);
}

}  // namespace
// Implied jerk rows (JerkTimingOptions::drop_implied_jerk_rows): on the PA-10 along demo path
// C (200 intervals, joint jerk limits of 4 a_max) the rows that the kept ones and the
// velocity and acceleration limits imply are left out of Ipopt's problem. The feasible set
// is the same, so the optimum is the same as with every row to Ipopt's accuracy, and every
// left-out row holds at the result (max_constraint_violation covers every row, and the
// joint jerks are recomputed here from the returned profile).
TEST(JerkTiming, ImpliedJerkRowsLeaveTheOptimumUnchanged) {
  auto path = core::build_path(testing::thesis_demo_path('C'));
  ASSERT_TRUE(path);
  auto orientation = core::plan_orientation(*path);
  ASSERT_TRUE(orientation);
  const core::RobotModel robot = *core::find_builtin_robot("pa10");
  core::MotionSpec m;
  m.duration_s = 1.0;
  const auto portions = core::plan_motion(*path, m);
  ASSERT_TRUE(portions);
  const auto grids = core::time_optimal_grids(*path, *orientation, portions->portions, &robot,
                                              core::home_configuration(robot), 200);
  ASSERT_TRUE(grids);
  const auto lim = core::time_optimal_limits(core::MotionSpec{}, &robot);
  const std::size_t n = robot.dof();
  JerkTimingOptions opt;
  opt.joint_jerk.resize(static_cast<Eigen::Index>(n));
  for (Eigen::Index j = 0; j < opt.joint_jerk.size(); ++j) opt.joint_jerk(j) = 4.0 * lim.joint_acceleration(j);
  opt.time_budget_s = 30.0;
  for (const auto& g : *grids) {
    const auto exact = core::solve_time_optimal(g, lim);
    ASSERT_TRUE(exact);
    const JerkTiming dropped = optimise_jerk_timing(g, lim, *exact, opt);
    JerkTimingOptions all = opt;
    all.drop_implied_jerk_rows = false;
    const JerkTiming full = optimise_jerk_timing(g, lim, *exact, all);
    std::printf("%zu of %zu jerk rows implied; %.9f s (%d iterations) against %.9f s (%d) with every row\n",
                dropped.implied_jerk_rows, dropped.jerk_rows, dropped.duration, dropped.report.iterations,
                full.duration, full.report.iterations);
    ASSERT_EQ(dropped.report.status, OptimizerStatus::kConverged) << dropped.report.message;
    ASSERT_EQ(full.report.status, OptimizerStatus::kConverged) << full.report.message;
    EXPECT_EQ(full.implied_jerk_rows, 0u);
    EXPECT_EQ(dropped.jerk_rows, 4 * g.size() * n);  // with and without the ramp, either side
    EXPECT_GT(dropped.implied_jerk_rows, dropped.jerk_rows / 10);  // the test is not vacuous
    EXPECT_NEAR(dropped.duration, full.duration, 1e-6 * full.duration);
    EXPECT_NEAR(dropped.report.objective_after, full.report.objective_after, 1e-6 * full.report.objective_after);
    EXPECT_LE(dropped.max_constraint_violation, 1e-6 * opt.joint_jerk.minCoeff());
    // Every joint jerk row, the left-out ones included, at every grid point.
    expect_joint_jerk_within(
        g, dropped, [&](std::size_t j) { return opt.joint_jerk(static_cast<Eigen::Index>(j)); }, n);
  }
}

// A row implied by another at every grid point is left out, the one that binds is kept: two
// joints along a line, joint 1 moving half as fast as joint 0 (q_s = 1 and 0.5 [rad/m], no
// curvature terms), so |q_ddd_1| = |q_ddd_0| / 2 everywhere. With the same jerk limit joint
// 1's rows are implied by joint 0's; with joint 1's limit below half of joint 0's, joint 0's
// are implied by joint 1's, and joint 1's limit binds.
TEST(JerkTiming, ImpliedRowIsTheDominatedJoint) {
  auto g = line_grid(51, 1.0);
  for (auto& p : g) {
    p.q_s = JointVector(2);
    p.q_s << 1.0, 0.5;
    p.q_ss = JointVector::Zero(2);
  }
  core::TimeOptimalLimits lim;
  lim.joint_velocity = JointVector::Constant(2, 1.0);
  lim.joint_acceleration = JointVector::Constant(2, 2.0);
  const auto exact = core::solve_time_optimal(g, lim);
  ASSERT_TRUE(exact);
  JerkTimingOptions opt;
  opt.joint_jerk = JointVector::Constant(2, 10.0);
  const JerkTiming r = optimise_jerk_timing(g, lim, *exact, opt);
  ASSERT_EQ(r.report.status, OptimizerStatus::kConverged) << r.report.message;
  // Four rows per joint and point (with and without the ramp, s_ddot either side). Without
  // curvature terms the two rows with the ramp are one, and those without are 0: implied.
  EXPECT_EQ(r.jerk_rows, 4 * 2 * g.size());
  // Joint 1 (half of joint 0's jerk) everywhere, in both rows with the ramp, and the four
  // rows without the ramp.
  EXPECT_EQ(r.implied_jerk_rows, (2 + 4) * g.size());
  opt.joint_jerk(1) = 4.0;                   // joint 1 now binds first: joint 0 is implied
  const JerkTiming r1 = optimise_jerk_timing(g, lim, *exact, opt);
  ASSERT_EQ(r1.report.status, OptimizerStatus::kConverged) << r1.report.message;
  EXPECT_EQ(r1.implied_jerk_rows, (2 + 4) * g.size());
  double worst = 0.0;
  for (const double j : r1.jerk) worst = std::max(worst, std::abs(0.5 * j) / 4.0);
  EXPECT_LE(worst, 1.0 + 1e-6);
  EXPECT_GT(worst, 0.99);  // joint 1's limit binds
}

// Regression: with a Cartesian maxJerk of 1e-10 m/s^3 the jerk-limited motion of
// the PA-10 along demo path C lasts hours, and the sample check of its every sample ran on,
// deaf to the call's stop token, 22 s past a 2 s deadline. The token requested while it
// plans (as gRPC does at the deadline) now ends it with `motion` "stopped", not a plan. The
// stop comes early in the work (its solves and checks take about a second on a 2-core
// machine, and refuse the limit at their end), so that it is the stop that ends it.
TEST(JerkTiming, ADegenerateJerkLimitEndsAtItsStopToken) {
  auto path = core::build_path(testing::thesis_demo_path('C'));
  ASSERT_TRUE(path);
  auto orientation = core::plan_orientation(*path);
  ASSERT_TRUE(orientation);
  const core::RobotModel robot = *core::find_builtin_robot("pa10");
  core::MotionSpec spec;
  spec.duration_s = 0.0;
  spec.max_jerk = 1e-10;  // [m/s^3]
  std::stop_source deadline;
  JerkTimingOptions opt;
  opt.time_budget_s = 0.5;
  opt.stop = deadline.get_token();
  std::jthread at_deadline([&deadline] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    deadline.request_stop();
  });
  const auto t0 = std::chrono::steady_clock::now();
  const auto plan = plan_time_optimal_jerk(*path, *orientation, spec, &robot, core::home_configuration(robot),
                                           jerk_exact_options(), opt);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("maxJerk 1e-10: %s after %.2f s\n",
              plan ? "a plan" : plan.error().front().description.c_str(), seconds);
  ASSERT_FALSE(plan) << "planned a motion of " << plan->motion.duration_s << " s instead of stopping";
  EXPECT_EQ(plan.error().front().field, "motion");
  EXPECT_NE(plan.error().front().description.find("stopped"), std::string::npos) << plan.error().front().description;
}

}  // namespace geotraj::optim
