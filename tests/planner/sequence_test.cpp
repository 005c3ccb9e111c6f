// planner::plan of a sequence (planner/sequence.cpp), without the wire: steps one after the
// other, each from where the previous one ends, with their own reports; a given start away
// from the previous end named by its step.
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "planner/planner.hpp"
#include "planner/robots.hpp"

namespace geotraj::test {
namespace {

using ::testing::HasSubstr;

std::shared_ptr<const planner::Robot> pa10() {
  const core::RobotModel& model = *planner::find_builtin_robot("pa10");
  return std::make_shared<planner::Robot>(core::ValidRobot::check(model).value(), core::home_configuration(model));
}

planner::Step joint_step(std::vector<double> goal, double duration_s, bool start_given = false,
                         std::vector<double> start = {}) {
  planner::Step step;
  step.geometry = core::JointMoveSpec{std::move(start), std::move(goal)};
  step.motion.duration_s = duration_s;
  step.own_motion = true;
  step.own_motion_fields = {"durationS"};
  step.start_given = start_given;
  return step;
}

std::string described(const planner::Error& e) {
  std::string out = "kind " + std::to_string(static_cast<int>(e.kind));
  for (const auto& v : e.violations) out += "; " + v.field + ": " + v.description;
  for (const auto& l : e.limits) out += "; limit " + std::to_string(static_cast<int>(l.kind)) + " joint " + std::to_string(l.joint) + " at t = " + std::to_string(l.t);
  return out;
}

// The first step starts at the robot's initial joints (as the wire fills it); the second
// from where the first ends (its start a placeholder the planner replaces).
planner::Request two_joint_moves() {
  planner::Request request;
  request.robot = pa10();
  request.motion = core::MotionSpec{};
  request.motion->duration_s = 1.0;
  const auto& seed = request.robot->seed;
  const std::vector<double> start(seed.data(), seed.data() + seed.size());
  request.sequence.push_back(joint_step({0.2, 0.1, 0.0, 0.2, 0.0, 0.2, 0.0}, 4.0, false, start));
  request.sequence.push_back(joint_step({-0.1, 0.2, 0.1, 0.3, 0.0, 0.1, 0.2}, 5.0, false, start));
  return request;
}

TEST(PlannerSequence, StepsFollowEachOtherFromWhereThePreviousEnds) {
  const auto request = two_joint_moves();
  const auto plan = planner::plan(request, {}, {});
  ASSERT_TRUE(plan.has_value()) << (plan ? "" : described(plan.error()));
  ASSERT_EQ(plan->steps.size(), 2u);
  EXPECT_EQ(plan->steps[0].kind, "jointMove");
  EXPECT_NEAR(plan->steps[0].start_time_s, 0.0, 1e-12);
  EXPECT_NEAR(plan->steps[0].duration_s, 4.0, 1e-12);
  EXPECT_NEAR(plan->steps[1].start_time_s, 4.0, 1e-12);
  EXPECT_NEAR(plan->steps[1].duration_s, 5.0, 1e-12);
  // Every sample counted once: the rest between them is the second step's first sample.
  EXPECT_EQ(plan->steps[1].first_sample, plan->steps[0].first_sample + plan->steps[0].sample_count);
  ASSERT_TRUE(plan->joints.has_value());
}

TEST(PlannerSequence, AGivenStartAwayFromThePreviousEndIsNamedByItsStep) {
  auto request = two_joint_moves();
  request.sequence[1] = joint_step({-0.1, 0.2, 0.1, 0.3, 0.0, 0.1, 0.2}, 5.0, /*start_given=*/true,
                                   {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0});
  const auto plan = planner::plan(request, {}, {});
  ASSERT_FALSE(plan.has_value());
  ASSERT_FALSE(plan.error().violations.empty()) << described(plan.error());
  EXPECT_THAT(plan.error().violations.front().field, HasSubstr("sequence[1]"));
}

TEST(PlannerSequence, AStepThatCannotBePlannedIsNamedFromTheRequestsRoot) {
  auto request = two_joint_moves();
  const auto start = std::get<core::JointMoveSpec>(request.sequence[0].geometry).start;
  request.sequence[0] = joint_step({0.3, 0.2}, 1.5, false, start);  // two goal values for seven joints
  const auto plan = planner::plan(request, {}, {});
  ASSERT_FALSE(plan.has_value());
  ASSERT_FALSE(plan.error().violations.empty()) << described(plan.error());
  EXPECT_THAT(plan.error().violations.front().field, HasSubstr("sequence[0]"));
}

planner::Step line_step(Eigen::Vector3d start, Eigen::Vector3d goal, double blend_tolerance) {
  planner::Step step;
  core::LinearMoveSpec line;
  line.start.p_WT = start;
  line.goal.p_WT = goal;
  step.geometry = line;
  step.motion.max_speed = 0.1;
  step.motion.max_acceleration = 0.5;
  step.motion.max_jerk = 10.0;
  step.blend_tolerance = blend_tolerance;
  return step;
}

// A chain of blended lines whose first junction is straight on: only the turn is a corner, and
// the plan sums the motion up (the whole's peaks are the steps' largest).
TEST(PlannerSequence, AStraightJunctionIsNoCornerAndThePlanSumsTheMotionUp) {
  const Eigen::Vector3d a(0.4, 0.0, 0.5), b(0.5, 0.0, 0.5), c(0.6, 0.0, 0.5), d(0.6, 0.1, 0.5);
  planner::Request request;
  request.motion = request.sequence.emplace_back(line_step(a, b, 0.01)).motion;
  request.sequence.push_back(line_step(b, c, 0.01));
  request.sequence.push_back(line_step(c, d, 0.0));
  request.sequence.push_back(line_step(d, a, 0.0));
  const auto plan = planner::plan(request, {}, {});
  ASSERT_TRUE(plan.has_value()) << (plan ? "" : described(plan.error()));
  ASSERT_EQ(plan->steps.size(), 2u);
  EXPECT_EQ(plan->steps[0].kind, "blended");
  ASSERT_EQ(plan->steps[0].corners.size(), 1u) << "a -> b -> c is straight on";
  EXPECT_EQ(plan->steps[0].corners[0].after, 1u);
  EXPECT_NEAR(plan->steps[0].corners[0].corner, std::acos(0.0), 1e-9);
  ASSERT_TRUE(plan->summary.has_value());
  const planner::MotionSummary& whole = *plan->summary;
  EXPECT_NEAR(whole.duration_s, plan->steps[1].start_time_s + plan->steps[1].duration_s, 1e-12);
  EXPECT_EQ(whole.sample_count, plan->steps[1].first_sample + plan->steps[1].sample_count);
  double tangential = 0.0, speed = 0.0;
  for (const auto& step : plan->steps) {
    EXPECT_GT(step.peak_tangential_acceleration, 0.0);
    EXPECT_LE(step.peak_tangential_acceleration, 0.5 + 1e-9);
    tangential = std::max(tangential, step.peak_tangential_acceleration);
    speed = std::max(speed, step.tool.speed);
  }
  EXPECT_EQ(whole.peak_tangential_acceleration, tangential);
  EXPECT_EQ(whole.tool.speed, speed);
  EXPECT_LE(whole.tool.speed, 0.1 + 1e-9);
}

}  // namespace
}  // namespace geotraj::test
