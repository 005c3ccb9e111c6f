// Robot models: the built-in arms are valid, and validate_robot names the field of every
// problem (`limits[2].minPosition`, `links[1].alpha`, ...), all of them at once.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "test_support.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::test {
namespace {

using core::RobotModel;
using core::Violations;

RobotModel valid_model() { return *core::find_builtin_robot("ur5"); }

// The model with its DH table edited and the chain written again from it.
template <class Edit>
void edit_dh(RobotModel& m, Edit edit) {
  core::DhTable t = *m.dh;
  edit(t);
  core::set_dh(m, std::move(t));
}

// The UR5 as a general chain (no DH table kept): what a URDF or `joints` model is.
RobotModel general_model() {
  RobotModel m = valid_model();
  m.dh.reset();
  return m;
}

TEST(Robot, BuiltinsAreValid) {
  ASSERT_EQ(core::builtin_robots().size(), 2u);
  for (const auto& m : core::builtin_robots()) {
    EXPECT_TRUE(core::validate_robot(m).empty()) << m.name << "\n" << listed(core::validate_robot(m));
    EXPECT_FALSE(m.description.empty());
  }
  EXPECT_EQ(core::find_builtin_robot("pa10")->dof(), 7u);
  EXPECT_EQ(core::find_builtin_robot("ur5")->dof(), 6u);
  EXPECT_EQ(core::find_builtin_robot("nope"), nullptr);
}

TEST(Robot, HomeConfiguration) {
  const auto& pa10 = *core::find_builtin_robot("pa10");
  const core::JointVector q = core::home_configuration(pa10);
  ASSERT_EQ(q.size(), 7);
  for (std::size_t i = 0; i < 7; ++i) EXPECT_EQ(q(static_cast<Eigen::Index>(i)), pa10.home[i]);
  RobotModel m = valid_model();
  m.home.clear();
  EXPECT_TRUE(core::home_configuration(m).isZero());
}

struct BadCase {
  const char* name;
  const char* field;
  void (*spoil)(RobotModel&);
};

class RobotValidation : public ::testing::TestWithParam<BadCase> {};

TEST_P(RobotValidation, NamesTheField) {
  RobotModel m = valid_model();
  GetParam().spoil(m);
  const Violations v = core::validate_robot(m);
  EXPECT_TRUE(names(v, GetParam().field)) << "expected " << GetParam().field << ", got\n" << listed(v);
  for (const auto& x : v) EXPECT_FALSE(x.description.empty()) << x.field;
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

INSTANTIATE_TEST_SUITE_P(
    Robot, RobotValidation,
    ::testing::Values(
        BadCase{"NoLinks", "links",
                [](RobotModel& m) {
                  edit_dh(m, [](core::DhTable& table) { table.links.clear(); });
                  m.limits.clear();
                  m.home.clear();
                }},
        BadCase{"TooManyJoints", "links",
                [](RobotModel& m) {
                  edit_dh(m, [](core::DhTable& table) { table.links.resize(core::kMaxJoints + 1); });
                  m.limits.resize(core::kMaxJoints + 1, m.limits.front());
                  m.home.clear();
                }},
        BadCase{"FewerLimitsThanLinks", "limits", [](RobotModel& m) { m.limits.pop_back(); }},
        BadCase{"MoreLimitsThanLinks", "limits", [](RobotModel& m) { m.limits.push_back(m.limits.front()); }},
        BadCase{"NaNLinkLength", "links[1].a", [](RobotModel& m) { edit_dh(m, [](core::DhTable& table) { table.links[1].a = kNaN; }); }},
        BadCase{"NaNTwist", "links[3].alpha", [](RobotModel& m) { edit_dh(m, [](core::DhTable& table) { table.links[3].alpha = kNaN; }); }},
        BadCase{"InfiniteOffsetD", "links[0].d", [](RobotModel& m) { edit_dh(m, [](core::DhTable& table) { table.links[0].d = kInf; }); }},
        BadCase{"NaNTheta", "links[5].theta", [](RobotModel& m) { edit_dh(m, [](core::DhTable& table) { table.links[5].theta = kNaN; }); }},
        BadCase{"NaNOffset", "links[2].offset", [](RobotModel& m) { edit_dh(m, [](core::DhTable& table) { table.links[2].offset = kNaN; }); }},
        BadCase{"MinAboveMax", "limits[2].minPosition",
                [](RobotModel& m) {
                  m.limits[2].min_position = 1.0;
                  m.limits[2].max_position = -1.0;
                  m.home.clear();
                }},
        BadCase{"NaNMinPosition", "limits[0].minPosition", [](RobotModel& m) { m.limits[0].min_position = kNaN; }},
        BadCase{"InfiniteMaxPosition", "limits[4].maxPosition", [](RobotModel& m) { m.limits[4].max_position = kInf; }},
        BadCase{"ZeroMaxVelocity", "limits[1].maxVelocity", [](RobotModel& m) { m.limits[1].max_velocity = 0.0; }},
        BadCase{"NegativeMaxVelocity", "limits[3].maxVelocity", [](RobotModel& m) { m.limits[3].max_velocity = -2.0; }},
        BadCase{"ZeroMaxAcceleration", "limits[0].maxAcceleration",
                [](RobotModel& m) { m.limits[0].max_acceleration = 0.0; }},
        BadCase{"NegativeMaxJerk", "limits[5].maxJerk", [](RobotModel& m) { m.limits[5].max_jerk = -1.0; }},
        BadCase{"HomeOutsideLimits", "home[1]", [](RobotModel& m) { m.home[1] = m.limits[1].max_position + 0.1; }},
        BadCase{"HomeNaN", "home[0]", [](RobotModel& m) { m.home[0] = kNaN; }},
        BadCase{"HomeWrongSize", "home", [](RobotModel& m) { m.home.pop_back(); }},
        BadCase{"BaseNotARotation", "base.orientation", [](RobotModel& m) { m.base.linear()(0, 0) = 2.0; }},
        BadCase{"ToolMirrored", "tool.orientation", [](RobotModel& m) { m.tool.linear()(2, 2) = -1.0; }},
        BadCase{"ToolNotFinite", "tool", [](RobotModel& m) { m.tool.translation().x() = kNaN; }},
        BadCase{"NoJoints", "joints",
                [](RobotModel& m) {
                  m = general_model();
                  m.joints.clear();
                  m.limits.clear();
                  m.home.clear();
                }},
        BadCase{"ZeroAxis", "joints[2].axis",
                [](RobotModel& m) {
                  m = general_model();
                  m.joints[2].axis.setZero();
                }},
        BadCase{"AxisNotUnit", "joints[0].axis",
                [](RobotModel& m) {
                  m = general_model();
                  m.joints[0].axis = Eigen::Vector3d(0.0, 0.0, 2.0);
                }},
        BadCase{"OriginNaN", "joints[3].origin",
                [](RobotModel& m) {
                  m = general_model();
                  m.joints[3].origin.translation().y() = kNaN;
                }},
        BadCase{"OriginMirrored", "joints[1].origin.orientation",
                [](RobotModel& m) {
                  m = general_model();
                  m.joints[1].origin.linear()(0, 0) = -m.joints[1].origin.linear()(0, 0);
                }},
        BadCase{"OriginFar", "joints[4].origin.position",
                [](RobotModel& m) {
                  m = general_model();
                  m.joints[4].origin.translation().x() = 2e6;
                }},
        BadCase{"FlangeNotFinite", "flange",
                [](RobotModel& m) {
                  m = general_model();
                  m.flange.translation().z() = kInf;
                }},
        BadCase{"JointNameTooLong", "joints[5].name",
                [](RobotModel& m) {
                  m = general_model();
                  m.joints[5].name.assign(65, 'j');
                }}),
    [](const ::testing::TestParamInfo<BadCase>& p) { return std::string(p.param.name); });

TEST(Robot, EveryProblemIsReportedAtOnce) {
  RobotModel m = valid_model();
  edit_dh(m, [](core::DhTable& table) { table.links[1].alpha = kNaN; });
  m.limits[2].max_velocity = 0.0;
  m.home[3] = 100.0;
  const Violations v = core::validate_robot(m);
  EXPECT_TRUE(names(v, "links[1].alpha")) << listed(v);
  EXPECT_TRUE(names(v, "limits[2].maxVelocity")) << listed(v);
  EXPECT_TRUE(names(v, "home[3]")) << listed(v);
  EXPECT_EQ(v.size(), 3u) << listed(v);
}

// ValidRobot: refused with validate_robot's violations; once made, copies share the one
// model, and the default jerk keeps it valid (and leaves a jerk-limited model as it is).
TEST(Robot, AValidRobotIsCheckedOnceAndShared) {
  RobotModel bad = valid_model();
  bad.limits[0].max_velocity = 0.0;
  const auto refused = core::ValidRobot::check(bad);
  ASSERT_FALSE(refused.has_value());
  EXPECT_EQ(refused.error().size(), core::validate_robot(bad).size()) << listed(refused.error());
  EXPECT_TRUE(names(refused.error(), "limits[0].maxVelocity")) << listed(refused.error());

  RobotModel plain = valid_model();
  for (auto& l : plain.limits) l.max_jerk.reset();
  const auto robot = core::ValidRobot::check(plain);
  ASSERT_TRUE(robot.has_value()) << listed(robot.error());
  const core::ValidRobot copy = *robot;
  EXPECT_EQ(&copy.model(), &robot->model());
  EXPECT_EQ(copy->dof(), valid_model().dof());

  const core::ValidRobot jerked = core::with_default_jerk(*robot);
  EXPECT_NE(&jerked.model(), &robot->model());
  EXPECT_TRUE(core::jerk_limited(jerked));
  EXPECT_TRUE(core::validate_robot(jerked).empty()) << listed(core::validate_robot(jerked));
  for (std::size_t i = 0; i < jerked->dof(); ++i) {
    EXPECT_EQ(*jerked->limits[i].max_jerk, core::jerk_bound(robot->model().limits[i])) << "joint " << i;
  }
  EXPECT_EQ(&core::with_default_jerk(jerked).model(), &jerked.model());  // nothing to add: shared
}

// A continuous joint's position limits are not read: any finite value is within them, NaN
// limits are not an error, and a home far outside [min, max] is fine.
TEST(Robot, ContinuousJointsHaveNoPositionLimits) {
  RobotModel m = general_model();
  m.joints[5].type = core::JointType::kContinuous;
  m.limits[5].min_position = kNaN;
  m.limits[5].max_position = kNaN;
  m.home[5] = 40.0;
  EXPECT_TRUE(core::validate_robot(m).empty()) << listed(core::validate_robot(m));
  EXPECT_TRUE(core::within_position_limits(core::JointType::kContinuous, m.limits[5], -1e5));
  EXPECT_FALSE(core::within_position_limits(core::JointType::kRevolute, m.limits[4], 100.0));
  m.home[5] = kInf;
  EXPECT_TRUE(names(core::validate_robot(m), "home[5]"));
}

TEST(Robot, DescriptionsNameTheValue) {
  RobotModel m = valid_model();
  m.limits[2].min_position = 1.5;
  m.limits[2].max_position = -1.5;
  m.home.clear();
  const Violations v = core::validate_robot(m);
  ASSERT_EQ(v.size(), 1u) << listed(v);
  EXPECT_NE(v[0].description.find("1.5"), std::string::npos) << v[0].description;
}

}  // namespace
}  // namespace geotraj::test
