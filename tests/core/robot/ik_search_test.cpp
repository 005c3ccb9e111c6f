// The IK search of the whole joint range (core/robot/ik.hpp, search_ik), closed loop through
// the public forward kinematics:
//  - cold solves from the home configuration of random reachable poses (the FK of
//    configurations uniform within the limits; GEOTRAJ_PROPERTY_CASES, default 10,000 per
//    arm): at least 99.9 % solved, every solution within the tolerances and the limits;
//  - every solution of one pose: the UR5's eight branches, the PA-10's several;
//  - an unreachable target: the closest pose, a local minimum of the pose error within the
//    limits, no better pose among the attempts' starts;
//  - the order (nearest the seed first) and the seeded search (one attempt).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::IkSearchOptions;
using core::JointVector;
using core::RobotModel;

constexpr double kTwoPi = 2.0 * std::numbers::pi;

JointVector uniform_configuration(const RobotModel& m, std::mt19937_64& rng) {
  JointVector q(static_cast<Eigen::Index>(m.dof()));
  for (std::size_t i = 0; i < m.dof(); ++i) {
    q(static_cast<Eigen::Index>(i)) =
        std::uniform_real_distribution<double>(m.limits[i].min_position, m.limits[i].max_position)(rng);
  }
  return q;
}

// Position [m] and orientation [rad] errors of q's pose against the target, by the public FK.
std::pair<double, double> pose_errors(const RobotModel& m, const JointVector& q, const Eigen::Isometry3d& target) {
  const Eigen::Isometry3d X = core::forward_kinematics(m, q);
  return {(X.translation() - target.translation()).norm(),
          Eigen::AngleAxisd(target.linear() * X.linear().transpose()).angle()};
}

bool within_limits(const RobotModel& m, const JointVector& q) {
  for (std::size_t i = 0; i < m.dof(); ++i) {
    const double x = q(static_cast<Eigen::Index>(i));
    if (!(x >= m.limits[i].min_position && x <= m.limits[i].max_position)) return false;
  }
  return true;
}

void expect_solution(const RobotModel& m, const core::IkResult& r, const Eigen::Isometry3d& target) {
  EXPECT_TRUE(r.converged);
  EXPECT_TRUE(within_limits(m, r.q));
  const auto [e_p, e_r] = pose_errors(m, r.q, target);
  EXPECT_LE(e_p, 1e-9 + 1e-14);
  EXPECT_LE(e_r, 1e-9 + 1e-14);
}

void cold_solves(const char* robot) {
  const RobotModel& m = *core::find_builtin_robot(robot);
  const JointVector home = core::home_configuration(m);
  const int cases = property_case_count(10000);
  std::mt19937_64 rng(kPropertySeed);
  int solved = 0;
  long attempts = 0;
  for (int c = 0; c < cases; ++c) {
    const Eigen::Isometry3d target = core::forward_kinematics(m, uniform_configuration(m, rng));
    const core::IkSearchResult r = core::search_ik(m, target, home);
    attempts += r.attempts;
    if (r.solutions.empty()) continue;
    ++solved;
    ASSERT_EQ(r.solutions.size(), 1u) << "stops at the first solution";
    expect_solution(m, r.solutions.front(), target);
  }
  const double rate = 100.0 * solved / cases;
  std::printf("[ measured ] cold IK %s from home: %d of %d solved (%.2f %%), %.2f attempts on average\n", robot, solved,
              cases, rate, static_cast<double>(attempts) / cases);
  EXPECT_GE(rate, 99.9) << robot;
}

TEST(IkSearch, ColdSolvesOfRandomReachablePa10Poses) { cold_solves("pa10"); }
TEST(IkSearch, ColdSolvesOfRandomReachableUr5Poses) { cold_solves("ur5"); }

// Two solutions of the same arm pose differ by whole turns on joints whose range spans one.
double branch_distance(const RobotModel& m, const JointVector& a, const JointVector& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < m.dof(); ++i) {
    double d = a(static_cast<Eigen::Index>(i)) - b(static_cast<Eigen::Index>(i));
    if (m.limits[i].max_position - m.limits[i].min_position >= kTwoPi) d = std::remainder(d, kTwoPi);
    worst = std::max(worst, std::abs(d));
  }
  return worst;
}

TEST(IkSearch, EveryBranchOfAUr5Pose) {
  const RobotModel& m = *core::find_builtin_robot("ur5");
  JointVector q(6);
  q << 0.3, -1.2, 1.4, -0.8, 1.1, 0.5;
  const Eigen::Isometry3d target = core::forward_kinematics(m, q);
  IkSearchOptions options;
  options.all_solutions = true;
  options.max_attempts = 2000;
  const auto r = core::search_ik(m, target, q, options);
  // Shoulder left / right, elbow up / down, wrist flipped or not: eight arm poses.
  ASSERT_EQ(r.solutions.size(), 8u);
  for (const auto& s : r.solutions) expect_solution(m, s, target);
  for (std::size_t a = 0; a < r.solutions.size(); ++a) {
    for (std::size_t b = a + 1; b < r.solutions.size(); ++b) {
      EXPECT_GT(branch_distance(m, r.solutions[a].q, r.solutions[b].q), 1e-3) << a << " and " << b;
    }
  }
  // Nearest the seed first: the seed is a solution itself.
  EXPECT_LT((r.solutions.front().q - q).norm(), 1e-6);
  EXPECT_EQ(r.attempts, 2000);
}

TEST(IkSearch, SeveralBranchesOfAPa10Pose) {
  const RobotModel& m = *core::find_builtin_robot("pa10");
  JointVector q(7);
  q << 0.4, 0.6, -0.3, 1.2, 0.5, 0.8, -0.2;
  const Eigen::Isometry3d target = core::forward_kinematics(m, q);
  IkSearchOptions options;
  options.all_solutions = true;
  options.max_attempts = 500;
  options.max_solutions = 8;
  const auto r = core::search_ik(m, target, q, options);
  std::printf("[ measured ] PA-10 pose: %zu distinct solutions kept of 500 attempts\n", r.solutions.size());
  ASSERT_GE(r.solutions.size(), 2u);
  ASSERT_LE(r.solutions.size(), 8u);
  for (const auto& s : r.solutions) expect_solution(m, s, target);
  for (std::size_t k = 1; k < r.solutions.size(); ++k) {
    EXPECT_LE((r.solutions[k - 1].q - q).norm(), (r.solutions[k].q - q).norm()) << "nearest the seed first";
  }
}

TEST(IkSearch, ASeededSearchStaysOnTheSeedsBranch) {
  const RobotModel& m = *core::find_builtin_robot("ur5");
  JointVector q(6);
  q << -0.7, -1.9, 2.1, -1.4, -1.2, 2.5;
  const Eigen::Isometry3d target = core::forward_kinematics(m, q);
  JointVector seed = q;
  seed.array() += 0.05;
  IkSearchOptions options;
  options.max_attempts = 1;
  const auto r = core::search_ik(m, target, seed, options);
  ASSERT_EQ(r.solutions.size(), 1u);
  EXPECT_EQ(r.attempts, 1);
  EXPECT_LT((r.solutions.front().q - q).norm(), 1e-6);
}

// Beyond the PA-10's reach, turned: no solution; the closest pose is a local minimum of
// |e|^2 (m^2 + rad^2) within the limits: no joint moved by +-1e-4 (inside the limits)
// lowers it by more than rounding.
TEST(IkSearch, TheClosestPoseToAnUnreachableTarget) {
  const RobotModel& m = *core::find_builtin_robot("pa10");
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation() = Eigen::Vector3d(1.6, 0.9, 0.7);
  target.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const auto r = core::search_ik(m, target, core::home_configuration(m));
  EXPECT_TRUE(r.solutions.empty());
  EXPECT_FALSE(r.closest.converged);
  ASSERT_TRUE(within_limits(m, r.closest.q));
  const auto [e_p, e_r] = pose_errors(m, r.closest.q, target);
  EXPECT_NEAR(e_p, r.closest.position_error, 1e-12);
  EXPECT_NEAR(e_r, r.closest.orientation_error, 1e-12);
  const double merit = e_p * e_p + e_r * e_r;
  const auto [home_p, home_r] = pose_errors(m, core::home_configuration(m), target);
  EXPECT_LT(merit, home_p * home_p + home_r * home_r);
  for (Eigen::Index i = 0; i < r.closest.q.size(); ++i) {
    for (const double h : {-1e-4, 1e-4}) {
      JointVector x = r.closest.q;
      x(i) += h;
      if (!within_limits(m, x)) continue;
      const auto [p, o] = pose_errors(m, x, target);
      EXPECT_GE(p * p + o * o, merit - 1e-9) << "joint " << i << " moved by " << h;
    }
  }
  std::printf("[ measured ] unreachable PA-10 target %.3f m from the base: closest pose %.4f m and %.4f rad away\n",
              target.translation().norm(), e_p, e_r);
}

// closest_pose alone, from a start: a local minimum of the pose error within the limits, below
// the start's; from outside the limits it starts clamped; a reachable target is reached.
TEST(IkSearch, TheClosestPoseFromAStart) {
  const RobotModel& m = *core::find_builtin_robot("ur5");
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation() = Eigen::Vector3d(1.4, -0.6, 0.9);
  target.linear() = Eigen::AngleAxisd(1.1, Eigen::Vector3d(3, -1, 2).normalized()).toRotationMatrix();
  JointVector start = core::home_configuration(m);
  start(0) = m.limits[0].max_position + 1.0;  // clamped first
  const core::IkResult r = core::closest_pose(m, target, start);
  std::printf("[ measured ] closest pose from a start: %d iterations, %.6f m, %.6f rad\n", r.iterations, r.position_error, r.orientation_error);
  EXPECT_FALSE(r.converged);
  ASSERT_TRUE(within_limits(m, r.q));
  const auto [e_p, e_r] = pose_errors(m, r.q, target);
  EXPECT_NEAR(e_p, r.position_error, 1e-12);
  EXPECT_NEAR(e_r, r.orientation_error, 1e-12);
  const double merit = e_p * e_p + e_r * e_r;
  for (Eigen::Index i = 0; i < r.q.size(); ++i) {
    for (const double h : {-1e-4, 1e-4}) {
      JointVector x = r.q;
      x(i) += h;
      if (!within_limits(m, x)) continue;
      const auto [p, o] = pose_errors(m, x, target);
      EXPECT_GE(p * p + o * o, merit - 1e-9) << "joint " << i << " moved by " << h;
    }
  }
  JointVector q = core::home_configuration(m);
  q(1) += 0.3;
  q(3) -= 0.4;
  const Eigen::Isometry3d reachable = core::forward_kinematics(m, q);
  const core::IkResult reached = core::closest_pose(m, reachable, core::home_configuration(m));
  EXPECT_TRUE(reached.converged);
  const auto [p, o] = pose_errors(m, reached.q, reachable);
  EXPECT_LT(p, 1e-9);
  EXPECT_LT(o, 1e-9);
}

}  // namespace
}  // namespace geotraj::test
