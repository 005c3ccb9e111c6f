// Live execution (core/live/execution.hpp) and its building block, the jerk-limited rate
// change (core/live/rate_profile.hpp), on the thesis's demonstration path C with the PA-10:
// full speed repeats the plan exactly, every set point stands on the plan at its plan time,
// an override change, a pause and a stop keep the joint limits (finite differences of the
// set points), stops come within the predicted time, and a plan with no room to slow down
// is refused with the limit named.
#include "core/live/execution.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/geometry/path.hpp"
#include "core/live/rate_profile.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/time_optimal.hpp"
#include "core/robot/dynamics.hpp"
#include "core/robot/robot.hpp"
#include "random_robot.hpp"
#include "test_support.hpp"
#include "thesis_paths.hpp"

namespace geotraj {
namespace {

using core::JointVector;
using core::LiveSample;
using core::LiveState;
using core::RateProfile;

// --- the rate profile ------------------------------------------------------------------------

TEST(RateProfile, FromRestTheClosedFormTime) {
  // A cruise phase: T = dv / a + a / j; none: T = 2 sqrt(dv / j).
  EXPECT_NEAR(RateProfile::plan(1.0, 0.0, 0.0, 2.0, 8.0).duration(), 0.5 + 0.25, 1e-12);
  EXPECT_NEAR(RateProfile::plan(0.0, 0.0, 0.1, 2.0, 8.0).duration(), 2.0 * std::sqrt(0.1 / 8.0), 1e-12);
  // Symmetric: the integral is the mean of the ends times the time.
  const RateProfile p = RateProfile::plan(1.0, 0.0, 0.0, 2.0, 8.0);
  EXPECT_NEAR(p.distance(), 0.5 * p.duration(), 1e-12);
}

// Random starts and targets: the profile lands on the target at rest, never exceeds the
// acceleration and jerk bounds, and its value, acceleration and integral are continuous.
TEST(RateProfile, RandomChangesKeepTheirBounds) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int cases = test::property_case_count(2000);
  for (int c = 0; c < cases; ++c) {
    const double A = 0.1 + 5.0 * std::abs(u(rng)), J = 0.5 + 50.0 * std::abs(u(rng));
    const double v0 = u(rng), v1 = u(rng), a0 = A * u(rng);
    const RateProfile p = RateProfile::plan(v0, a0, v1, A, J);
    SCOPED_TRACE("plan(" + std::to_string(v0) + ", " + std::to_string(a0) + ", " + std::to_string(v1) + ", " +
                 std::to_string(A) + ", " + std::to_string(J) + ")");
    const core::RateState end = p.at(p.duration());
    EXPECT_NEAR(end.v, v1, 1e-9);
    EXPECT_NEAR(end.a, 0.0, 1e-9);
    const int n = 400;
    core::RateState prev = p.at(0.0);
    EXPECT_DOUBLE_EQ(prev.v, v0);
    EXPECT_DOUBLE_EQ(prev.a, a0);
    for (int k = 1; k <= n; ++k) {
      const double t = p.duration() * k / n;
      const core::RateState s = p.at(t);
      EXPECT_LE(std::abs(s.a), std::max(A, std::abs(a0)) * (1 + 1e-9));
      EXPECT_LE(std::abs(s.j), J * (1 + 1e-12));
      const double dt = p.duration() / n;
      EXPECT_LE(std::abs(s.a - prev.a), J * dt * (1 + 1e-9) + 1e-12);
      EXPECT_LE(s.v, p.max_value() + 1e-12);
      EXPECT_GE(s.v, p.min_value() - 1e-12);
      prev = s;
    }
  }
}

// --- the speed factor's bounds ---------------------------------------------------------------

TEST(FactorBounds, TheFormulasOfTheFileComment) {
  core::LiveRow row{"joint 1", "rad", 2.0, 3.0, 20.0, 4.0, 50.0};
  const std::vector<core::LiveRow> rows{row};
  const core::FactorBounds b = core::factor_bounds(rows, 1.0, 0.05);
  // rd = min((4 - 3) / 2, (50 - 20) / (6 * 3)) = 0.5; rdd = (50 - 20 - 3 * 3 * 0.5) / 2.
  EXPECT_DOUBLE_EQ(b.acceleration, 0.5);
  EXPECT_DOUBLE_EQ(b.jerk, (30.0 - 4.5) / 2.0);
  EXPECT_FALSE(b.jerk_from_ramp);
  // At r_h = 0.5 the room grows: (4 - 3 / 4) / 2.
  EXPECT_DOUBLE_EQ(core::factor_bounds(rows, 0.5, 0.05).acceleration, std::min(3.25 / 2.0, (50.0 - 2.5) / 9.0));
  // The stop from full speed: T = r / rd + rd / rdd, covering r T / 2 of plan time.
  const core::StopPrediction stop = core::predict_stop(1.0, 0.0, b);
  EXPECT_NEAR(stop.time_s, 1.0 / b.acceleration + b.acceleration / b.jerk, 1e-12);
  EXPECT_NEAR(stop.plan_time_s, 0.5 * stop.time_s, 1e-12);
  // A limit used fully at full speed leaves no room there.
  core::LiveRow full = row;
  full.peak_acceleration = 4.0;
  EXPECT_EQ(core::factor_bounds({full}, 1.0, 0.05).acceleration, 0.0);
}

// A quantity the plan barely moves (a peak rate of 1e-298, rounding's): its room of 1e307 / s
// once gave, over the 0.05 s ramp, an infinite jerk bound, which the rate profile of every
// cycle refuses by aborting the process. The bounds are capped, finite, and a change plans.
TEST(FactorBounds, ABarelyMovingQuantityGivesFiniteBounds) {
  const core::LiveRow barely{"joint 0", "rad", 1e-298, 0.0, 0.0, 1e9, std::numeric_limits<double>::infinity()};
  for (const double r : {1.0, 0.5, 0.0}) {
    const core::FactorBounds b = core::factor_bounds({barely}, r, 0.05);
    EXPECT_TRUE(std::isfinite(b.acceleration) && b.acceleration > 0.0) << b.acceleration;
    EXPECT_TRUE(std::isfinite(b.jerk) && b.jerk > 0.0) << b.jerk;
    const core::StopPrediction stop = core::predict_stop(1.0, 0.0, b);
    EXPECT_TRUE(std::isfinite(stop.time_s) && stop.time_s > 0.0) << stop.time_s;
  }
}

// --- live execution on the PA-10 along path C ------------------------------------------------

// The default reserve of Execute (planner::reserve_room): 10 % of every acceleration.
const double kReserved = std::sqrt(0.9);

struct Pa10C {
  const core::RobotModel* robot = core::find_builtin_robot("pa10");
  JointVector seed = core::home_configuration(*robot);
  core::Trajectory trajectory;
  core::MotionSpec spec;

  // durationS > 0: the thesis's 10 s trapezoid; 0: time-optimal at `speed_scale`.
  explicit Pa10C(double duration_s, double speed_scale = 1.0) {
    core::Path path = test::build_or_fail(testing::thesis_demo_path('C'));
    auto orientation = core::plan_orientation(path);
    EXPECT_TRUE(orientation);
    spec.duration_s = duration_s;
    spec.speed_scale = speed_scale;
    core::MotionPlan timing;
    if (duration_s > 0.0) {
      auto planned = core::plan_motion(path, spec);
      EXPECT_TRUE(planned);
      timing = *planned;
    } else {
      auto planned = core::plan_time_optimal(path, *orientation, spec, robot, seed);
      EXPECT_TRUE(planned) << planned.error()[0].description;
      timing = planned->motion;
    }
    trajectory = core::PathMotion{std::move(path), std::move(timing), std::move(*orientation)};
  }

  core::Expected<core::LiveExecution> start() const {
    return core::LiveExecution::start(trajectory, robot, seed, core::live_limits(robot), spec.cycle_rate_hz);
  }
};

// Commands at given times [s] of the live clock.
struct Script {
  double t;
  void (*act)(core::LiveExecution&);
};

std::vector<LiveSample> run(core::LiveExecution& live, const std::vector<Script>& script, double max_s = 120.0) {
  std::vector<LiveSample> out;
  LiveSample s;
  std::size_t next = 0;
  while (live.next(s)) {
    out.push_back(s);
    while (next < script.size() && s.sample.t + 1e-12 >= script[next].t) script[next++].act(live);
    if (s.sample.t > max_s) break;
  }
  return out;
}

// Every joint within its velocity and acceleration limits by finite differences of the set
// points (the mean velocity over a period; the second difference), and the streamed joint
// velocities and accelerations within them too. Returns the largest usage.
double check_limits(const std::vector<LiveSample>& samples, const core::RobotModel& robot) {
  double usage = 0.0;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    const auto& a = samples[k - 1].sample.joints;
    const auto& b = samples[k].sample.joints;
    const double h = samples[k].sample.t - samples[k - 1].sample.t;
    for (Eigen::Index j = 0; j < b.q.size(); ++j) {
      const auto& l = robot.limits[static_cast<std::size_t>(j)];
      const double v = (b.q(j) - a.q(j)) / h;
      EXPECT_LE(std::abs(v), l.max_velocity * (1 + 1e-6)) << "joint " << j << " t " << samples[k].sample.t;
      EXPECT_LE(std::abs(b.q_ddot(j)), l.max_acceleration * (1 + 1e-6)) << "joint " << j << " t " << samples[k].sample.t;
      usage = std::max({usage, std::abs(v) / l.max_velocity, std::abs(b.q_ddot(j)) / l.max_acceleration});
      if (k + 1 < samples.size()) {
        const double acc = (samples[k + 1].sample.joints.q(j) - 2.0 * b.q(j) + a.q(j)) / (h * h);
        EXPECT_LE(std::abs(acc), l.max_acceleration * 1.02) << "joint " << j << " t " << samples[k].sample.t;
      }
    }
  }
  return usage;
}

// Each set point is the plan's own sample at its plan time (the same IK branch): on the path.
void check_on_plan(const Pa10C& c, const std::vector<LiveSample>& samples) {
  core::TrajectorySampler plan(c.trajectory, c.robot, c.seed);
  core::TrajectorySample x;
  for (const LiveSample& s : samples) {
    plan.at(s.plan_time, x);
    EXPECT_LE((x.tool.X_WT.translation() - s.sample.tool.X_WT.translation()).norm(), 1e-12) << "t " << s.sample.t;
    EXPECT_LE((x.joints.q - s.sample.joints.q).norm(), 1e-12) << "t " << s.sample.t;
  }
}

TEST(LiveExecution, FullSpeedRepeatsThePlan) {
  const Pa10C c(0.0, kReserved);
  auto started = c.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  auto& live = *started;
  const auto samples = run(live, {});
  core::TrajectorySampler plan(c.trajectory, c.robot, c.seed);
  core::TrajectorySample x;
  std::size_t k = 0;
  while (plan.next(x)) {
    ASSERT_LT(k, samples.size());
    // Live samples stay on the controller's clock (k / rate): the plan's last sample, at
    // exactly its duration, comes at the first cycle at or after it.
    EXPECT_NEAR(samples[k].sample.t, static_cast<double>(k) / c.spec.cycle_rate_hz, 1e-12);
    EXPECT_LT(samples[k].sample.t - x.t, 1.0 / c.spec.cycle_rate_hz);
    EXPECT_GE(samples[k].sample.t - x.t, -1e-12);
    EXPECT_LE((samples[k].sample.joints.q - x.joints.q).norm(), 1e-12) << "k " << k;
    EXPECT_LE((samples[k].sample.joints.q_dot - x.joints.q_dot).norm(), 1e-12) << "k " << k;
    ++k;
  }
  EXPECT_EQ(k, samples.size());
  EXPECT_EQ(samples.back().state, LiveState::kCompleted);
  EXPECT_EQ(live.state(), LiveState::kCompleted);
}

TEST(LiveExecution, AnOverrideChangeStaysOnThePathWithinTheLimits) {
  const Pa10C c(0.0, kReserved);
  auto started = c.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  auto& live = *started;
  const auto samples = run(live, {{2.0, [](core::LiveExecution& l) { l.set_override(0.3); }},
                                  {6.0, [](core::LiveExecution& l) { l.set_override(1.0); }}});
  EXPECT_EQ(samples.back().state, LiveState::kCompleted);
  EXPECT_NEAR(samples.back().plan_time, live.plan_duration(), 1e-12);
  double slowest = 1.0;
  for (const auto& s : samples) {
    if (s.sample.t > 2.0 && s.sample.t < 6.0) slowest = std::min(slowest, s.speed_factor);
  }
  EXPECT_NEAR(slowest, 0.3, 1e-12);
  check_limits(samples, *c.robot);
  check_on_plan(c, samples);
  // Slower: longer than the plan.
  EXPECT_GT(samples.back().sample.t, live.plan_duration() + 1.0);
}

// The torques streamed live (a model with mass properties: the PA-10 given random ones and a
// payload) are those of the motion as it runs, at its speed factor: inverse dynamics of each
// set point's own joints, velocities and accelerations, through an override change and back.
TEST(LiveExecution, TheTorquesAreThoseOfTheMotionAsItRuns) {
  std::mt19937_64 rng(7);
  core::RobotModel model = test::with_random_inertials(*core::find_builtin_robot("pa10"), rng);
  model.payload.mass = 2.0;
  Pa10C c(0.0, kReserved);
  c.robot = &model;
  auto started = c.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  const auto samples = run(*started, {{2.0, [](core::LiveExecution& l) { l.set_override(0.3); }},
                                      {6.0, [](core::LiveExecution& l) { l.set_override(1.0); }}});
  JointVector tau;
  std::size_t slowed = 0;
  for (const auto& s : samples) {
    const auto& j = s.sample.joints;
    ASSERT_EQ(j.tau.size(), j.q.size()) << "t " << s.sample.t;
    core::inverse_dynamics(model, j.q, j.q_dot, j.q_ddot, core::dynamics_options(model), tau);
    EXPECT_LE((tau - j.tau).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, tau.cwiseAbs().maxCoeff())) << "t " << s.sample.t;
    if (s.speed_factor < 0.99) ++slowed;
  }
  EXPECT_GT(slowed, 100u);
}

// A plan with a durationS keeps the room it has: the thesis's 10 s breaks the PA-10's
// limits at the cusp (StreamSamples needs reportOnly for it); at 40 s it has room.
TEST(LiveExecution, APlanWithADurationKeepsItsOwnRoom) {
  const Pa10C fast(10.0);
  EXPECT_FALSE(fast.start());
  const Pa10C slow(40.0);
  auto started = slow.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  const auto samples = run(*started, {{5.0, [](core::LiveExecution& l) { l.stop(); }}});
  EXPECT_EQ(samples.back().state, LiveState::kStopped);
  check_limits(samples, *slow.robot);
  check_on_plan(slow, samples);
}

TEST(LiveExecution, PauseHoldsOnThePathThenResumes) {
  const Pa10C c(0.0, kReserved);
  auto started = c.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  auto& live = *started;
  double predicted = 0.0;
  std::vector<LiveSample> samples;
  LiveSample s;
  double paused_at = -1.0, rest_at = -1.0;
  while (live.next(s)) {
    samples.push_back(s);
    if (paused_at < 0.0 && s.sample.t >= 3.0) {
      predicted = live.stopping().time_s;
      live.pause();
      paused_at = s.sample.t;
    }
    if (rest_at < 0.0 && s.state == LiveState::kPaused) rest_at = s.sample.t;
    if (rest_at > 0.0 && s.sample.t >= rest_at + 1.0 && live.state() == LiveState::kPaused) live.resume();
  }
  ASSERT_GT(rest_at, 0.0);
  EXPECT_LE(rest_at - paused_at, predicted + 0.01 + 1e-9);
  EXPECT_GT(rest_at - paused_at, 0.05);  // slowed, not jumped to rest
  // Held: the same point, at rest, while paused.
  for (const auto& x : samples) {
    if (x.state == LiveState::kPaused) {
      EXPECT_EQ(x.speed_factor, 0.0);
      EXPECT_EQ(x.sample.joints.q_dot.norm(), 0.0);
    }
  }
  EXPECT_EQ(samples.back().state, LiveState::kCompleted);
  check_limits(samples, *c.robot);
  check_on_plan(c, samples);
}

TEST(LiveExecution, StopEndsAtRestOnThePathWithinThePredictedTime) {
  const Pa10C c(0.0, kReserved);
  auto started = c.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  auto& live = *started;
  std::vector<LiveSample> samples;
  LiveSample s;
  double predicted = 0.0, predicted_tau = 0.0, stop_at = -1.0, tau_at_stop = 0.0;
  while (live.next(s)) {
    samples.push_back(s);
    if (stop_at < 0.0 && s.sample.t >= 4.0) {
      predicted = live.stopping().time_s;
      predicted_tau = live.stopping().plan_time_s;
      tau_at_stop = s.plan_time;
      live.stop();
      stop_at = s.sample.t;
    }
  }
  EXPECT_FALSE(live.next(s));
  const LiveSample& last = samples.back();
  EXPECT_EQ(last.state, LiveState::kStopped);
  EXPECT_EQ(last.sample.joints.q_dot.norm(), 0.0);
  EXPECT_EQ(last.sample.joints.q_ddot.norm(), 0.0);
  EXPECT_LE(last.sample.t - stop_at, predicted + 0.01 + 1e-9);
  EXPECT_LE(last.plan_time - tau_at_stop, predicted_tau + 1e-9);
  EXPECT_LT(last.plan_time, live.plan_duration());
  check_limits(samples, *c.robot);
  check_on_plan(c, samples);
}

TEST(LiveExecution, AStopBeforeTheFirstSampleEndsAtOnce) {
  const Pa10C c(0.0, kReserved);
  auto started = c.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  auto& live = *started;
  live.stop();
  LiveSample s;
  ASSERT_TRUE(live.next(s));
  EXPECT_EQ(s.state, LiveState::kStopped);
  EXPECT_EQ(s.plan_time, 0.0);
  EXPECT_FALSE(live.next(s));
}

// Live execution keeps the jerk limits the plan keeps: a trapezoid (acceleration steps) on
// an arm with jerk limits is refused, the joint named. The steps are measured as the joint
// report measures them, at the cycle rate (100 Hz here: about 15 rad/s^3 on this slow plan).
TEST(LiveExecution, APlanBreakingAJerkLimitIsRefused) {
  const Pa10C slow(40.0);
  core::RobotModel jerky = *slow.robot;
  for (auto& l : jerky.limits) l.max_jerk = 5.0;
  auto refused = core::LiveExecution::start(slow.trajectory, &jerky, slow.seed,
                                            core::live_limits(&jerky), slow.spec.cycle_rate_hz);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error()[0].description.find("jerk"), std::string::npos) << refused.error()[0].description;
  EXPECT_NE(refused.error()[0].description.find("joint"), std::string::npos) << refused.error()[0].description;
}

// A time-optimal plan uses some acceleration limit fully: no room to slow down on the path
// at full speed. The same plan at speedScale sqrt(0.9) (reserve 0.1) has room.
TEST(LiveExecution, ASaturatingPlanIsRefusedNamingTheLimit) {
  const Pa10C full(0.0);
  auto refused = core::LiveExecution::start(full.trajectory, full.robot, full.seed,
                                            core::live_limits(full.robot), 100.0);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error()[0].field, "motion");
  EXPECT_NE(refused.error()[0].description.find("acceleration limit"), std::string::npos)
      << refused.error()[0].description;
  const Pa10C reserved(0.0, kReserved);
  auto started = reserved.start();
  ASSERT_TRUE(started) << started.error()[0].description;
  auto& live = *started;
  const auto samples = run(live, {{0.5, [](core::LiveExecution& l) { l.stop(); }}});
  EXPECT_EQ(samples.back().state, LiveState::kStopped);
  EXPECT_LE(check_limits(samples, *reserved.robot), 1.0 + 1e-6);
  check_on_plan(reserved, samples);
}

}  // namespace
}  // namespace geotraj
