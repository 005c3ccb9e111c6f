// The jerk-limited timing of joint paths (optim/timing/joint_path_jerk.hpp): every sample
// at 1 and 4 kHz within the joints' velocity, acceleration and jerk limits by differences of
// the streamed positions, the acceleration continuous (its step between samples within
// the jerk limit times the period: nothing that grows with the rate), at rest with zero
// acceleration at both ends, within 25 % of the exact sweep's time under the default jerk
// limits (20 maxAcceleration per second).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/planning/joint_path.hpp"
#include "core/planning/moves.hpp"
#include "core/robot/robot.hpp"
#include "optim/timing/joint_path_jerk.hpp"
#include "tests/support/build_paths.hpp"

namespace geotraj::optim {
namespace {

// The PA-10 with the planner's default jerk limits (20 maxAcceleration per second).
const core::ValidRobot& jerky_pa10() {
  static const core::ValidRobot robot =
      core::with_default_jerk(*core::ValidRobot::check(*core::find_builtin_robot("pa10")));
  return robot;
}

core::JointPathSpec waypoints(unsigned seed, std::size_t count, double tolerance) {
  std::mt19937 rng(seed);
  core::JointPathSpec spec;
  spec.blend_tolerance = tolerance;
  for (std::size_t i = 0; i < count; ++i) {
    core::JointWaypoint w;
    for (const auto& lim : jerky_pa10()->limits) {
      const double mid = 0.5 * (lim.min_position + lim.max_position), half = 0.15 * (lim.max_position - lim.min_position);
      w.positions.push_back(std::uniform_real_distribution<double>(mid - half, mid + half)(rng));
    }
    spec.waypoints.push_back(std::move(w));
  }
  return spec;
}

// The solver's time budget (1 s by default, a server call's) well above what these plans
// take on a loaded machine or under the sanitizers: the results do not depend on the load.
JerkTimingOptions unhurried() {
  JerkTimingOptions o;
  o.time_budget_s = 120.0;
  return o;
}

TEST(JointPathJerk, EverySampleWithinVelocityAccelerationAndJerkAtOneAndFourKilohertz) {
  const core::JointPathSpec spec = waypoints(41, 7, 0.1);
  const core::RobotModel& m = jerky_pa10();
  for (const double rate : {1000.0, 4000.0}) {
    core::MotionSpec motion;
    motion.cycle_rate_hz = rate;
    auto path = core::build_joint_path(m, spec);
    ASSERT_TRUE(path);
    auto timed = plan_joint_path_jerk(jerky_pa10(), *path, motion, joint_path_jerk_exact_options(), unhurried());
    ASSERT_TRUE(timed) << timed.error().front().field << ": " << timed.error().front().description;
    const core::JointPathPlan& p = timed->plan;
    std::printf("%g Hz: T %.4f (exact %.4f), refinements %d, slowed %.4f, status %d, %s, iterations %d\n", rate,
                p.duration_s, timed->exact_duration_s, timed->rounds.refinements, timed->rounds.slowed_by,
                static_cast<int>(timed->rounds.report.status), timed->rounds.report.message.c_str(),
                timed->rounds.report.iterations);
    EXPECT_GE(p.duration_s, timed->exact_duration_s);
    EXPECT_LE(p.duration_s, 1.25 * timed->exact_duration_s);
    EXPECT_LE(timed->jerk_usage, 1.0 + 1e-9);
    std::vector<core::MoveSample> s;
    core::JointPathSampler sampler(p);
    for (core::MoveSample x; sampler.next(x);) s.push_back(x);
    ASSERT_EQ(s.size(), p.sample_count);
    EXPECT_EQ(s.back().q, p.path.last);
    EXPECT_LT(s.front().q_ddot.norm(), 1e-9);  // the acceleration starts at zero
    EXPECT_LT(s.back().q_ddot.norm(), 1e-9);
    double worst_jerk = 0.0;
    for (std::size_t k = 1; k + 1 < s.size(); ++k) {
      const double h0 = s[k].t - s[k - 1].t, h1 = s[k + 1].t - s[k].t;
      for (std::size_t j = 0; j < m.dof(); ++j) {
        const auto J = static_cast<Eigen::Index>(j);
        const auto& l = m.limits[j];
        EXPECT_LE(std::abs((s[k + 1].q(J) - s[k].q(J)) / h1), l.max_velocity * 1.001) << "t " << s[k].t;
        const double a = 2.0 * ((s[k + 1].q(J) - s[k].q(J)) / h1 - (s[k].q(J) - s[k - 1].q(J)) / h0) / (h0 + h1);
        EXPECT_LE(std::abs(a), l.max_acceleration * 1.001) << "t " << s[k].t;
        const double jerk = std::abs(s[k].q_ddot(J) - s[k - 1].q_ddot(J)) / h0;
        worst_jerk = std::max(worst_jerk, jerk / *l.max_jerk);
      }
    }
    EXPECT_LE(worst_jerk, 1.0 + 1e-6) << rate << " Hz";
  }
}

TEST(JointPathJerk, AGivenDurationStretchesTheMotion) {
  auto path = core::build_joint_path(jerky_pa10(), waypoints(43, 4, 0.05));
  ASSERT_TRUE(path);
  core::MotionSpec motion;
  motion.cycle_rate_hz = 500.0;
  auto fastest = plan_joint_path_jerk(jerky_pa10(), *path, motion, joint_path_jerk_exact_options(), unhurried());
  ASSERT_TRUE(fastest);
  motion.duration_s = 3.0 * fastest->plan.duration_s;
  auto slow = plan_joint_path_jerk(jerky_pa10(), *path, motion, joint_path_jerk_exact_options(), unhurried());
  ASSERT_TRUE(slow);
  EXPECT_DOUBLE_EQ(slow->plan.duration_s, motion.duration_s);
  EXPECT_NEAR(slow->jerk_usage, fastest->jerk_usage / 27.0, 1e-9);
}

// Two waypoints with a collinear one between, and waypoints that reverse (a rest at each
// reversal): every portion is one line, timed in closed form by the double S under the line's own limits, which is the
// jerk-limited optimum there: as fast as the joint move between the same joints (whose
// synchronised profile meets the same limits) or faster, within every limit.
TEST(JointPathJerk, LinesTakeTheJointMovesTimeInClosedForm) {
  const std::vector<double> a{0.1, -0.4, 0.2, 0.9, -0.3, 0.5, 0.0}, b{1.2, 0.3, -0.6, 1.5, 0.4, -0.2, 1.0};
  core::MotionSpec motion;
  motion.cycle_rate_hz = 1000.0;
  core::MotionSpec s_curve = motion;  // the joint move's profile under the jerk limits
  s_curve.profile = core::ProfileShape::kSCurve;
  const auto move = core::plan_joint_move(jerky_pa10(), core::JointMoveSpec{a, b}, s_curve);
  ASSERT_TRUE(move);
  std::vector<double> middle(a.size());
  for (std::size_t k = 0; k < a.size(); ++k) middle[k] = 0.3 * a[k] + 0.7 * b[k];
  for (const int legs : {1, 3}) {
    core::JointPathSpec spec;
    spec.blend_tolerance = 0.1;
    for (int k = 0; k <= legs; ++k) {
      if (k == 1) spec.waypoints.push_back({middle, false});  // collinear: passed on the line
      spec.waypoints.push_back({k % 2 == 0 ? a : b, false});
    }
    auto path = core::build_joint_path(jerky_pa10(), spec);
    ASSERT_TRUE(path);
    auto timed = plan_joint_path_jerk(jerky_pa10(), *path, motion, joint_path_jerk_exact_options(), unhurried());
    ASSERT_TRUE(timed) << timed.error().front().description;
    std::printf("%d legs: %.6f s, the joint move %.6f s each; %s\n", legs, timed->plan.duration_s, move->duration_s,
                timed->rounds.report.message.c_str());
    EXPECT_THAT(timed->rounds.report.message, ::testing::HasSubstr("closed form"));
    EXPECT_LE(timed->plan.duration_s, legs * move->duration_s * (1.0 + 1e-9));
    EXPECT_GE(timed->plan.duration_s, legs * move->duration_s * 0.9);
    EXPECT_LE(timed->plan.velocity_usage, 1.0 + 1e-9);
    EXPECT_LE(timed->plan.acceleration_usage, 1.0 + 1e-9);
    EXPECT_LE(timed->jerk_usage, 1.0 + 1e-9);
  }
}

// A dense planner output on the UR5 under the default jerk, where the NLP finds no solution:
// the path is refused naming optimize.timing and the sweep that times it instead, or (should
// the NLP find one) planned within a few times the sweep's duration; never the sweep slowed
// until its jerk is within the limits (87 times longer: 1391 s for a 16 s path).
TEST(JointPathJerk, WhereTheNlpFindsNoSolutionThePathIsRefusedNotSlowedManyTimes) {
  std::ifstream file(std::string(testing::build_paths::source_dir()) + "/tests/optim/timing/data/ur5_walk200.txt");
  ASSERT_TRUE(file) << "the fixture ur5_walk200.txt";
  core::JointPathSpec spec;
  spec.blend_tolerance = 0.05;
  for (std::string line; std::getline(file, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    core::JointWaypoint w;
    for (double x; in >> x;) w.positions.push_back(x);
    spec.waypoints.push_back(std::move(w));
  }
  ASSERT_EQ(spec.waypoints.size(), 200u);
  const core::ValidRobot ur5 = core::with_default_jerk(*core::ValidRobot::check(*core::find_builtin_robot("ur5")));
  core::MotionSpec motion;
  motion.cycle_rate_hz = 1000.0;
  auto path = core::build_joint_path(ur5, spec);
  ASSERT_TRUE(path);
  auto sweep = core::plan_joint_path(ur5, *path, motion);
  ASSERT_TRUE(sweep);
  auto timed = plan_joint_path_jerk(ur5, *path, motion, joint_path_jerk_exact_options(), unhurried());
  if (timed) {
    std::printf("planned: %.4f s against the sweep's %.4f s\n", timed->plan.duration_s, sweep->duration_s);
    EXPECT_LE(timed->plan.duration_s, 3.0 * sweep->duration_s);
  } else {
    std::printf("refused: %s: %s\n", timed.error().front().field.c_str(), timed.error().front().description.c_str());
    EXPECT_EQ(timed.error().front().field, "optimize.timing");
    EXPECT_THAT(timed.error().front().description, ::testing::HasSubstr("optimize.timing.timeOptimal"));
  }
}

}  // namespace
}  // namespace geotraj::optim
