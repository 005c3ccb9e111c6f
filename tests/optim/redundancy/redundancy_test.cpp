// Whole-path redundancy resolution (optim/redundancy): on the PA-10, a smooth tool motion
// (the poses of a smooth joint motion) given with a jerky self-motion (the same poses,
// reached by joints that swing in the null space at 3 Hz): the optimiser keeps every pose to
// the IK's 1e-12 and the start's joints, and what it reports is what is measured on its
// joints from outside (finite differences); the acceleration criterion removes the swing,
// the range criterion moves the joints towards the middle of their ranges, the goal ends the
// motion at the joints given; bad input names its field.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "optim/redundancy/redundancy.hpp"

namespace geotraj::optim {
namespace {

using core::JointVector;
using Eigen::Isometry3d;

constexpr double kDt = 0.01;  // 100 Hz
constexpr std::size_t kSamples = 401;

struct Motion {
  core::ValidRobot robot;
  std::vector<Isometry3d> poses;
  std::vector<JointVector> smooth;  // the joints the poses come from
  std::vector<JointVector> swinging;  // the same poses, the self-motion swinging
};

// A unit vector of J's null space at q (the PA-10 has one dimension of self-motion).
JointVector null_direction(const core::RobotModel& model, const JointVector& q) {
  Isometry3d X;
  core::JointJacobian J;
  core::forward_kinematics(model, q, X, J);
  const Eigen::MatrixXd dense = J;
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(dense);
  return lu.kernel().col(0).normalized();
}

Motion pa10_motion() {
  auto robot = core::ValidRobot::check(*core::find_builtin_robot("pa10"));
  EXPECT_TRUE(robot);
  Motion m{*robot, {}, {}, {}};
  const core::RobotModel& model = m.robot;
  JointVector a(7), b(7);
  a << 0.1, 0.5, 0.2, 1.2, -0.3, 0.6, 0.1;
  b << 0.8, 0.2, -0.3, 1.6, 0.4, 0.2, -0.5;
  JointVector previous_direction;
  for (std::size_t k = 0; k < kSamples; ++k) {
    const double t = static_cast<double>(k) / static_cast<double>(kSamples - 1);
    const double blend = t * t * t * (10.0 - 15.0 * t + 6.0 * t * t);  // quintic rest to rest
    const JointVector q = a + blend * (b - a);
    m.smooth.push_back(q);
    m.poses.push_back(core::forward_kinematics(model, q));
    JointVector n = null_direction(model, q);
    if (k > 0 && n.dot(previous_direction) < 0.0) n = -n;
    previous_direction = n;
    const double swing = 0.15 * std::sin(2.0 * std::numbers::pi * 3.0 * kDt * static_cast<double>(k)) * std::sin(std::numbers::pi * t);
    core::IkOptions o;
    o.position_tolerance = o.orientation_tolerance = 1e-12;
    const core::IkResult ik = core::solve_ik(model, m.poses.back(), q + swing * n, o);
    EXPECT_TRUE(ik.converged) << k;
    m.swinging.push_back(k == 0 ? q : ik.q);
  }
  return m;
}

// The largest |second difference| / (dt^2 a_max) over the joints and samples (rests beyond
// the ends): the acceleration usage measured on the joints.
double acceleration_usage(const core::RobotModel& model, const std::vector<JointVector>& q) {
  double worst = 0.0;
  for (std::size_t k = 0; k < q.size(); ++k) {
    const JointVector& before = q[k == 0 ? 0 : k - 1];
    const JointVector& after = q[std::min(k + 1, q.size() - 1)];
    const JointVector d = (after - 2.0 * q[k] + before) / (kDt * kDt);
    for (Eigen::Index i = 0; i < d.size(); ++i)
      worst = std::max(worst, std::abs(d(i)) / model.limits[static_cast<std::size_t>(i)].max_acceleration);
  }
  return worst;
}

void expect_poses_held(const Motion& m, const RedundancyResult& r) {
  ASSERT_EQ(r.q.size(), m.poses.size());
  EXPECT_EQ(r.q[0], m.swinging[0]) << "the start's joints are held";
  double worst = 0.0;
  for (std::size_t k = 0; k < r.q.size(); ++k) {
    const Isometry3d X = core::forward_kinematics(m.robot, r.q[k]);
    worst = std::max(worst, (X.translation() - m.poses[k].translation()).norm());
    worst = std::max(worst, Eigen::AngleAxisd(X.linear() * m.poses[k].linear().transpose()).angle());
    for (std::size_t i = 0; i < 7; ++i) {
      const auto j = static_cast<Eigen::Index>(i);
      EXPECT_GE(r.q[k](j), m.robot->limits[i].min_position);
      EXPECT_LE(r.q[k](j), m.robot->limits[i].max_position);
    }
  }
  EXPECT_LT(worst, 1e-11);
  EXPECT_LE(r.worst_position_error, 1e-11);
}

TEST(Redundancy, TheAccelerationCriterionRemovesASwingingSelfMotion) {
  const Motion m = pa10_motion();
  RedundancyOptions o;
  o.weights.acceleration = 1.0;
  auto r = optimize_redundancy(m.robot, m.poses, kDt, m.swinging, o);
  ASSERT_TRUE(r);
  expect_poses_held(m, *r);
  const double before = acceleration_usage(m.robot, m.swinging);
  const double smooth = acceleration_usage(m.robot, m.smooth);
  const double after = acceleration_usage(m.robot, r->q);
  std::printf("PA-10, 401 samples: acceleration usage %.3f swinging, %.3f optimised (%.3f the smooth joints); "
              "%d iterations, %.1f ms, %s\n",
              before, after, smooth, r->report.iterations, 1e3 * r->report.seconds, name(r->report.status));
  EXPECT_GT(before, 5.0 * smooth);
  EXPECT_LE(after, 1.05 * smooth) << "at most the smooth motion's usage";
  // What it reports is what is measured.
  EXPECT_NEAR(r->report.objective_before, redundancy_objective(m.robot, m.swinging, kDt, o), 1e-9 * r->report.objective_before);
  EXPECT_NEAR(r->report.objective_after, redundancy_objective(m.robot, r->q, kDt, o), 1e-9 * r->report.objective_before);
  EXPECT_LT(r->report.objective_after, 0.05 * r->report.objective_before);
  EXPECT_EQ(r->report.status, OptimizerStatus::kConverged) << r->report.message;
}

TEST(Redundancy, TheRangeCriterionMovesTheJointsTowardsTheMiddleOfTheirRanges) {
  const Motion m = pa10_motion();
  RedundancyOptions o;
  o.weights.joint_range = 1.0;
  o.weights.acceleration = 1e-3;  // a little smoothness: the range alone has no coupling
  auto r = optimize_redundancy(m.robot, m.poses, kDt, m.smooth, o);
  ASSERT_TRUE(r);
  expect_poses_held(m, *r);
  const auto spread = [&](const std::vector<JointVector>& q) {
    double sum = 0.0;
    for (const JointVector& x : q)
      for (std::size_t i = 0; i < 7; ++i) {
        const core::JointLimits& l = m.robot->limits[i];
        sum += std::pow((x(static_cast<Eigen::Index>(i)) - 0.5 * (l.min_position + l.max_position)) /
                            (l.max_position - l.min_position), 2);
      }
    return sum;
  };
  EXPECT_LT(spread(r->q), spread(m.smooth)) << r->report.message << " " << r->peaks.worst() << " " << r->rounds;
}

// The last pose reached with the elbow swung 0.3 rad round the self-motion.
core::IkResult swung_goal(const Motion& m) {
  const JointVector& last = m.smooth.back();
  core::IkOptions ik_options;
  ik_options.position_tolerance = ik_options.orientation_tolerance = 1e-12;
  return core::solve_ik(m.robot, m.poses.back(), last + 0.3 * null_direction(m.robot, last), ik_options);
}

TEST(Redundancy, TheGoalEndsTheMotionAtTheJointsGiven) {
  const Motion m = pa10_motion();
  const core::IkResult goal = swung_goal(m);
  ASSERT_TRUE(goal.converged);
  ASSERT_GT((goal.q - m.smooth.back()).norm(), 0.2);
  RedundancyOptions o;
  o.weights.acceleration = 1.0;
  o.goal = goal.q;
  o.goal_weight = 1e3;
  auto r = optimize_redundancy(m.robot, m.poses, kDt, m.smooth, o);
  ASSERT_TRUE(r);
  expect_poses_held(m, *r);
  EXPECT_LT((r->q.back() - goal.q).norm(), 1e-3);
}

// Held (a straight line to goal joints): the motion ends at the goal exactly, the self-motion
// spread over the whole motion within the joints' limits, every pose kept.
TEST(Redundancy, AHeldGoalEndsTheMotionThereExactly) {
  const Motion m = pa10_motion();
  const core::IkResult goal = swung_goal(m);
  ASSERT_TRUE(goal.converged);
  RedundancyOptions o;
  o.weights.acceleration = 1.0;
  o.goal = goal.q;
  o.hold_goal = true;
  auto r = optimize_redundancy(m.robot, m.poses, kDt, m.smooth, o);
  ASSERT_TRUE(r);
  expect_poses_held(m, *r);
  EXPECT_EQ(r->q.back(), goal.q);
  EXPECT_NE(r->report.status, OptimizerStatus::kFailed) << r->report.message;
  EXPECT_LE(acceleration_usage(m.robot, r->q), 1.0);
  EXPECT_LE(r->peaks.worst(), 1.0);
  // Between: no sample jumps (the self-motion travels 0.3 rad over 4 s).
  double step = 0.0;
  for (std::size_t k = 1; k < r->q.size(); ++k) step = std::max(step, (r->q[k] - r->q[k - 1]).norm());
  EXPECT_LT(step, 0.02);
}

TEST(Redundancy, BadInputNamesItsField) {
  const Motion m = pa10_motion();
  const auto field = [&](RedundancyOptions o, std::vector<JointVector> initial, double dt = kDt) {
    auto r = optimize_redundancy(m.robot, m.poses, dt, initial, o);
    return r ? std::string("accepted") : r.error().front().field;
  };
  RedundancyOptions none;
  EXPECT_EQ(field(none, m.smooth), "weights");
  RedundancyOptions negative;
  negative.weights.velocity = -1.0;
  EXPECT_EQ(field(negative, m.smooth), "weights");
  RedundancyOptions ok;
  ok.weights.velocity = 1.0;
  EXPECT_EQ(field(ok, m.smooth, 0.0), "dt");
  EXPECT_EQ(field(ok, std::vector<JointVector>(m.smooth.begin(), m.smooth.end() - 1)), "initial");
  std::vector<JointVector> wrong = m.smooth;
  wrong[7](2) += 0.1;
  EXPECT_EQ(field(ok, wrong), "initial[7]");
  RedundancyOptions short_goal = ok;
  short_goal.goal = JointVector::Zero(6);
  EXPECT_EQ(field(short_goal, m.smooth), "goal");
  RedundancyOptions held = ok;
  held.hold_goal = true;
  EXPECT_EQ(field(held, m.smooth), "goal") << "held, but none given";
  held.goal = m.smooth.front();
  EXPECT_EQ(field(held, m.smooth), "goal") << "held, but not reaching the last pose";
}

}  // namespace
}  // namespace geotraj::optim
