// MoveIt's joint_limits.yaml (planner/joint_limits_yaml.hpp): a setup assistant's file read
// by MoveIt's rule (a value counts where its flag is true), every malformed file named by line
// and key, and the file as a request gives it (RobotSpec.jointLimitsYaml): the limits a URDF
// cannot give, under the request's jointLimits, a gripper's joints off the chain not read.
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "planner/joint_limits_yaml.hpp"
#include "planner/robot_spec.hpp"
#include "planner/robots.hpp"
#include "tests/planner/builtin_catalog.hpp"

namespace geotraj::test {
namespace {

using ::testing::HasSubstr;

// As MoveIt Setup Assistant writes one for the Panda with its hand (velocities from the URDF,
// accelerations chosen, a finger joint, the scaling defaults).
constexpr const char* kPandaYaml = R"(# joint_limits.yaml allows the dynamics properties specified in the URDF to be overwritten or augmented as needed
default_velocity_scaling_factor: 0.1
default_acceleration_scaling_factor: 0.1
joint_limits:
  panda_finger_joint1:
    has_velocity_limits: true
    max_velocity: 0.1
    has_acceleration_limits: false
    max_acceleration: 0
  panda_joint1:
    has_velocity_limits: true
    max_velocity: 2.175
    has_acceleration_limits: true
    max_acceleration: 3.75
    has_jerk_limits: true
    max_jerk: 7500
  panda_joint2:
    has_velocity_limits: true
    max_velocity: 2.175
    has_acceleration_limits: true
    max_acceleration: 1.875
    has_effort_limits: true
    max_effort: 87
  panda_joint3: {has_velocity_limits: true, max_velocity: 2.175, has_acceleration_limits: true, max_acceleration: 2.5}
  panda_joint4:
    has_velocity_limits: true
    max_velocity: 2.175
    has_acceleration_limits: true
    max_acceleration: 3.125
  panda_joint5:
    has_velocity_limits: true
    max_velocity: 2.61
    has_acceleration_limits: true
    max_acceleration: 3.75
  panda_joint6:
    has_velocity_limits: true
    max_velocity: 2.61
    has_acceleration_limits: true
    max_acceleration: 5
  panda_joint7:
    has_velocity_limits: true
    max_velocity: 2.61
    has_acceleration_limits: true
    max_acceleration: 5
)";

TEST(JointLimitsYaml, MoveItsRuleAValueCountsWhereItsFlagIsTrue) {
  const auto limits = planner::joint_limits_from_yaml(kPandaYaml, "f");
  ASSERT_TRUE(limits) << limits.error().front().description;
  ASSERT_EQ(limits->size(), 8u);
  const auto& finger = (*limits)[0];
  EXPECT_EQ(finger.joint, "panda_finger_joint1");
  EXPECT_EQ(finger.max_velocity, 0.1);
  EXPECT_FALSE(finger.max_acceleration) << "has_acceleration_limits: false";
  const auto& j1 = (*limits)[1];
  EXPECT_EQ(j1.max_acceleration, 3.75);
  EXPECT_EQ(j1.max_jerk, 7500.0);
  EXPECT_FALSE(j1.max_torque);
  EXPECT_EQ((*limits)[2].max_torque, 87.0);
  EXPECT_EQ((*limits)[3].max_acceleration, 2.5) << "a flow mapping";
  EXPECT_EQ((*limits)[7].max_velocity, 2.61);
}

TEST(JointLimitsYaml, EveryProblemIsNamedByLineAndKey) {
  const auto problems = [](const std::string& text) {
    auto r = planner::joint_limits_from_yaml(text, "robot.jointLimitsYaml");
    EXPECT_FALSE(r) << text;
    std::string all;
    if (!r)
      for (const auto& v : r.error()) {
        EXPECT_EQ(v.field, "robot.jointLimitsYaml");
        all += v.description + "\n";
      }
    return all;
  };
  EXPECT_THAT(problems("joint_limits: [a, b"), HasSubstr("is not YAML: line 1"));
  EXPECT_THAT(problems("limits:\n  a: {}\n"), HasSubstr("has no `joint_limits` mapping"));
  EXPECT_THAT(problems("- 1\n- 2\n"), HasSubstr("has no `joint_limits` mapping"));
  EXPECT_THAT(problems("joint_limits:\n  j1: 3\n"), HasSubstr("line 2, joint_limits.j1: must be a mapping"));
  EXPECT_THAT(problems("joint_limits:\n  j1:\n    has_velocity_limits: maybe\n    max_velocity: 1\n"),
              HasSubstr("line 3, joint_limits.j1.has_velocity_limits: must be true or false"));
  EXPECT_THAT(problems("joint_limits:\n  j1:\n    has_velocity_limits: true\n    max_velocity: fast\n"),
              HasSubstr("line 4, joint_limits.j1.max_velocity: must be a number"));
  EXPECT_THAT(problems("joint_limits:\n  j1:\n    has_acceleration_limits: true\n    max_acceleration: -2\n"),
              HasSubstr("line 4, joint_limits.j1.max_acceleration: "));
  EXPECT_THAT(problems("joint_limits:\n  j1:\n    has_jerk_limits: true\n    max_jerk: .inf\n"),
              HasSubstr("joint_limits.j1.max_jerk: "));
  EXPECT_THAT(problems("joint_limits:\n  j1:\n    has_velocity_limits: true\n"),
              HasSubstr("line 3, joint_limits.j1.has_velocity_limits: is true but max_velocity is missing"));
  EXPECT_THAT(problems("joint_limits:\n  j1: {}\n  j1: {}\n"), HasSubstr("the joint is named twice"));
  EXPECT_THAT(problems(std::string(200, '[') + std::string(200, ']')), HasSubstr("nests [ ] or { }"));
  EXPECT_THAT(problems(std::string(planner::kMaxJointLimitsYamlBytes + 1, ' ')), HasSubstr("bytes, more than"));
  // Every problem at once.
  const std::string two = problems(
      "joint_limits:\n  a:\n    has_velocity_limits: true\n    max_velocity: x\n  b:\n    has_jerk_limits: 2\n");
  EXPECT_THAT(two, HasSubstr("joint_limits.a.max_velocity"));
  EXPECT_THAT(two, HasSubstr("joint_limits.b.has_jerk_limits"));
}

// The Panda's URDF as Franka ships it (no <geotraj> block: no accelerations) is refused for a
// motion alone, and planned with MoveIt's file; the request's jointLimits over the file's; the
// hand's finger joint in the file not read; a file for another robot (the UR5e's joints)
// refused.
TEST(JointLimitsYaml, AUrdfWithoutAccelerationsTakesThemFromTheFile) {
  std::string urdf(planner::builtin_urdf("panda"));
  const auto block = urdf.rfind("<geotraj");  // the element, after the header comment
  ASSERT_NE(block, std::string::npos);
  urdf.erase(block, urdf.find("</geotraj>") + std::string("</geotraj>").size() - block);
  planner::RobotSpec spec;
  spec.source = planner::UrdfRobot{urdf};
  spec.tip_link = "panda_link8";
  const auto bare = planner::resolve_robot(spec, geotraj::testing::builtin_catalog());
  ASSERT_FALSE(bare);
  EXPECT_THAT(bare.error().front().description, HasSubstr("have no acceleration limit"));

  spec.joint_limits_yaml = kPandaYaml;
  spec.joint_limits.push_back({"panda_joint4", 1.5, std::nullopt, std::nullopt});
  const auto robot = planner::resolve_robot(spec, geotraj::testing::builtin_catalog());
  ASSERT_TRUE(robot) << robot.error().front().field << ": " << robot.error().front().description;
  const core::RobotModel& m = *robot->model;
  ASSERT_EQ(m.dof(), 7u);
  EXPECT_EQ(m.limits[0].max_acceleration, 3.75);
  EXPECT_EQ(m.limits[0].max_jerk, 7500.0);
  EXPECT_EQ(m.limits[1].max_acceleration, 1.875);
  EXPECT_EQ(m.limits[3].max_velocity, 1.5) << "the request's jointLimits over the file's";
  EXPECT_EQ(m.limits[3].max_acceleration, 3.125);
  EXPECT_EQ(m.limits[6].max_acceleration, 5.0);

  planner::RobotSpec panda;
  panda.source = planner::RobotByName{"panda"};
  panda.joint_limits_yaml = "joint_limits:\n  shoulder_pan_joint:\n    has_velocity_limits: true\n    max_velocity: 1\n";
  const auto other = planner::resolve_robot(panda, geotraj::testing::builtin_catalog());
  ASSERT_FALSE(other);
  bool named = false;
  for (const auto& v : other.error())
    named = named || (v.field == "robot.jointLimitsYaml" && v.description.find("names none of the model's joints") !=
                                                             std::string::npos);
  EXPECT_TRUE(named);
}

// A built-in model by name takes the file's limits over its own (a tighter set-up).
TEST(JointLimitsYaml, ABuiltInTakesTheFilesLimitsOverItsOwn) {
  planner::RobotSpec spec;
  spec.source = planner::RobotByName{"panda"};
  spec.joint_limits_yaml = kPandaYaml;
  const auto robot = planner::resolve_robot(spec, geotraj::testing::builtin_catalog());
  ASSERT_TRUE(robot) << robot.error().front().description;
  EXPECT_EQ(robot->model->limits[1].max_acceleration, 1.875);
  EXPECT_EQ(robot->model->limits[1].max_torque, 87.0);
  const auto bad = [] {
    planner::RobotSpec s;
    s.source = planner::RobotByName{"panda"};
    s.joint_limits_yaml = "joint_limits: {";
    return planner::resolve_robot(s, geotraj::testing::builtin_catalog());
  }();
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().front().field, "robot.jointLimitsYaml");
}

}  // namespace
}  // namespace geotraj::test
