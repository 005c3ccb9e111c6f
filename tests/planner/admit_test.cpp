// planner::admit (planner/admit.cpp), without the wire: a request as given becomes the
// planner's Request, or every violation of it named from the request's root. What each call
// needs of a request, the motion checked as its timing needs (no duration made up), the robot
// resolved once, the moves completed from the robot, and a sequence's steps each with the
// request's motion under its own.
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <variant>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/robot/kinematics.hpp"
#include "planner/jog.hpp"
#include "planner/kinematics.hpp"
#include "planner/request_input.hpp"
#include "planner/robots.hpp"
#include "tests/planner/builtin_catalog.hpp"

namespace geotraj::test {
namespace {

using ::testing::HasSubstr;

constexpr auto& catalog = geotraj::testing::builtin_catalog;

core::PathSpec line() {
  core::PathSpec path;
  core::KeyFrame a, b;
  a.p_W = {0.4, 0.0, 0.5};
  b.p_W = {0.6, 0.0, 0.5};
  path.frames = {a, b};
  return path;
}

planner::GeometryInput path_geometry() {
  planner::GeometryInput g;
  g.path = planner::PathInput{line(), {}, {}, true};
  return g;
}

planner::RobotSpec named(std::string name) {
  planner::RobotSpec spec;
  spec.source = planner::RobotByName{std::move(name)};
  return spec;
}

planner::MotionInput timed(double duration_s) {
  planner::MotionInput m;
  m.duration_s = duration_s;
  return m;
}

std::string listed(const core::Expected<planner::Request>& admitted) {
  std::string out;
  if (!admitted) {
    for (const auto& v : admitted.error()) out += v.field + ": " + v.description + "\n";
  }
  return out;
}

// The violation of `field` ("" when there is none).
std::string description_of(const core::Expected<planner::Request>& admitted, const std::string& field) {
  if (admitted) return "";
  for (const auto& v : admitted.error()) {
    if (v.field == field) return v.description;
  }
  return "";
}

TEST(Admit, EachCallAsksForWhatItNeeds) {
  planner::RequestInput in;
  in.geometry = path_geometry();
  // PlanTrajectory of a path alone: its geometry.
  auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  EXPECT_FALSE(admitted->motion.has_value());
  EXPECT_TRUE(std::holds_alternative<core::PathSpec>(admitted->geometry));
  // A stream needs a motion; a plan with a robot does too.
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kStream), "motion"),
              HasSubstr("required to stream"));
  in.robot = named("pa10");
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kPlan), "motion"),
              HasSubstr("with a robot or a move"));
  // An analysis reads the path only: neither the robot nor the motion.
  in.robot = named("no such arm");
  in.motion = timed(-1.0);
  admitted = planner::admit(in, catalog(), planner::Use::kAnalyze);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  EXPECT_EQ(admitted->robot, nullptr);
  // ... and a move is no path.
  in.geometry = {};
  in.geometry.joint_move = planner::JointMoveInput{};
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kAnalyze), "path"), HasSubstr("required"));
}

// A joint move or a joint path needs a robot: said where none is given; where one is given
// but refused, its own violations name it and nothing says it is missing.
TEST(Admit, AJointMotionNeedsARobotAndARefusedOneIsNamedOnce) {
  planner::RequestInput in;
  in.geometry.joint_move = planner::JointMoveInput{{}, {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7}, std::nullopt};
  in.motion = timed(2.0);
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kPlan), "robot"), HasSubstr("is required"));
  in.geometry = {};
  in.geometry.joint_path = core::JointPathSpec{};
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kPlan), "robot"), HasSubstr("is required"));
  in.robot = named("panda");
  in.robot->payload = core::Payload{std::numeric_limits<double>::quiet_NaN(), Eigen::Vector3d::Zero()};
  const auto refused = planner::admit(in, catalog(), planner::Use::kPlan);
  EXPECT_THAT(description_of(refused, "robot.payload.mass"), HasSubstr("must be in [0"));
  EXPECT_EQ(description_of(refused, "robot"), "") << listed(refused);
}

TEST(Admit, AMotionTimedByTheLimitsNeedsNoProfileLimits) {
  planner::RequestInput in;
  in.geometry = path_geometry();
  in.robot = named("pa10");
  in.motion = planner::MotionInput{};  // durationS 0 with a robot: time-optimal, the joint limits set the pace
  in.motion->ramp_time_s = 0.2;        // a duration's ramps: the limits time this one, and do not read it
  auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  EXPECT_EQ(admitted->motion->duration_s, 0.0) << "no duration made up";
  // Without a robot an S-curve of durationS 0 is a minimum-time profile: its limits are needed.
  in.robot.reset();
  in.motion = planner::MotionInput{};
  in.motion->profile = core::ProfileShape::kSCurve;
  admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  EXPECT_THAT(description_of(admitted, "motion.durationS"), HasSubstr("needs maxSpeed and maxAcceleration"));
  EXPECT_THAT(description_of(admitted, "motion.maxJerk"), HasSubstr("S-curve"));
  // The values are checked whoever times the motion.
  in.motion->profile.reset();
  in.motion->speed_scale = 1.5;
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kPlan), "motion.speedScale"),
              HasSubstr("(0, 1]"));
}

TEST(Admit, AnAccelerationScaleScalesOnlyATimingByTheLimits) {
  planner::RequestInput in;
  in.geometry = path_geometry();
  in.robot = named("pa10");
  in.motion = timed(5.0);
  in.motion->acceleration_scale = 0.5;
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kPlan), "motion.accelerationScale"),
              HasSubstr("timed by it instead"));
  // An approach move comes first, and the limits time it.
  in.robot->approach = planner::Approach::kJoint;
  const auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  EXPECT_EQ(admitted->motion->acceleration_scale, 0.5);
}

TEST(Admit, MovesAreCompletedFromTheRobot) {
  const core::RobotModel& pa10 = *catalog().find("pa10");
  planner::RequestInput in;
  in.robot = named("pa10");
  in.robot->initial_joints = {0.1, 0.2, 0.0, 1.2, 0.0, 0.5, 0.0};
  in.motion = timed(2.0);
  in.geometry.joint_move = planner::JointMoveInput{{}, {0.0, 0.3, 0.0, 1.0, 0.0, 0.4, 0.0}, std::nullopt};
  auto admitted = planner::admit(in, catalog(), planner::Use::kStream);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  EXPECT_EQ(std::get<core::JointMoveSpec>(admitted->geometry).start, in.robot->initial_joints)
      << "an empty start is the initial joints";
  // A line without a start starts at the pose of the initial joints.
  in.geometry = {};
  in.geometry.linear_move = planner::LinearMoveInput{};
  in.geometry.linear_move->goal = core::ToolPose{};
  in.geometry.linear_move->goal->p_WT = {0.3, 0.1, 0.6};
  admitted = planner::admit(in, catalog(), planner::Use::kStream);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  core::JointVector q(pa10.dof());
  for (std::size_t j = 0; j < pa10.dof(); ++j) q[static_cast<Eigen::Index>(j)] = in.robot->initial_joints[j];
  const Eigen::Isometry3d X = core::forward_kinematics(admitted->robot->model, q);
  EXPECT_LT((std::get<core::LinearMoveSpec>(admitted->geometry).start.p_WT - X.translation()).norm(), 1e-12);
  // Without a robot the line needs its start; goal joints need the robot too.
  in.robot.reset();
  in.geometry.linear_move->goal.reset();
  in.geometry.linear_move->goal_joints = {0.0, 0.0};
  admitted = planner::admit(in, catalog(), planner::Use::kStream);
  EXPECT_THAT(description_of(admitted, "linearMove.start"), HasSubstr("required without a robot"));
  EXPECT_THAT(description_of(admitted, "linearMove.goalJoints"), HasSubstr("needs `robot`"));
}

TEST(Admit, FollowingAPoseTakesSixJointsNamedWhereTheChainWasWritten) {
  core::RobotModel planar = *catalog().find("pa10");
  planar.name = "three joints";
  planar.joints.resize(3);
  planar.limits.resize(3);
  planar.home.resize(3);
  planar.dh.reset();
  planner::RobotSpec spec;
  spec.source = planner::InlineRobot{planar, "robot.model.links"};
  planner::RequestInput in;
  in.geometry = path_geometry();
  in.robot = spec;
  in.motion = timed(2.0);
  const auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  ASSERT_FALSE(admitted.has_value());
  EXPECT_THAT(description_of(admitted, "robot.model.links"), HasSubstr("has 3 joints")) << listed(admitted);
}

TEST(Admit, TheWiresViolationsComeFirstAndEveryOtherIsListedWithThem) {
  planner::RequestInput in;
  in.geometry = path_geometry();
  in.robot = named("no such arm");
  in.motion = timed(2.0);
  in.motion->cycle_rate_hz = -5.0;
  in.violations.push_back({"robot.base.orientation", "must be a unit quaternion"});
  const auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  ASSERT_FALSE(admitted.has_value());
  ASSERT_GE(admitted.error().size(), 3u) << listed(admitted);
  EXPECT_EQ(admitted.error().front().field, "robot.base.orientation");
  EXPECT_THAT(description_of(admitted, "robot.name"), HasSubstr("no such arm"));
  EXPECT_THAT(description_of(admitted, "motion.cycleRateHz"), HasSubstr("Hz"));
}

// A path the wire could not read in full: its violations and core's of what it could read,
// in key-frame order, before the request's other fields; a step's after the request's own.
TEST(Admit, APartlyReadPathIsListedWithCoresViolationsInFrameOrder) {
  planner::PathInput path{line(), {}, {}, true};
  path.spec.frames.push_back(path.spec.frames.back());
  path.spec.frames[2].p_W.x() = 0.8;
  path.spec.frames[0].kappa = -1.0;                     // core: frames[0].curvature
  path.spec.frames[1].N_W = Eigen::Vector3d::UnitX();   // core, but noise beside the wire's
  path.violations.push_back({"frames[1].tangent", "is required"});
  path.unchecked.insert("frames[1].normal");
  path.spec.frames[2].tangent_scale = -1.0;             // core: frames[2].tangentScale

  planner::RequestInput in;
  in.geometry.path = path;
  in.motion = timed(2.0);
  in.violations.push_back({"pacing", "unknown value 7"});
  auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  ASSERT_FALSE(admitted.has_value());
  std::vector<std::string> fields;
  for (const auto& v : admitted.error()) fields.push_back(v.field);
  EXPECT_THAT(fields, ::testing::ElementsAre("path.frames[0].curvature", "path.frames[1].tangent",
                                             "path.frames[2].tangentScale", "pacing"))
      << listed(admitted);

  // The same path as a sequence's step: the request's own fields first, then the step's path
  // and the step's other fields.
  planner::RequestInput sequence;
  sequence.motion = timed(2.0);
  sequence.sequence.resize(2);
  sequence.sequence_given = 2;
  sequence.sequence[0].geometry.path = path;
  sequence.sequence[1].geometry.path = planner::PathInput{line(), {}, {}, true};
  sequence.violations.push_back({"sequence[0].motion.profile", "unknown value 9"});
  sequence.violations.push_back({"pacing", "unknown value 7"});
  admitted = planner::admit(sequence, catalog(), planner::Use::kPlan);
  ASSERT_FALSE(admitted.has_value());
  fields.clear();
  for (const auto& v : admitted.error()) fields.push_back(v.field);
  ASSERT_GE(fields.size(), 5u) << listed(admitted);
  EXPECT_THAT(std::vector<std::string>(fields.begin(), fields.begin() + 5),
              ::testing::ElementsAre("pacing", "sequence[0].path.frames[0].curvature", "sequence[0].path.frames[1].tangent",
                                     "sequence[0].path.frames[2].tangentScale", "sequence[0].motion.profile"))
      << listed(admitted);

  // A path refused before it was read (too many key frames) is not checked further.
  planner::PathInput unread{path.spec, {{"frames", "has 3 key frames; this server accepts at most 2"}}, {}, false};
  EXPECT_THAT(planner::path_violations(unread), ::testing::SizeIs(1));
  const auto alone = planner::admit_path(unread);
  ASSERT_FALSE(alone.has_value());
  EXPECT_EQ(alone.error().front().field, "path.frames");
  EXPECT_EQ(planner::admit_path(std::nullopt).error().front().field, "path");
  EXPECT_TRUE(planner::path_violations(planner::PathInput{line(), {}, {}, true}).empty());
}

planner::StepInput line_step(Eigen::Vector3d goal) {
  planner::StepInput step;
  step.geometry.linear_move = planner::LinearMoveInput{};
  step.geometry.linear_move->goal = core::ToolPose{};
  step.geometry.linear_move->goal->p_WT = goal;
  return step;
}

TEST(Admit, AStepTakesEveryMotionFieldItLacksFromTheRequest) {
  planner::RequestInput in;
  in.robot = named("pa10");
  in.motion = timed(3.0);
  in.motion->cycle_rate_hz = 250.0;
  in.motion->acceleration_scale = 0.5;
  in.sequence.push_back(line_step({0.5, 0.1, 0.5}));
  in.sequence.push_back(line_step({0.5, 0.2, 0.5}));
  in.sequence[1].motion = planner::MotionInput{};
  in.sequence[1].motion->max_speed = 0.3;
  in.sequence_given = 2;
  // The request's accelerationScale with its durationS is refused once, on the request's field.
  auto admitted = planner::admit(in, catalog(), planner::Use::kStream);
  EXPECT_THAT(description_of(admitted, "motion.accelerationScale"), HasSubstr("timed by it"));
  in.motion->acceleration_scale.reset();
  admitted = planner::admit(in, catalog(), planner::Use::kStream);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  ASSERT_EQ(admitted->sequence.size(), 2u);
  const planner::Step& second = admitted->sequence[1];
  EXPECT_EQ(second.motion.cycle_rate_hz, 250.0) << "inherited";
  EXPECT_EQ(second.motion.duration_s, 3.0) << "inherited";
  EXPECT_EQ(second.motion.max_speed, 0.3);
  EXPECT_TRUE(second.own_motion);
  EXPECT_EQ(second.own_motion_fields, std::vector<std::string>{"maxSpeed"});
  EXPECT_EQ(admitted->sequence[0].motion.cycle_rate_hz, 250.0);
  // The robot is resolved once, for every step.
  EXPECT_NE(admitted->robot, nullptr);
  // A field the step gives is named on the step; one it inherits, on the request.
  in.sequence[1].motion->max_speed = -1.0;
  admitted = planner::admit(in, catalog(), planner::Use::kStream);
  EXPECT_THAT(description_of(admitted, "sequence[1].motion.maxSpeed"), HasSubstr("> 0")) << listed(admitted);
  in.sequence[1].motion->max_speed = 0.3;
  in.motion->speed_scale = 2.0;
  admitted = planner::admit(in, catalog(), planner::Use::kStream);
  EXPECT_THAT(description_of(admitted, "motion.speedScale"), HasSubstr("(0, 1]")) << listed(admitted);
  // A step's own rate differs from the first step's: named on the field the user gave.
  in.motion->speed_scale.reset();
  in.sequence[1].motion->cycle_rate_hz = 100.0;
  admitted = planner::admit(in, catalog(), planner::Use::kStream);
  EXPECT_THAT(description_of(admitted, "sequence[1].motion.cycleRateHz"), HasSubstr("one rate, 250 Hz"));
}

TEST(Admit, ALineAfterTheFirstStepStartsWhereThePreviousEnds) {
  planner::RequestInput in;
  in.robot = named("pa10");
  in.motion = timed(2.0);
  in.optimize = planner::OptimizeInput{};
  in.optimize->tangent_scales = true;  // applies to the path step; the line takes the timing only
  in.optimize->values.tangent_scales = optim::TangentScaleOptions{};
  planner::StepInput path;
  path.geometry = path_geometry();
  path.blend_tolerance = 0.0;
  in.sequence = {path, line_step({0.5, 0.1, 0.5})};
  in.sequence_given = 2;
  const auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  ASSERT_TRUE(admitted.has_value()) << listed(admitted);
  EXPECT_FALSE(admitted->sequence[1].start_given) << "the planner sets its start";
  ASSERT_TRUE(admitted->optimize.has_value());
  EXPECT_TRUE(admitted->optimize->tangent_scales.has_value());
}

TEST(Admit, ASequenceTooLongIsRefusedBeforeItsStepsAreRead) {
  planner::RequestInput in;
  in.motion = timed(1.0);
  in.sequence_given = planner::kMaxSequenceSteps + 1;
  const auto admitted = planner::admit(in, catalog(), planner::Use::kPlan);
  EXPECT_THAT(description_of(admitted, "sequence"), HasSubstr("at most 64")) << listed(admitted);
  EXPECT_THAT(description_of(planner::admit(in, catalog(), planner::Use::kAnalyze), "sequence"),
              HasSubstr("AnalyzePath"));
}

TEST(Admit, TheKinematicsCallsNeedARobotAndAJointEach) {
  planner::ForwardInput forward;
  forward.joints = {0.0, 0.1};
  auto fk = planner::admit(forward, catalog());
  ASSERT_FALSE(fk.has_value());
  EXPECT_EQ(fk.error().front().field, "robot");
  forward.robot = named("pa10");
  fk = planner::admit(forward, catalog());
  ASSERT_FALSE(fk.has_value());
  EXPECT_EQ(fk.error().front().field, "joints");
  EXPECT_THAT(fk.error().front().description, HasSubstr("2 values for a 7-joint robot"));
  forward.joints = {0.0, 0.1, 0.0, 1.0, 0.0, 0.5, std::nan("")};
  fk = planner::admit(forward, catalog());
  ASSERT_FALSE(fk.has_value());
  EXPECT_EQ(fk.error().front().field, "joints[6]");
  forward.joints.back() = 0.0;
  fk = planner::admit(forward, catalog());
  ASSERT_TRUE(fk.has_value());
  EXPECT_EQ(fk->joints.size(), 7);

  planner::InverseInput inverse;
  inverse.robot = named("pa10");
  auto ik = planner::admit(inverse, catalog());
  ASSERT_FALSE(ik.has_value());
  EXPECT_EQ(ik.error().front().field, "target");
  inverse.target = Eigen::Isometry3d(Eigen::Translation3d(2e6, 0.0, 0.0));
  ik = planner::admit(inverse, catalog());
  ASSERT_FALSE(ik.has_value());
  EXPECT_EQ(ik.error().front().field, "target.position");
}

TEST(Admit, AJogsRobotIsResolvedAndItsBoundsCheckedAgainstIt) {
  planner::JogInput input;
  auto jog = planner::admit(input, catalog());
  ASSERT_FALSE(jog.has_value());
  EXPECT_EQ(jog.error().front().field, "start.robot");
  input.robot = named("no such arm");
  jog = planner::admit(input, catalog());
  ASSERT_FALSE(jog.has_value());
  EXPECT_EQ(jog.error().front().field, "start.robot.name");
  input.robot = named("ur5");
  input.options.velocity_scale = 0.5;
  jog = planner::admit(input, catalog());
  ASSERT_TRUE(jog.has_value()) << jog.error().front().field;
  EXPECT_EQ(jog->robot.model->name, "ur5");
  EXPECT_EQ(jog->options.velocity_scale, 0.5);
  input.options.velocity_scale = 5e-324;  // no joint could move
  jog = planner::admit(input, catalog());
  ASSERT_FALSE(jog.has_value());
  EXPECT_EQ(jog.error().front().field.rfind("start.", 0), 0u) << jog.error().front().field;
}

}  // namespace
}  // namespace geotraj::test
