// The wire alone (server/wire/convert.hpp), without gRPC calls: each field of a PlanRequest
// reaches the planner's Request as the API documents it, each value the wire cannot translate
// is named by its field, and the robot model's wire form round-trips.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <variant>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "planner/robots.hpp"
#include "server/wire/convert.hpp"
#include "tests/planner/builtin_catalog.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

constexpr auto& catalog = geotraj::testing::builtin_catalog;

// The request as the wire reads it, admitted by the planner for `use`.
core::Expected<planner::Request> convert(const v1::PlanRequest& request, planner::Use use = planner::Use::kPlan) {
  return planner::admit(server::request_input_from_proto(request, server::ServiceLimits{}), catalog(), use);
}

// The violation of `field` in a refused conversion ("" when there is none).
std::string description_of(const core::Expected<planner::Request>& converted, const std::string& field) {
  if (converted) return "";
  for (const auto& v : converted.error()) {
    if (v.field == field) return v.description;
  }
  return "";
}

std::string listed(const core::Expected<planner::Request>& converted) {
  std::string out;
  if (!converted) {
    for (const auto& v : converted.error()) out += v.field + ": " + v.description + "\n";
  }
  return out;
}

TEST(WireRequest, EveryMotionFieldReachesThePlanner) {
  auto request = demo_example('c');
  auto* m = request.mutable_motion();
  m->set_duration_s(7.5);
  m->set_profile(v1::MOTION_PROFILE_S_CURVE);
  m->set_ramp_fraction(0.3);
  m->set_cycle_rate_hz(250.0);
  m->set_time_parameterization(v1::TIME_PARAMETERIZATION_TAYLOR_SECOND_ORDER);
  m->set_speed_scale(0.5);
  m->set_max_speed(0.4);
  m->set_max_acceleration(2.0);
  m->set_max_jerk(30.0);
  m->set_max_angular_speed(1.5);
  m->set_max_angular_acceleration(6.0);
  const auto converted = convert(request);
  ASSERT_TRUE(converted.has_value()) << listed(converted);
  ASSERT_TRUE(converted->motion.has_value());
  const core::MotionSpec& s = *converted->motion;
  EXPECT_EQ(s.duration_s, 7.5);
  EXPECT_EQ(s.profile, core::ProfileShape::kSCurve);
  EXPECT_EQ(s.ramp_fraction, 0.3);
  EXPECT_TRUE(s.ramp_fraction_given);
  EXPECT_EQ(s.cycle_rate_hz, 250.0);
  EXPECT_EQ(s.time_parameterization, core::TimeParameterization::kTaylorSecondOrder);
  EXPECT_EQ(s.speed_scale, 0.5);
  EXPECT_EQ(s.max_speed, 0.4);
  EXPECT_EQ(s.max_acceleration, 2.0);
  EXPECT_EQ(s.max_jerk, 30.0);
  EXPECT_EQ(s.max_angular_speed, 1.5);
  EXPECT_EQ(s.max_angular_acceleration, 6.0);
}

TEST(WireRequest, UnknownEnumValuesAreNamedWithTheValuesThatExist) {
  auto request = demo_example('a');
  request.mutable_motion()->set_profile(static_cast<v1::MotionProfile>(42));
  auto converted = convert(request);
  EXPECT_THAT(description_of(converted, "motion.profile"), HasSubstr("unknown value 42"));
  EXPECT_THAT(description_of(converted, "motion.profile"), HasSubstr("MOTION_PROFILE_S_CURVE"));

  request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  request.mutable_robot()->set_approach(static_cast<v1::ApproachMove>(9));
  converted = convert(request);
  EXPECT_THAT(description_of(converted, "robot.approach"), HasSubstr("unknown value 9"));

  request = demo_example('a');
  request.set_pacing(static_cast<v1::StreamPacing>(7));
  converted = convert(request, planner::Use::kStream);
  EXPECT_THAT(description_of(converted, "pacing"), HasSubstr("unknown value 7"));
}

TEST(WireRequest, EveryRobotFieldReachesThePlanner) {
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  auto* r = request.mutable_robot();
  r->set_report_only(true);
  r->set_branch_tolerance(2e-3);
  r->set_start_position_tolerance(2e-4);
  r->set_start_orientation_tolerance(3e-3);
  r->set_approach(v1::APPROACH_MOVE_LINEAR);
  r->set_velocity_scale(0.5);
  r->set_acceleration_scale(0.25);
  auto* base = r->mutable_base();
  base->mutable_position()->set_z(0.1);
  base->mutable_orientation()->set_w(std::sqrt(0.5));
  base->mutable_orientation()->set_z(std::sqrt(0.5));
  r->clear_initial_joints();
  for (double q : {0.1, 0.2, 0.0, 1.2, 0.0, 0.5, 0.0}) r->add_initial_joints(q);
  auto* named = r->add_joint_limits();
  const core::RobotModel& pa10 = *catalog().find("pa10");
  named->set_joint(pa10.joints[3].name);
  named->set_max_velocity(0.8);
  const auto converted = convert(request);
  ASSERT_TRUE(converted.has_value()) << listed(converted);
  const planner::Robot& robot = *converted->robot;
  EXPECT_TRUE(robot.report_only);
  EXPECT_EQ(robot.branch_tolerance, 2e-3);
  EXPECT_EQ(robot.start_position_tolerance, 2e-4);
  EXPECT_EQ(robot.start_orientation_tolerance, 3e-3);
  EXPECT_EQ(robot.approach, planner::Approach::kLinear);
  EXPECT_DOUBLE_EQ(robot.model->limits[0].max_velocity, 0.5 * pa10.limits[0].max_velocity);
  EXPECT_DOUBLE_EQ(robot.model->limits[3].max_velocity, 0.4);  // the request's 0.8, scaled
  EXPECT_DOUBLE_EQ(robot.model->limits[0].max_acceleration, 0.25 * pa10.limits[0].max_acceleration);
  EXPECT_NEAR(robot.model->base.translation().z(), 0.1, 1e-15);
  EXPECT_TRUE(robot.model->base.linear().isApprox(
      Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-12));
  ASSERT_EQ(robot.seed.size(), 7);
  EXPECT_EQ(robot.seed(3), 1.2);
}

TEST(WireRequest, APoseThatIsNoneIsNamedWithTheRestOfTheRobot) {
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  request.mutable_robot()->mutable_tool()->mutable_orientation()->set_w(2.0);
  request.mutable_robot()->set_branch_tolerance(-1.0);
  const auto converted = convert(request);
  EXPECT_THAT(description_of(converted, "robot.tool.orientation"), HasSubstr("unit quaternion"));
  EXPECT_THAT(description_of(converted, "robot.branchTolerance"), HasSubstr("> 0")) << "in the same answer";
}

TEST(WireRequest, AnInlineModelWrittenTwoWaysIsRefusedByField) {
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  v1::RobotModel model;
  server::to_proto(*catalog().find("ur5"), model);  // a DH table: links
  model.add_joints()->set_name("extra");             // and a general chain
  *request.mutable_robot()->mutable_model() = model;
  const auto converted = convert(request);
  EXPECT_THAT(description_of(converted, "robot.model.joints"), HasSubstr("give one"));
}

TEST(WireRequest, AModelsWireFormRoundTrips) {
  for (const auto& model : catalog().models) {
    v1::RobotModel wire;
    server::to_proto(model, wire);
    const auto back = server::robot_model_from_proto(wire, "robot.model.");
    ASSERT_TRUE(back.has_value()) << model->name;
    EXPECT_EQ(back->name, model->name);
    ASSERT_EQ(back->dof(), model->dof()) << model->name;
    for (std::size_t i = 0; i < model->dof(); ++i) {
      EXPECT_EQ(back->joints[i].name, model->joints[i].name);
      EXPECT_TRUE(back->joints[i].origin.isApprox(model->joints[i].origin, 1e-12)) << model->name << " joint " << i;
      EXPECT_EQ(back->limits[i].max_velocity, model->limits[i].max_velocity);
      EXPECT_EQ(back->limits[i].max_jerk, model->limits[i].max_jerk);
    }
    EXPECT_TRUE(back->flange.isApprox(model->flange, 1e-12)) << model->name;
    EXPECT_EQ(back->home, model->home);
  }
}

// Mass properties and torque limits cross the wire: a general chain's on its joints, a DH
// table's on its rows (in frame i, moved by set_dh the same way on both sides); an inertia
// of other than six values is refused by field.
TEST(WireRequest, MassPropertiesAndTorqueLimitsRoundTrip) {
  for (const char* name : {"panda", "ur5"}) {
    core::RobotModel model = *catalog().find(name);
    for (std::size_t i = 0; i < model.dof(); ++i) {
      const double k = static_cast<double>(i + 1);
      const core::Inertial in{2.0 * k, Eigen::Vector3d(0.01 * k, -0.02, 0.03), Eigen::Matrix3d::Identity() * 0.01 * k};
      if (model.dh) model.dh->links[i].inertial = in; else model.joints[i].inertial = in;
      model.limits[i].max_torque = 10.0 * k;
    }
    if (model.dh) core::set_dh(model, *model.dh);
    v1::RobotModel wire;
    server::to_proto(model, wire);
    const auto back = server::robot_model_from_proto(wire, "robot.model.");
    ASSERT_TRUE(back.has_value()) << name;
    for (std::size_t i = 0; i < model.dof(); ++i) {
      ASSERT_TRUE(back->joints[i].inertial.has_value()) << name << " " << i;
      EXPECT_EQ(back->joints[i].inertial->mass, model.joints[i].inertial->mass);
      EXPECT_TRUE(back->joints[i].inertial->center_of_mass.isApprox(model.joints[i].inertial->center_of_mass, 1e-15));
      EXPECT_TRUE(back->joints[i].inertial->inertia.isApprox(model.joints[i].inertial->inertia, 1e-15));
      EXPECT_EQ(back->limits[i].max_torque, model.limits[i].max_torque);
    }
    v1::RobotModel bad = wire;
    auto* inertia = bad.joints_size() > 0 ? bad.mutable_joints(2)->mutable_inertial()->mutable_inertia()
                                          : bad.mutable_links(2)->mutable_inertial()->mutable_inertia();
    inertia->RemoveLast();
    const auto refused = server::robot_model_from_proto(bad, "robot.model.");
    ASSERT_FALSE(refused.has_value());
    EXPECT_EQ(refused.error().front().field,
              std::string("robot.model.") + (bad.joints_size() > 0 ? "joints" : "links") + "[2].inertial.inertia");
    EXPECT_THAT(refused.error().front().description, HasSubstr("needs 6 values"));
  }
}

// A model file is read as written (its JSON and wire form refused here, named by field) and
// checked where it enters the catalogue (core::ValidRobot::check, geotrajd's start).
TEST(WireRequest, AModelFileIsReadAsWrittenAndCheckedWhereItEnters) {
  v1::RobotModel wire;
  server::to_proto(*catalog().find("ur5"), wire);
  wire.mutable_limits(2)->set_max_velocity(-1.0);
  std::string json;
  ASSERT_TRUE(google::protobuf::util::MessageToJsonString(wire, &json).ok());
  const auto read = server::robot_model_from_json(json);
  ASSERT_TRUE(read.has_value()) << read.error().front().field;
  EXPECT_EQ(read->limits[2].max_velocity, -1.0);
  const auto checked = core::ValidRobot::check(*read);
  ASSERT_FALSE(checked.has_value());
  EXPECT_EQ(checked.error().front().field, "limits[2].maxVelocity");
  EXPECT_FALSE(server::robot_model_from_json("{\"name\": \"x\", \"links\": 3}").has_value());
}

TEST(WireRequest, FollowingAPoseNeedsSixJointsNamedWhereTheModelCameFrom) {
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  v1::RobotModel model;
  core::RobotModel five = *catalog().find("ur5");
  five.dh->links.pop_back();
  five.limits.pop_back();
  five.home.pop_back();
  core::set_dh(five, *five.dh);
  server::to_proto(five, model);
  *request.mutable_robot()->mutable_model() = model;
  request.mutable_robot()->clear_initial_joints();
  const auto converted = convert(request);
  EXPECT_THAT(description_of(converted, "robot.model.links"), HasSubstr("5 joints"));
}

// The wire reads; it does not judge: values the planner refuses (an unknown arm, a negative
// duration, a move with two goals, a scale a duration ignores) reach planner::RequestInput as
// given, with no violation of the wire's.
TEST(WireRequest, ReadsEveryValueWithoutJudgingIt) {
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  request.mutable_robot()->set_name("no such arm");
  request.mutable_motion()->set_duration_s(-1.0);
  request.mutable_motion()->set_acceleration_scale(0.5);
  auto* move = request.mutable_joint_move();
  move->add_goal(0.1);
  move->mutable_goal_pose()->mutable_position()->set_x(0.4);
  const planner::RequestInput in = server::request_input_from_proto(request, server::ServiceLimits{});
  EXPECT_TRUE(in.violations.empty()) << in.violations.front().field;
  ASSERT_TRUE(in.robot.has_value());
  EXPECT_EQ(std::get<planner::RobotByName>(in.robot->source).name, "no such arm");
  ASSERT_TRUE(in.motion.has_value());
  EXPECT_EQ(in.motion->duration_s, -1.0);
  EXPECT_EQ(in.motion->acceleration_scale, 0.5);
  ASSERT_TRUE(in.geometry.path.has_value());
  EXPECT_TRUE(in.geometry.path->usable());
  ASSERT_TRUE(in.geometry.joint_move.has_value());
  EXPECT_EQ(in.geometry.joint_move->goal, std::vector<double>{0.1});
  ASSERT_TRUE(in.geometry.joint_move->goal_pose.has_value());
  EXPECT_EQ(in.geometry.joint_move->goal_pose->translation().x(), 0.4);
  EXPECT_EQ(in.geometry.kinds(), 2) << "two kinds, for the planner to refuse";
}

TEST(WireRequest, AMotionGivesTheFieldsItSets) {
  auto request = demo_example('a');
  v1::MotionSpec m;
  m.set_profile(v1::MOTION_PROFILE_S_CURVE);
  m.set_max_speed(0.3);
  *request.mutable_motion() = m;
  const planner::RequestInput in = server::request_input_from_proto(request, server::ServiceLimits{});
  ASSERT_TRUE(in.motion.has_value());
  EXPECT_EQ(planner::given_fields(*in.motion), (std::vector<std::string>{"profile", "maxSpeed"}));
  EXPECT_FALSE(in.motion->duration_s.has_value()) << "proto3: a duration of 0 is not given";
}

TEST(WireRequest, ASequencesStepsAreReadWithWhatCannotBeReadNamedFromTheRoot) {
  auto request = example<v1::PlanRequest>("sequence_ur5.json");
  ASSERT_GE(request.sequence_size(), 2);
  auto* path_step = request.add_sequence();
  *path_step->mutable_path() = demo_example('a').path();
  path_step->mutable_path()->mutable_frames(0)->clear_tangent();
  path_step->mutable_motion()->set_max_jerk(40.0);
  path_step->set_blend_tolerance(0.01);
  auto* pose_step = request.add_sequence();
  pose_step->mutable_joint_move()->mutable_goal_pose()->mutable_orientation()->set_w(2.0);
  const planner::RequestInput in = server::request_input_from_proto(request, server::ServiceLimits{});
  const std::size_t steps = static_cast<std::size_t>(request.sequence_size());
  ASSERT_EQ(in.sequence.size(), steps);
  EXPECT_EQ(in.sequence_given, steps);
  const planner::StepInput& p = in.sequence[steps - 2];
  ASSERT_TRUE(p.geometry.path.has_value());
  EXPECT_FALSE(p.geometry.path->usable()) << "not readable";
  // Named from the path; core's checks of the normal against the missing tangent are noise.
  ASSERT_FALSE(p.geometry.path->violations.empty());
  EXPECT_EQ(p.geometry.path->violations.front().field, "frames[0].tangent");
  EXPECT_EQ(p.geometry.path->unchecked.count("frames[0].normal"), 1U);
  EXPECT_EQ(p.blend_tolerance, 0.01);
  ASSERT_TRUE(p.motion.has_value());
  EXPECT_EQ(planner::given_fields(*p.motion), std::vector<std::string>{"maxJerk"});
  const auto named = [&in](const std::string& field) {
    return std::any_of(in.violations.begin(), in.violations.end(),
                       [&field](const core::FieldViolation& v) { return v.field == field; });
  };
  EXPECT_TRUE(named("sequence[" + std::to_string(steps - 1) + "].jointMove.goalPose.orientation"));
  // A sequence longer than the planner plans is not read at all.
  for (int i = 0; i < planner::kMaxSequenceSteps; ++i) *request.add_sequence() = request.sequence(0);
  const planner::RequestInput long_one = server::request_input_from_proto(request, server::ServiceLimits{});
  EXPECT_TRUE(long_one.sequence.empty());
  EXPECT_EQ(long_one.sequence_given, static_cast<std::size_t>(request.sequence_size()));
}

TEST(WireRequest, ASequenceStepTakesTheRequestsMotionFieldsItDoesNotGive) {
  auto request = example<v1::PlanRequest>("sequence_ur5.json");
  ASSERT_GE(request.sequence_size(), 2);
  request.mutable_motion()->set_cycle_rate_hz(250.0);
  auto* step = request.mutable_sequence(1);
  step->mutable_motion()->set_duration_s(3.0);
  step->mutable_motion()->clear_cycle_rate_hz();
  const auto converted = convert(request);
  ASSERT_TRUE(converted.has_value()) << listed(converted);
  ASSERT_EQ(converted->sequence.size(), static_cast<std::size_t>(request.sequence_size()));
  EXPECT_EQ(converted->sequence[1].motion.cycle_rate_hz, 250.0);
  EXPECT_EQ(converted->sequence[1].motion.duration_s, 3.0);
}

}  // namespace
}  // namespace geotraj::testing
