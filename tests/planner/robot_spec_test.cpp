// planner::resolve_robot (planner/robot_spec.hpp): a request's robot resolved against the
// server's catalogue, without the wire: every source, every override, every violation named by
// the request's field, all of them in one answer.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "planner/robot_spec.hpp"
#include "planner/robots.hpp"
#include "tests/planner/builtin_catalog.hpp"

namespace geotraj::test {
namespace {

using ::testing::HasSubstr;

constexpr auto& catalog = geotraj::testing::builtin_catalog;

planner::RobotSpec by_name(std::string name) {
  planner::RobotSpec spec;
  spec.source = planner::RobotByName{std::move(name)};
  return spec;
}

// The violation of `field`, or an empty one (field "") when there is none.
core::FieldViolation violation_of(const core::Violations& all, const std::string& field) {
  const auto it = std::find_if(all.begin(), all.end(), [&](const core::FieldViolation& v) { return v.field == field; });
  return it == all.end() ? core::FieldViolation{} : *it;
}

TEST(ResolveRobot, ABuiltInByNameStartsAtItsHome) {
  const auto robot = planner::resolve_robot(by_name("pa10"), catalog());
  ASSERT_TRUE(robot.has_value());
  const core::RobotModel& pa10 = *catalog().find("pa10");
  EXPECT_EQ(robot->model->dof(), pa10.dof());
  EXPECT_TRUE(robot->seed.isApprox(core::home_configuration(pa10)));
  EXPECT_FALSE(robot->inline_model);
  EXPECT_EQ(robot->approach, planner::Approach::kNone);
  // Unchanged, the catalogue's model is shared as it was checked when it entered; a request
  // that changes it (here a tool) gets its own, checked again.
  EXPECT_EQ(&robot->model.model(), &catalog().find("pa10")->model());
  auto tooled = by_name("pa10");
  tooled.tool = Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.123));
  const auto with_tool = planner::resolve_robot(tooled, catalog());
  ASSERT_TRUE(with_tool.has_value());
  EXPECT_NE(&with_tool->model.model(), &catalog().find("pa10")->model());
  EXPECT_TRUE(with_tool->model->tool.isApprox(*tooled.tool));
  EXPECT_FALSE(catalog().find("pa10")->model().tool.isApprox(*tooled.tool)) << "the catalogue's model is unchanged";
}

TEST(ResolveRobot, AnUnknownNameListsTheNamesTheServerKnows) {
  const auto robot = planner::resolve_robot(by_name("pa11"), catalog());
  ASSERT_FALSE(robot.has_value());
  const auto v = violation_of(robot.error(), "robot.name");
  EXPECT_THAT(v.description, HasSubstr("'pa11'"));
  for (const auto& m : catalog().models) EXPECT_THAT(v.description, HasSubstr(m->name));
}

TEST(ResolveRobot, NoSourceIsRefusedNamingTheThreeWays) {
  const auto robot = planner::resolve_robot(planner::RobotSpec{}, catalog());
  ASSERT_FALSE(robot.has_value());
  EXPECT_THAT(violation_of(robot.error(), "robot").description, HasSubstr("urdf"));
}

TEST(ResolveRobot, JointLimitsByNameReplaceTheModelsAndScalesApplyAfterThem) {
  auto spec = by_name("ur5");
  const core::RobotModel& ur5 = *catalog().find("ur5");
  spec.joint_limits.push_back({ur5.joints[2].name, 0.5, 1.5, 10.0});
  spec.velocity_scale = 0.5;
  spec.acceleration_scale = 0.25;
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_TRUE(robot.has_value());
  const auto& l = robot->model->limits[2];
  EXPECT_DOUBLE_EQ(l.max_velocity, 0.25);
  EXPECT_DOUBLE_EQ(l.max_acceleration, 0.375);
  ASSERT_TRUE(l.max_jerk.has_value());
  EXPECT_DOUBLE_EQ(*l.max_jerk, 2.5);
  EXPECT_DOUBLE_EQ(robot->model->limits[0].max_velocity, 0.5 * ur5.limits[0].max_velocity);
}

TEST(ResolveRobot, EveryBadValueIsNamedInOneAnswer) {
  auto spec = by_name("ur5");
  spec.joint_limits.push_back({"no_such_joint", 1.0, std::nullopt, std::nullopt});
  spec.joint_limits.push_back({"", -1.0, std::nullopt, std::nullopt});
  spec.branch_tolerance = -1.0;
  spec.start_orientation_tolerance = std::nan("");
  spec.velocity_scale = 1.5;
  spec.base_link = "base";
  spec.initial_joints = {0.0, 0.0};
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(robot.has_value());
  const auto& all = robot.error();
  EXPECT_THAT(violation_of(all, "robot.jointLimits[1].joint").description, HasSubstr("required"));
  EXPECT_THAT(violation_of(all, "robot.jointLimits[1].maxVelocity").description, HasSubstr("got -1"));
  EXPECT_THAT(violation_of(all, "robot.branchTolerance").description, HasSubstr("> 0"));
  EXPECT_THAT(violation_of(all, "robot.startOrientationTolerance").description, HasSubstr("finite"));
  EXPECT_THAT(violation_of(all, "robot.velocityScale").description, HasSubstr("(0, 1]"));
  EXPECT_THAT(violation_of(all, "robot.baseLink").description, HasSubstr("urdf"));
  EXPECT_THAT(violation_of(all, "robot.initialJoints").description, HasSubstr("2 values for a 6-joint robot"));
}

TEST(ResolveRobot, AJointLimitNamingNoJointListsTheModelsJoints) {
  auto spec = by_name("pa10");
  spec.joint_limits.push_back({"elbow", 1.0, std::nullopt, std::nullopt});
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(robot.has_value());
  const auto v = violation_of(robot.error(), "robot.jointLimits[0].joint");
  EXPECT_THAT(v.description, HasSubstr("'elbow'"));
  EXPECT_THAT(v.description, HasSubstr((*catalog().find("pa10"))->joints[0].name));
}

TEST(ResolveRobot, AScaleThatTakesALimitOutOfRangeNamesTheJoint) {
  auto spec = by_name("pa10");
  spec.acceleration_scale = 5e-324;
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(robot.has_value());
  EXPECT_THAT(violation_of(robot.error(), "robot.accelerationScale").description, HasSubstr("joint 0"));
}

TEST(ResolveRobot, InitialJointsOutsideTheLimitsAreNamedByIndex) {
  auto spec = by_name("pa10");
  spec.initial_joints.assign(7, 0.0);
  spec.initial_joints[3] = 100.0;
  spec.initial_joints[5] = std::numeric_limits<double>::infinity();
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(robot.has_value());
  EXPECT_THAT(violation_of(robot.error(), "robot.initialJoints[3]").description, HasSubstr("outside"));
  EXPECT_THAT(violation_of(robot.error(), "robot.initialJoints[5]").description, HasSubstr("finite"));
}

TEST(ResolveRobot, AnInlineModelIsValidatedUnderItsField) {
  core::RobotModel model = *catalog().find("ur5");
  model.limits[1].max_velocity = 0.0;
  planner::RobotSpec spec;
  spec.source = planner::InlineRobot{model};
  spec.branch_tolerance = 0.0;
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(robot.has_value());
  EXPECT_THAT(violation_of(robot.error(), "robot.model.limits[1].maxVelocity").description, HasSubstr("> 0"));
  EXPECT_FALSE(violation_of(robot.error(), "robot.branchTolerance").field.empty()) << "checked in the same answer";

  spec.source = planner::InlineRobot{*catalog().find("ur5")};
  spec.branch_tolerance.reset();
  const auto fine = planner::resolve_robot(spec, catalog());
  ASSERT_TRUE(fine.has_value());
  EXPECT_TRUE(fine->inline_model);
}

TEST(ResolveRobot, AnUnreadableInlineModelLeavesTheRestChecked) {
  planner::RobotSpec spec;
  spec.source = planner::InlineRobot{std::nullopt};
  spec.velocity_scale = 0.0;
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(robot.has_value());
  EXPECT_FALSE(violation_of(robot.error(), "robot.velocityScale").field.empty());
}

TEST(ResolveRobot, BaseAndToolReplaceTheModelsAndAreBounded) {
  auto spec = by_name("pa10");
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  base.translation() = Eigen::Vector3d(0.5, 0.0, 0.2);
  Eigen::Isometry3d tool = Eigen::Isometry3d(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()));
  spec.base = base;
  spec.tool = tool;
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_TRUE(robot.has_value());
  EXPECT_TRUE(robot->model->base.isApprox(base));
  EXPECT_TRUE(robot->model->tool.isApprox(tool));

  base.translation().x() = 1e9;
  spec.base = base;
  const auto far = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(far.has_value());
  EXPECT_THAT(violation_of(far.error(), "robot.base.position").description, HasSubstr("at most"));
}

TEST(ResolveRobot, AUrdfTakesTheRequestsJointLimitsOverItsOwn) {
  planner::RobotSpec spec;
  spec.source = planner::UrdfRobot{std::string(planner::builtin_urdf("panda"))};
  spec.joint_limits.push_back({"panda_joint4", 0.75, 2.0, std::nullopt});
  const auto robot = planner::resolve_robot(spec, catalog());
  ASSERT_TRUE(robot.has_value());
  EXPECT_TRUE(robot->inline_model);
  const auto& joints = robot->model->joints;
  const auto it = std::find_if(joints.begin(), joints.end(), [](const core::Joint& j) { return j.name == "panda_joint4"; });
  ASSERT_NE(it, joints.end());
  const auto& l = robot->model->limits[static_cast<std::size_t>(it - joints.begin())];
  EXPECT_DOUBLE_EQ(l.max_velocity, 0.75);
  EXPECT_DOUBLE_EQ(l.max_acceleration, 2.0);

  spec.source = planner::UrdfRobot{"<robot name='x'>"};
  const auto bad = planner::resolve_robot(spec, catalog());
  ASSERT_FALSE(bad.has_value());
  EXPECT_FALSE(violation_of(bad.error(), "robot.urdf").field.empty());
}

}  // namespace
}  // namespace geotraj::test
