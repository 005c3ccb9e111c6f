// planner::plan of a sequence (planner/sequence.cpp), without the wire: steps one after the
// other, each from where the previous one ends, with their own reports; a given start away
// from the previous end named by its step.
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

}  // namespace
}  // namespace geotraj::test
