// Robots through the real service: ListRobots' built-in models; PlanTrajectory's joint report
// and FAILED_PRECONDITION (with a google.rpc.PreconditionFailure) when the arm cannot follow;
// StreamSamples' joints checked against an independent Denavit-Hartenberg forward kinematics
// written here from the ListRobots answer, and against finite differences; bad robot input
// named field by field; the joint move and the straight-line move; robot model files served
// by geotrajd.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gmock/gmock.h>

#include "planner/robots.hpp"
#include "tests/server/support/daemon.hpp"
#include "tests/server/support/dh_reference.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

void set_pose(v1::Pose& out, const Eigen::Isometry3d& X) {
  const Eigen::Quaterniond q(X.linear());
  out.mutable_position()->set_x(X.translation().x());
  out.mutable_position()->set_y(X.translation().y());
  out.mutable_position()->set_z(X.translation().z());
  out.mutable_orientation()->set_w(q.w());
  out.mutable_orientation()->set_x(q.x());
  out.mutable_orientation()->set_y(q.y());
  out.mutable_orientation()->set_z(q.z());
}

class RobotTest : public ServerTest {
 protected:
  v1::ListRobotsResponse list_robots() {
    v1::ListRobotsResponse response;
    const auto status = stub_->ListRobots(context().get(), v1::ListRobotsRequest{}, &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return response;
  }

  // PlanTrajectory's and StreamSamples' field violations for a request both must refuse.
  std::vector<Violation> refused(const v1::PlanRequest& request) {
    v1::PlanResponse response;
    const auto status = plan(request, response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
    grpc::Status stream_status;
    const auto samples = stream_all(request, stream_status);
    EXPECT_TRUE(samples.empty());
    EXPECT_EQ(stream_status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << stream_status.error_message();
    EXPECT_EQ(stream_status.error_message(), status.error_message());
    return bad_request_violations(status);
  }
};

// The thesis's demonstration path A with the PA-10.
v1::PlanRequest pa10_path_a(double duration_s, bool report_only) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(duration_s);
  request.mutable_robot()->set_name("pa10");
  request.mutable_robot()->set_report_only(report_only);
  return request;
}

// ---------------------------------------------------------------------------------------
// ListRobots

TEST_F(RobotTest, ListRobotsReturnsTheBuiltInModelsInFull) {
  const auto robots = list_robots();
  std::set<std::string> names;
  for (const auto& m : robots.robots()) names.insert(m.name());
  EXPECT_EQ(names, (std::set<std::string>{"pa10", "ur5", "panda", "iiwa14", "ur5e"}));

  struct Expected {
    std::string name;
    int dof;
    v1::DhConvention convention;
  };
  for (const Expected& e : {Expected{"pa10", 7, v1::DH_CONVENTION_MODIFIED}, Expected{"ur5", 6, v1::DH_CONVENTION_STANDARD}}) {
    SCOPED_TRACE(e.name);
    const auto m = robot_model(e.name);
    EXPECT_EQ(m.dh_convention(), e.convention);
    ASSERT_EQ(m.links_size(), e.dof);
    ASSERT_EQ(m.limits_size(), e.dof);
    ASSERT_EQ(m.home_size(), e.dof);
    EXPECT_FALSE(m.description().empty());
    EXPECT_TRUE(m.has_base());
    EXPECT_TRUE(m.has_tool());
    for (int i = 0; i < e.dof; ++i) {
      const auto& l = m.links(i);
      const auto& lim = m.limits(i);
      EXPECT_EQ(l.joint_type(), v1::JOINT_TYPE_REVOLUTE) << "joint " << i;
      EXPECT_TRUE(std::isfinite(l.a()) && std::isfinite(l.alpha()) && std::isfinite(l.d()) && std::isfinite(l.theta()));
      EXPECT_LT(lim.min_position(), lim.max_position()) << "joint " << i;
      EXPECT_GT(lim.max_velocity(), 0.0) << "joint " << i;
      EXPECT_GT(lim.max_acceleration(), 0.0) << "joint " << i;
      EXPECT_GE(m.home(i), lim.min_position()) << "joint " << i;
      EXPECT_LE(m.home(i), lim.max_position()) << "joint " << i;
    }
  }
  // Joints numbered from 0 at the base, named as their makers name them.
  std::vector<std::string> pa10_names, ur5_names;
  const auto pa10_model = robot_model("pa10"), ur5_model = robot_model("ur5");
  for (const auto& l : pa10_model.links()) pa10_names.push_back(l.name());
  for (const auto& l : ur5_model.links()) ur5_names.push_back(l.name());
  EXPECT_EQ(pa10_names, (std::vector<std::string>{"S1", "S2", "S3", "E1", "E2", "W1", "W2"}));
  EXPECT_EQ(ur5_names,
            (std::vector<std::string>{"shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"}));
  // The PA-10's home puts the tool on the first key frame of the thesis's demonstration
  // paths (Table 7.8: (0.106, 0, 0.975) m), so a demo plan starts where the arm rests.
  const auto pa10 = robot_model("pa10");
  const Eigen::Vector3d p_home = forward_kinematics(pa10, pa10.home()).translation();
  EXPECT_LT((p_home - Eigen::Vector3d(0.106, 0.0, 0.975)).norm(), 1e-6) << p_home.transpose();
}

// The arms written as URDF are listed as general chains: joints by name and kind, origins,
// axes, the flange; the served pose is the one the listing describes (an independent product
// of the listed transforms), and the listing given back inline is the same arm.
TEST_F(RobotTest, ListRobotsDescribesUrdfArmsAsGeneralChains) {
  const std::pair<const char*, std::vector<std::string>> expected[] = {
      {"panda", {"panda_joint1", "panda_joint2", "panda_joint3", "panda_joint4", "panda_joint5", "panda_joint6", "panda_joint7"}},
      {"iiwa14", {"joint_a1", "joint_a2", "joint_a3", "joint_a4", "joint_a5", "joint_a6", "joint_a7"}},
      {"ur5e", {"shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"}}};
  for (const auto& [name, joint_names] : expected) {
    SCOPED_TRACE(name);
    const auto m = robot_model(name);
    EXPECT_EQ(m.links_size(), 0);
    ASSERT_EQ(m.joints_size(), static_cast<int>(joint_names.size()));
    ASSERT_EQ(m.limits_size(), m.joints_size());
    EXPECT_TRUE(m.has_flange());
    for (int i = 0; i < m.joints_size(); ++i) {
      EXPECT_EQ(m.joints(i).name(), joint_names[static_cast<std::size_t>(i)]);
      EXPECT_EQ(m.joints(i).joint_type(), v1::JOINT_TYPE_REVOLUTE);
      EXPECT_NEAR(vec(m.joints(i).axis()).norm(), 1.0, 1e-12);
    }
    // Forward kinematics served for the name, for the listing given inline, and computed here.
    std::vector<double> q(m.home().begin(), m.home().end());
    q[0] += 0.3;
    q[2] -= 0.2;
    v1::ForwardKinematicsRequest by_name, inline_model;
    by_name.mutable_robot()->set_name(name);
    *inline_model.mutable_robot()->mutable_model() = m;
    for (double x : q) {
      by_name.add_joints(x);
      inline_model.add_joints(x);
    }
    v1::ForwardKinematicsResponse a, b;
    ASSERT_TRUE(stub_->ComputeForwardKinematics(context().get(), by_name, &a).ok());
    const auto status = stub_->ComputeForwardKinematics(context().get(), inline_model, &b);
    ASSERT_TRUE(status.ok()) << status.error_message();
    const Eigen::Isometry3d X = forward_kinematics(m, q);
    EXPECT_LT((vec(a.pose().position()) - X.translation()).norm(), 1e-12);
    EXPECT_LT(quat(a.pose().orientation()).angularDistance(Eigen::Quaterniond(X.linear())), 1e-12);
    EXPECT_LT((vec(b.pose().position()) - X.translation()).norm(), 1e-12);
  }
}

// robot.urdf: the document inline, checked like any field: INVALID_ARGUMENT naming
// robot.urdf with the element and line, robot.tipLink with the leaves to choose from.
TEST_F(RobotTest, InlineUrdfIsCheckedAndNamed) {
  v1::ForwardKinematicsRequest request;
  request.mutable_robot()->set_urdf("<robot name=\"r\">\n  <link name=\"a\"/>\n  <link name=\"b\">\n</robot>");
  request.add_joints(0.0);
  v1::ForwardKinematicsResponse response;
  auto status = stub_->ComputeForwardKinematics(context().get(), request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  auto violations = bad_request_violations(status);
  EXPECT_THAT(violation_of(violations, "robot.urdf"), HasSubstr("line")) << describe(violations);

  const std::string two_leaves = R"(<robot name="forked">
  <link name="base"/><link name="left"/><link name="right"/>
  <joint name="jl" type="revolute"><parent link="base"/><child link="left"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="jr" type="revolute"><parent link="base"/><child link="right"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <geotraj><joint name="jl" max_acceleration="2"/><joint name="jr" max_acceleration="2"/></geotraj>
</robot>)";
  request.mutable_robot()->set_urdf(two_leaves);
  status = stub_->ComputeForwardKinematics(context().get(), request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  violations = bad_request_violations(status);
  EXPECT_THAT(violation_of(violations, "robot.tipLink"), HasSubstr("'left', 'right'")) << describe(violations);
  // Named, the chain is one joint about x (URDF's default axis).
  request.mutable_robot()->set_tip_link("right");
  request.set_joints(0, 0.5);
  status = stub_->ComputeForwardKinematics(context().get(), request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_NEAR(quat(response.pose().orientation()).angularDistance(
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()))), 0.0, 1e-12);
  // Base and tip links belong to a URDF only.
  v1::ForwardKinematicsRequest named;
  named.mutable_robot()->set_name("ur5");
  named.mutable_robot()->set_tip_link("tool0");
  for (int i = 0; i < 6; ++i) named.add_joints(0.0);
  status = stub_->ComputeForwardKinematics(context().get(), named, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "robot.tipLink"), HasSubstr("urdf"));
}

// ---------------------------------------------------------------------------------------
// PlanTrajectory with a robot

// Path A in the thesis's 10 s is too fast for the PA-10's accelerations: reportOnly gives the
// report, which says so.
TEST_F(RobotTest, ReportOnlyGivesTheJointReport) {
  v1::PlanResponse response;
  const auto status = plan(pa10_path_a(10.0, /*report_only=*/true), response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_TRUE(response.has_robot());
  ASSERT_TRUE(response.has_motion());
  const auto& r = response.robot();
  EXPECT_EQ(r.name(), "pa10");
  EXPECT_EQ(r.samples(), response.motion().sample_count());
  EXPECT_EQ(r.samples(), 1001u);
  // The IK converges to its tolerance at every sample (1e-9 m, 1e-9 rad).
  EXPECT_LE(r.max_ik_position_error(), 1e-9);
  EXPECT_LE(r.max_ik_orientation_error(), 1e-9);
  // On one smooth branch the midpoint deviation is O(dt^2): below the chord sagitta bound
  // kappa ds^2 / 8 <= 1e-4 m of the demo paths at 100 Hz, far below the 1 mm tolerance.
  EXPECT_LT(r.max_midpoint_deviation(), 1e-4);
  EXPECT_GT(r.min_manipulability(), 0.0);
  const auto pa10 = robot_model("pa10");
  ASSERT_EQ(r.joints_size(), 7);
  bool over = false;
  for (int j = 0; j < 7; ++j) {
    const auto& u = r.joints(j);
    EXPECT_EQ(u.joint(), static_cast<unsigned>(j));
    EXPECT_LE(u.min_position(), u.max_position());
    EXPECT_NEAR(u.velocity_usage(), u.peak_velocity() / pa10.limits(j).max_velocity(), 1e-12);
    EXPECT_NEAR(u.acceleration_usage(), u.peak_acceleration() / pa10.limits(j).max_acceleration(), 1e-12);
    over = over || u.velocity_usage() > 1.0 || u.acceleration_usage() > 1.0;
  }
  EXPECT_TRUE(over);
  EXPECT_FALSE(r.feasible());
  ASSERT_GT(r.violations_size(), 0);
  for (const auto& v : r.violations()) {
    EXPECT_LT(v.margin(), 0.0);
    EXPECT_LT(v.sample(), r.samples());
    EXPECT_NEAR(v.t(), 0.01 * static_cast<double>(v.sample()), 1e-9);
  }
  EXPECT_LT(r.tightest_acceleration().margin(), 0.0);
  // Which limit sets the pace: stretches in time order up to the end, one of them at the
  // most used limit of the whole motion.
  ASSERT_GT(r.binding_size(), 0);
  EXPECT_NEAR(r.binding(r.binding_size() - 1).t_end(), response.motion().duration_s(), 1e-12);
  double top = 0.0, top_stretch = 0.0;
  for (const auto& u : r.joints()) top = std::max({top, u.velocity_usage(), u.acceleration_usage()});
  for (int i = 0; i < r.binding_size(); ++i) {
    const auto& b = r.binding(i);
    EXPECT_TRUE(b.kind() == v1::BINDING_KIND_JOINT_VELOCITY || b.kind() == v1::BINDING_KIND_JOINT_ACCELERATION);
    EXPECT_LT(b.joint(), 7u);
    if (i > 0) {
      EXPECT_EQ(b.t_start(), r.binding(i - 1).t_end());
    }
    top_stretch = std::max(top_stretch, b.usage());
  }
  EXPECT_NEAR(top_stretch, top, 1e-12 * top);
}

TEST_F(RobotTest, WithoutReportOnlyTheBrokenLimitsAreAFailedPrecondition) {
  v1::PlanResponse report;
  ASSERT_TRUE(plan(pa10_path_a(10.0, /*report_only=*/true), report).ok());

  v1::PlanResponse response;
  const auto status = plan(pa10_path_a(10.0, /*report_only=*/false), response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("joint"));
  EXPECT_THAT(status.error_message(), HasSubstr("t ="));
  EXPECT_THAT(status.error_message(), HasSubstr("sample"));
  EXPECT_THAT(status.error_message(), HasSubstr("pa10"));

  // The details list every violation of the report, in its order.
  const auto violations = precondition_violations(status);
  ASSERT_EQ(static_cast<int>(violations.size()), report.robot().violations_size());
  for (std::size_t i = 0; i < violations.size(); ++i) {
    const auto& event = report.robot().violations(static_cast<int>(i));
    EXPECT_EQ(violations[i].type(), v1::LimitKind_Name(event.kind()));
    EXPECT_EQ(violations[i].subject(), "joint " + std::to_string(event.joint()));
    EXPECT_THAT(violations[i].description(), HasSubstr("sample " + std::to_string(event.sample())));
    EXPECT_THAT(violations[i].description(), HasSubstr("t ="));
  }

  // StreamSamples refuses the same motion before its first sample; with reportOnly it
  // streams it (broken position, velocity or acceleration limits only: for simulation).
  grpc::Status stream_status;
  auto samples = stream_all(pa10_path_a(10.0, /*report_only=*/false), stream_status);
  EXPECT_TRUE(samples.empty());
  EXPECT_EQ(stream_status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(stream_status.error_message(), status.error_message());
  EXPECT_EQ(precondition_violations(stream_status).size(), violations.size());

  samples = stream_all(pa10_path_a(10.0, /*report_only=*/true), stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), 1001u);
  for (const auto& s : samples) ASSERT_EQ(s.joints_size(), 7) << "t = " << s.t();
}

// The thesis's path C with kappa' and tau' left to the default reading takes the PA-10's
// elbow (joint 3) 0.8 mrad from its limit at t = 4.71 s, and the IK fails at the next sample: reportOnly
// lets the broken accelerations through but not the failed IK, and the refusal says so and
// names the elbow, not the acceleration at t = 3.9 s it used to lead with.
TEST_F(RobotTest, AReportOnlyRefusalNamesWhatReportOnlyCannotPassAndItsCause) {
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  for (auto& frame : *request.mutable_path()->mutable_frames()) {
    frame.clear_curvature_derivative();
    frame.clear_torsion_derivative();
  }
  ASSERT_TRUE(request.robot().report_only());
  grpc::Status status;
  EXPECT_TRUE(stream_all(request, status).empty());
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(status.error_message(), HasSubstr("even with robot.reportOnly"));
  EXPECT_THAT(status.error_message(), HasSubstr("the inverse kinematics did not converge at t = 4.72 s"));
  EXPECT_THAT(status.error_message(),
              HasSubstr("after joint 3 position 2.39029 is 0.000811 from its limit 2.3911 at t = 4.71 s"));
  // PlanTrajectory reports it all, the elbow before the failed IK.
  v1::PlanResponse response;
  ASSERT_TRUE(plan(request, response).ok());
  const auto& v = response.robot().violations();
  const auto ik = std::find_if(v.begin(), v.end(), [](const auto& e) { return e.kind() == v1::LIMIT_KIND_IK; });
  ASSERT_NE(ik, v.end());
  ASSERT_NE(ik, v.begin());
  EXPECT_EQ(std::prev(ik)->kind(), v1::LIMIT_KIND_POSITION);
  EXPECT_EQ(std::prev(ik)->joint(), 3u);
  EXPECT_EQ(std::prev(ik)->sample() + 1, ik->sample());
}

// The Panda gives jerk limits: a path with a durationS and the default trapezoid steps its
// accelerations at the start and the end, which the joint report measures as a jerk at the
// cycle rate (as live execution does, which refused such a plan that Plan called within
// every limit); the S-curve keeps them.
TEST_F(RobotTest, AJerkLimitIsCheckedWhereTheModelGivesOne) {
  auto request = example<v1::PlanRequest>("plan_panda_path_c.json");
  request.mutable_motion()->set_duration_s(8.0);
  request.mutable_motion()->set_cycle_rate_hz(4000.0);  // a step of 3.4 rad/s^2 is 13700 rad/s^3 here
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("jerk"));
  EXPECT_THAT(status.error_message(), HasSubstr("exceeds maxJerk"));
  request.mutable_robot()->set_report_only(true);
  ASSERT_TRUE(plan(request, response).ok());
  const auto& v = response.robot().violations();
  EXPECT_TRUE(std::any_of(v.begin(), v.end(), [](const auto& e) { return e.kind() == v1::LIMIT_KIND_JERK; }));
  // The binding report names it too: a joint's jerk, by differences, the most used limit
  // where the trapezoid steps (above 100 %).
  const auto& binding = response.robot().binding();
  EXPECT_TRUE(std::any_of(binding.begin(), binding.end(), [](const auto& b) {
    return b.kind() == v1::BINDING_KIND_JOINT_JERK && b.usage() > 1.0;
  }));
  request.mutable_robot()->set_report_only(false);
  request.mutable_motion()->set_profile(v1::MOTION_PROFILE_S_CURVE);
  const auto smooth = plan(request, response);
  ASSERT_TRUE(smooth.ok()) << smooth.error_message();
  EXPECT_TRUE(response.robot().feasible());
}

// The UR5 gives no jerk limits: its fastest line (maxSpeed, no acceleration or jerk limit in
// the request) used to start with a step of the tool's acceleration (joint jerk 732 rad/s^3
// by differences at 1 kHz). It is timed jerk-limited under the default bound, 20 maxAcceleration
// (a ramp of 0.05 s), which the plan names; at 1 and 4 kHz the streamed joints start and end
// at rest with zero acceleration and their jerk, by differences, stays within that bound.
TEST_F(RobotTest, AFastestMotionOnAModelWithoutJerkLimitsDoesNotStepItsAcceleration) {
  const auto ur5 = robot_model("ur5");
  for (const double rate : {1000.0, 4000.0}) {
    SCOPED_TRACE(rate);
    auto request = example<v1::PlanRequest>("linear_move_ur5.json");
    request.mutable_motion()->set_duration_s(0.0);
    request.mutable_motion()->set_max_speed(0.25);
    request.mutable_motion()->set_cycle_rate_hz(rate);
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_TRUE(response.robot().feasible());
    ASSERT_TRUE(response.robot().has_default_jerk());
    const auto& used = response.robot().default_jerk();
    EXPECT_EQ(used.ramp_s(), 0.05);
    ASSERT_EQ(used.joints_size(), 6);
    ASSERT_EQ(used.max_jerk_size(), 6);
    for (int j = 0; j < 6; ++j) {
      EXPECT_EQ(used.joints(j), static_cast<unsigned>(j));
      EXPECT_DOUBLE_EQ(used.max_jerk(j), ur5.limits(j).max_acceleration() / 0.05);
    }
    EXPECT_THAT(used.message(), HasSubstr("the ur5 model gives no maxJerk for joints 0 (shoulder_pan), 1 (shoulder_lift)"));
    EXPECT_THAT(used.message(), HasSubstr("maxAcceleration / 0.05 s"));

    grpc::Status stream_status;
    const auto samples = stream_all(request, stream_status);
    ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
    ASSERT_EQ(samples.size(), response.motion().sample_count());
    ASSERT_GT(samples.size(), 10u);
    for (int j = 0; j < 6; ++j) {
      EXPECT_EQ(samples.front().joint_accelerations(j), 0.0) << "joint " << j;
      EXPECT_NEAR(samples.back().joint_accelerations(j), 0.0, 1e-9) << "joint " << j;
      EXPECT_NEAR(samples.back().joint_velocities(j), 0.0, 1e-9) << "joint " << j;
    }
    double worst = 0.0;  // jerk by differences / the default bound
    for (std::size_t k = 1; k < samples.size(); ++k) {
      for (int j = 0; j < 6; ++j) {
        const double jerk =
            std::abs(samples[k].joint_accelerations(j) - samples[k - 1].joint_accelerations(j)) * rate;
        worst = std::max(worst, jerk / used.max_jerk(j));
      }
    }
    EXPECT_LE(worst, 1.0 + 1e-6);
    EXPECT_GT(worst, 0.5) << "the jerk bound shapes the ramps";
  }
}

// A path that its maxSpeed paces: the binding report names the Cartesian speed at 100 % on
// the path (it listed joint limits at 3-8 %), and each step has its own summary (the
// approach's peak speed was reported as the request's, whose maxSpeed is 0.05).
TEST_F(RobotTest, TheBindingReportNamesTheCartesianLimitThatSetsThePace) {
  auto request = example<v1::PlanRequest>("plan_panda_path_c.json");
  request.mutable_motion()->set_max_speed(0.05);
  request.mutable_motion()->set_cycle_rate_hz(250.0);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(response.steps_size(), 2);  // the joint approach, then the path
  const auto& approach = response.steps(0).motion();
  const auto& path = response.steps(1).motion();
  EXPECT_EQ(path.duration_s(), response.steps(1).duration_s());
  EXPECT_NEAR(path.peak_speed(), 0.05, 0.05 * 1e-3);
  EXPECT_LE(path.peak_speed(), 0.05 * (1.0 + 1e-9));
  EXPECT_GT(approach.peak_speed(), 0.05) << "the joint approach is not bound by the path's maxSpeed";
  EXPECT_EQ(response.motion().peak_speed(), std::max(approach.peak_speed(), path.peak_speed()));
  EXPECT_GT(path.duration_s(), 20.0);

  // The path's stretches: the Cartesian speed binds, at 100 %, for most of its time.
  const double path_start = response.steps(1).start_time_s();
  double at_speed = 0.0;
  for (const auto& b : response.robot().binding()) {
    if (b.t_start() < path_start - 1e-9) {
      EXPECT_NE(b.kind(), v1::BINDING_KIND_CARTESIAN_SPEED) << "the approach has no Cartesian limit";
      continue;
    }
    if (b.kind() == v1::BINDING_KIND_CARTESIAN_SPEED) {
      EXPECT_NEAR(b.usage(), 1.0, 1e-5);  // the timing keeps 1e-6 of margin
      EXPECT_EQ(b.limit(), 0.05);
      at_speed += b.t_end() - b.t_start();
    }
  }
  EXPECT_GT(at_speed, 0.8 * path.duration_s());
  // The usage is the samples' own: the tool speed by differences of the streamed positions.
  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  double fastest = 0.0;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    if (samples[k].step() != 1 || samples[k - 1].step() != 1) continue;
    const auto& a = samples[k - 1].position();
    const auto& b = samples[k].position();
    fastest = std::max(fastest, std::hypot(b.x() - a.x(), b.y() - a.y(), b.z() - a.z()) * 250.0);
  }
  EXPECT_NEAR(fastest, 0.05, 0.05 * 1e-3);
}

// With a durationS the request chooses the profile: no default is used, and the plan says none.
TEST_F(RobotTest, AMotionOfAGivenDurationUsesNoDefaultJerk) {
  auto request = example<v1::PlanRequest>("linear_move_ur5.json");
  v1::PlanResponse response;
  ASSERT_TRUE(plan(request, response).ok());
  EXPECT_FALSE(response.robot().has_default_jerk());
}

// ---------------------------------------------------------------------------------------
// StreamSamples with a robot

// Path A over 60 s is within every limit of the PA-10 (accelerations scale with 1 / T^2: the
// 10 s plan's worst usage, 2.36, becomes 0.07).
// FIXED orientation on a straight start (no normal at frame 0): the tool keeps the
// orientation the PA-10 holds at its home (the IK seed), so the first sample is the robot's
// pose and the joints stay near home; before, the plan was refused for want of a normal.
TEST_F(RobotTest, FixedStraightStartKeepsTheRobotsToolOrientation) {
  const auto pa10 = robot_model("pa10");
  const Eigen::Isometry3d X_home = forward_kinematics(pa10, pa10.home());
  const Eigen::Vector3d p0 = X_home.translation();
  auto request = from_json<v1::PlanRequest>(R"({"path": {"frames": [
      {"tangent": {"y": 1}}, {"tangent": {"y": 1}}]},
      "motion": {"durationS": 3}, "robot": {"name": "pa10"}})");
  auto* frames = request.mutable_path()->mutable_frames();
  for (int k = 0; k < 2; ++k) {
    auto* p = frames->Mutable(k)->mutable_position();
    p->set_x(p0.x());
    p->set_y(p0.y() + 0.1 * k);
    p->set_z(p0.z());
  }
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_FALSE(samples.empty());
  const Eigen::Quaterniond q_home(X_home.linear());
  for (const auto& s : samples) {
    EXPECT_LT(quat(s.orientation()).angularDistance(q_home), 1e-9);
    EXPECT_LT(Eigen::Quaterniond(forward_kinematics(pa10, s.joints()).linear()).angularDistance(q_home), 1e-8);
  }
  for (int j = 0; j < 7; ++j) EXPECT_NEAR(samples.front().joints(j), pa10.home(j), 1e-6) << "joint " << j;
}

TEST_F(RobotTest, SlowDemoStreamsJointsThatReproduceTheTool) {
  const auto request = pa10_path_a(60.0, /*report_only=*/false);
  v1::PlanResponse response;
  const auto plan_status = plan(request, response);
  ASSERT_TRUE(plan_status.ok()) << plan_status.error_message();
  ASSERT_TRUE(response.robot().feasible());
  EXPECT_LE(response.robot().max_ik_position_error(), 1e-9);

  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(samples.size(), response.motion().sample_count());
  ASSERT_EQ(samples.size(), 6001u);

  const auto pa10 = robot_model("pa10");
  const double dt = 0.01;  // 100 Hz
  double worst_position = 0.0, worst_angle = 0.0, worst_fd = 0.0, peak_qd = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const auto& s = samples[k];
    ASSERT_EQ(s.joints_size(), 7) << "sample " << k;
    ASSERT_EQ(s.joint_velocities_size(), 7) << "sample " << k;
    ASSERT_EQ(s.joint_accelerations_size(), 7) << "sample " << k;
    // Forward kinematics of the streamed joints is the streamed tool pose: the IK's
    // residuals (<= 1e-9 m, 1e-9 rad) plus rounding.
    const Eigen::Isometry3d X_WT = forward_kinematics(pa10, s.joints());
    worst_position = std::max(worst_position, (X_WT.translation() - vec(s.position())).norm());
    worst_angle = std::max(worst_angle, Eigen::Quaterniond(X_WT.linear()).angularDistance(quat(s.orientation())));
    for (int j = 0; j < 7; ++j) peak_qd = std::max(peak_qd, std::abs(s.joint_velocities(j)));
    if (k == 0 || k + 1 == samples.size()) continue;
    // Central differences of the joint positions against the streamed joint velocities.
    // Their error is (h/4) osc(q_ddot) over [t - h, t + h] (integral form of Taylor's
    // remainder): h^2/6 |q'''| where q_ddot is smooth, and (h/4) times the jump where the
    // trapezoid's acceleration switches between two samples. The oscillation of the three
    // sampled accelerations estimates it; a factor 1.5 covers what happens between samples,
    // and 1e-6 rad/s covers the IK's 1e-9 residuals over 2h = 0.02 s.
    const auto& prev = samples[k - 1];
    const auto& next = samples[k + 1];
    for (int j = 0; j < 7; ++j) {
      const double fd = (next.joints(j) - prev.joints(j)) / (next.t() - prev.t());
      const double a[3] = {prev.joint_accelerations(j), s.joint_accelerations(j), next.joint_accelerations(j)};
      const double osc = *std::max_element(a, a + 3) - *std::min_element(a, a + 3);
      const double error = std::abs(fd - s.joint_velocities(j));
      EXPECT_LE(error, 1.5 * dt / 4.0 * osc + 1e-6) << "joint " << j << " at t = " << s.t();
      worst_fd = std::max(worst_fd, error);
    }
  }
  EXPECT_LT(worst_position, 1e-8);
  EXPECT_LT(worst_angle, 1e-8);
  // As a relative figure: the trapezoid's acceleration steps (at most about the peak joint
  // acceleration, 0.13 rad/s^2 here) bound it by (h/4) 0.13 / 0.10 rad/s = 3e-3.
  EXPECT_LT(worst_fd / peak_qd, 3e-3) << "worst " << worst_fd << " rad/s of a peak " << peak_qd << " rad/s";
  // Starts at home (the IK seed), at rest.
  for (int j = 0; j < 7; ++j) {
    EXPECT_NEAR(samples.front().joints(j), pa10.home(j), 1e-6) << "joint " << j;
    EXPECT_EQ(samples.front().joint_velocities(j), 0.0) << "joint " << j;
    EXPECT_NEAR(samples.back().joint_velocities(j), 0.0, 1e-12) << "joint " << j;
  }
}

// The thesis's demonstration under the default reading on the PA-10, as fast as its limits
// allow (durationS 0): every path streams, starts at home and keeps every joint limit, as
// streamed and as measured on the stream by differences of the joint positions (first
// differences for the velocity, second for the acceleration: both see what happens between
// samples, where the timing's limits are met at its grid points: measured up to 0.008 % over).
TEST_F(RobotTest, FastestDemonstrationStreamsWithinTheLimitsUnderTheDefaultReading) {
  const auto pa10 = robot_model("pa10");
  for (char which : {'a', 'b', 'c'}) {
    SCOPED_TRACE(std::string("path ") + which);
    auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
    *request.mutable_path() = demo_example(which).path();
    ASSERT_EQ(request.path().unspecified(), v1::UNSPECIFIED_CONSTRAINTS_UNSPECIFIED) << "the default reading";
    request.mutable_motion()->set_duration_s(0.0);
    v1::PlanResponse response;
    const auto plan_status = plan(request, response);
    ASSERT_TRUE(plan_status.ok()) << plan_status.error_message();
    ASSERT_TRUE(response.robot().feasible());
    EXPECT_LT(response.motion().duration_s(), 6.0) << "faster than the thesis's 10 s";
    grpc::Status status;
    const auto samples = stream_all(request, status);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(samples.size(), response.motion().sample_count());
    double worst_v = 0.0, worst_a = 0.0, worst_fd_v = 0.0, worst_fd_a = 0.0;
    for (std::size_t k = 0; k < samples.size(); ++k) {
      const auto& smp = samples[k];
      ASSERT_EQ(smp.joints_size(), 7);
      for (int j = 0; j < 7; ++j) {
        const auto& lim = pa10.limits(j);
        EXPECT_GE(smp.joints(j), lim.min_position());
        EXPECT_LE(smp.joints(j), lim.max_position());
        worst_v = std::max(worst_v, std::abs(smp.joint_velocities(j)) / lim.max_velocity());
        worst_a = std::max(worst_a, std::abs(smp.joint_accelerations(j)) / lim.max_acceleration());
        if (k == 0) continue;
        const auto& prev = samples[k - 1];
        const double dt = smp.t() - prev.t();
        worst_fd_v = std::max(worst_fd_v, std::abs(smp.joints(j) - prev.joints(j)) / dt / lim.max_velocity());
        if (k + 1 == samples.size()) continue;
        const auto& next = samples[k + 1];
        const double h = 0.5 * (next.t() - prev.t());
        const double second = ((next.joints(j) - smp.joints(j)) / (next.t() - smp.t()) -
                               (smp.joints(j) - prev.joints(j)) / (smp.t() - prev.t())) / h;
        worst_fd_a = std::max(worst_fd_a, std::abs(second) / lim.max_acceleration());
      }
    }
    std::printf("[ measured ] path %c: %.3f s; usage streamed v %.6f a %.6f, by differences v %.6f a %.6f\n", which,
                response.motion().duration_s(), worst_v, worst_a, worst_fd_v, worst_fd_a);
    EXPECT_LE(worst_v, 1.0 + 1e-6);
    EXPECT_LE(worst_a, 1.0 + 1e-6);
    EXPECT_LE(worst_fd_v, 1.0 + 1e-3);
    EXPECT_LE(worst_fd_a, 1.0 + 1e-2);
    EXPECT_GT(worst_v, 0.99) << "time-optimal: some joint at its velocity limit";
    for (int j = 0; j < 7; ++j) EXPECT_NEAR(samples.front().joints(j), pa10.home(j), 1e-6) << "joint " << j;
  }
}

// Override factors on the joint limits (robot.velocityScale, robot.accelerationScale): the
// fastest motion along path C then uses at most those fractions of the model's limits, and
// reaches them.
TEST_F(RobotTest, LimitOverridesScaleTheJointLimits) {
  const auto pa10 = robot_model("pa10");
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  request.mutable_motion()->set_duration_s(0.0);
  v1::PlanResponse full;
  ASSERT_TRUE(plan(request, full).ok());
  request.mutable_robot()->set_velocity_scale(0.5);
  request.mutable_robot()->set_acceleration_scale(0.25);
  v1::PlanResponse scaled;
  const auto plan_status = plan(request, scaled);
  ASSERT_TRUE(plan_status.ok()) << plan_status.error_message();
  EXPECT_GT(scaled.motion().duration_s(), 1.5 * full.motion().duration_s());
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  double worst_v = 0.0, worst_a = 0.0;
  for (const auto& smp : samples)
    for (int j = 0; j < 7; ++j) {
      worst_v = std::max(worst_v, std::abs(smp.joint_velocities(j)) / pa10.limits(j).max_velocity());
      worst_a = std::max(worst_a, std::abs(smp.joint_accelerations(j)) / pa10.limits(j).max_acceleration());
    }
  std::printf("[ measured ] scaled 0.5 / 0.25: %.3f s against %.3f s; velocity %.6f, acceleration %.6f of the model's\n",
              scaled.motion().duration_s(), full.motion().duration_s(), worst_v, worst_a);
  EXPECT_LE(worst_v, 0.5 * (1 + 1e-9));
  EXPECT_LE(worst_a, 0.25 * (1 + 1e-9));
  EXPECT_GT(std::max(worst_v / 0.5, worst_a / 0.25), 0.99) << "a scaled limit binds";
  // The report's limits are the scaled ones.
  const auto& tightest = scaled.robot().tightest_velocity();
  EXPECT_NEAR(tightest.limit(), 0.5 * pa10.limits(static_cast<int>(tightest.joint())).max_velocity(), 1e-12);

  for (const double bad : {0.0, 1.5, -1.0, std::nan("")}) {
    auto wrong = request;
    wrong.mutable_robot()->set_velocity_scale(bad);
    wrong.mutable_robot()->set_acceleration_scale(bad);
    v1::PlanResponse response;
    const auto refused = plan(wrong, response);
    ASSERT_EQ(refused.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad;
    const auto violations = bad_request_violations(refused);
    EXPECT_NE(violation_of(violations, "robot.velocityScale"), "") << bad;
    EXPECT_NE(violation_of(violations, "robot.accelerationScale"), "") << bad;
  }
}

// A limit broken on purpose: an inline copy of the PA-10 whose joint 2 may barely move.
TEST_F(RobotTest, ABrokenLimitNamesItsJoint) {
  auto slow = robot_model("pa10");
  slow.set_name("pa10-slow-joint-2");
  slow.mutable_limits(2)->set_max_velocity(1e-3);  // [rad/s]; path A over 60 s needs 0.10
  auto request = pa10_path_a(60.0, /*report_only=*/false);
  *request.mutable_robot()->mutable_model() = slow;

  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("pa10-slow-joint-2"));
  EXPECT_THAT(status.error_message(), HasSubstr("joint 2 speed"));
  EXPECT_THAT(status.error_message(), HasSubstr("maxVelocity 0.001"));
  const auto violations = precondition_violations(status);
  ASSERT_EQ(violations.size(), 1u);
  EXPECT_EQ(violations[0].type(), "LIMIT_KIND_VELOCITY");
  EXPECT_EQ(violations[0].subject(), "joint 2");

  grpc::Status stream_status;
  EXPECT_TRUE(stream_all(request, stream_status).empty());
  EXPECT_EQ(stream_status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(stream_status.error_message(), HasSubstr("joint 2"));

  request.mutable_robot()->set_report_only(true);
  ASSERT_TRUE(plan(request, response).ok());
  ASSERT_EQ(response.robot().violations_size(), 1);
  const auto& v = response.robot().violations(0);
  EXPECT_EQ(v.kind(), v1::LIMIT_KIND_VELOCITY);
  EXPECT_EQ(v.joint(), 2u);
  EXPECT_EQ(v.limit(), 1e-3);
  EXPECT_GT(v.value(), 1e-3);
  EXPECT_NEAR(v.margin(), v.limit() - v.value(), 1e-15);
  EXPECT_EQ(response.robot().name(), "pa10-slow-joint-2");
}

// ---------------------------------------------------------------------------------------
// Bad robot input: INVALID_ARGUMENT naming the field

TEST_F(RobotTest, UnknownRobotNameListsTheKnownOnes) {
  auto request = pa10_path_a(60.0, false);
  request.mutable_robot()->set_name("pa11");
  const auto violations = refused(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "robot.name");
  EXPECT_THAT(violations[0].description, HasSubstr("pa11"));
  EXPECT_THAT(violations[0].description, HasSubstr("pa10"));
  EXPECT_THAT(violations[0].description, HasSubstr("ur5"));
}

TEST_F(RobotTest, InitialJointsOfTheWrongSize) {
  auto request = pa10_path_a(60.0, false);
  for (double q : {0.0, 0.1, 0.2}) request.mutable_robot()->add_initial_joints(q);
  const auto violations = refused(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "robot.initialJoints");
  EXPECT_THAT(violations[0].description, HasSubstr("3 values"));
  EXPECT_THAT(violations[0].description, HasSubstr("7-joint"));
}

TEST_F(RobotTest, InlineModelWithANaNLink) {
  auto request = pa10_path_a(60.0, false);
  auto m = robot_model("pa10");
  m.mutable_links(1)->set_a(std::numeric_limits<double>::quiet_NaN());
  *request.mutable_robot()->mutable_model() = m;
  const auto violations = refused(request);
  EXPECT_THAT(violation_of(violations, "robot.model.links[1].a"), HasSubstr("finite")) << describe(violations);
}

TEST_F(RobotTest, InlineModelWithTooLongAJointName) {
  auto request = pa10_path_a(60.0, false);
  auto m = robot_model("pa10");
  m.mutable_links(2)->set_name(std::string(65, 'x'));
  *request.mutable_robot()->mutable_model() = m;
  const auto violations = refused(request);
  EXPECT_THAT(violation_of(violations, "robot.model.links[2].name"), HasSubstr("65 bytes; at most 64"))
      << describe(violations);
}

TEST_F(RobotTest, InlineModelWithMinPositionAboveMaxPosition) {
  auto request = pa10_path_a(60.0, false);
  auto m = robot_model("pa10");
  m.mutable_limits(3)->set_min_position(1.0);
  m.mutable_limits(3)->set_max_position(-1.0);
  *request.mutable_robot()->mutable_model() = m;
  const auto violations = refused(request);
  EXPECT_NE(violation_of(violations, "robot.model.limits[3].minPosition"), "") << describe(violations);
}

// A path 14 cm from the PA-10's home (its tool pose at the initial joints) is refused: the
// robot would jump to it at the first sample. FAILED_PRECONDITION names the distance; the
// same path from initialJoints at its start plans.
TEST_F(RobotTest, APathMustStartWhereTheRobotIs) {
  auto request = pa10_path_a(60.0, false);
  for (auto& frame : *request.mutable_path()->mutable_frames()) {
    frame.mutable_position()->set_y(frame.position().y() + 0.14);
  }
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  const auto violations = precondition_violations(status);
  ASSERT_EQ(violations.size(), 1u);
  EXPECT_EQ(violations[0].subject(), "robot.initialJoints");
  EXPECT_THAT(violations[0].description(), HasSubstr("the path starts 0.14 m and "));
  grpc::Status stream_status;
  EXPECT_TRUE(stream_all(request, stream_status).empty());
  EXPECT_EQ(stream_status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);

  // The joints of the path's start (the IK nearest the home), given as initialJoints.
  const auto pa10 = robot_model("pa10");
  v1::InverseKinematicsRequest ik;
  ik.mutable_robot()->set_name("pa10");
  Eigen::Isometry3d start = forward_kinematics(pa10, pa10.home());
  start.translation().y() += 0.14;
  set_pose(*ik.mutable_target(), start);
  v1::InverseKinematicsResponse at_start;
  ASSERT_TRUE(stub_->ComputeInverseKinematics(context().get(), ik, &at_start).ok());
  ASSERT_TRUE(at_start.reachable());
  *request.mutable_robot()->mutable_initial_joints() = at_start.solutions(0).joints();
  const auto planned = plan(request, response);
  EXPECT_TRUE(planned.ok()) << planned.error_message();
}

// The same path 14 cm away with robot.approach: a minimum-time approach move first (joint or
// straight), then the path; the plan is a sequence of the two, the robot at rest between
// them, streamed continuously from the home, every joint within its limits.
TEST_F(RobotTest, AnApproachMoveBringsTheRobotToThePathsStart) {
  auto request = pa10_path_a(60.0, false);
  for (auto& frame : *request.mutable_path()->mutable_frames()) {
    frame.mutable_position()->set_y(frame.position().y() + 0.14);
  }
  const auto pa10 = robot_model("pa10");
  for (const auto approach : {v1::APPROACH_MOVE_JOINT, v1::APPROACH_MOVE_LINEAR}) {
    SCOPED_TRACE(v1::ApproachMove_Name(approach));
    request.mutable_robot()->set_approach(approach);
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(response.steps_size(), 2);
    EXPECT_EQ(response.steps(0).kind(), approach == v1::APPROACH_MOVE_JOINT ? "jointMove" : "linearMove");
    EXPECT_EQ(response.steps(1).kind(), "path");
    EXPECT_LT(response.steps(1).closed_loop().max_error(), 1e-6);
    EXPECT_TRUE(response.robot().feasible());
    grpc::Status stream_status;
    const auto samples = stream_all(request, stream_status);
    ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
    ASSERT_EQ(samples.size(), response.motion().sample_count());
    for (int j = 0; j < 7; ++j) EXPECT_NEAR(samples.front().joints(j), pa10.home(j), 1e-9);
    const auto& at_path = samples[response.steps(1).first_sample()];
    EXPECT_NEAR(at_path.position().y(), request.path().frames(0).position().y(), 1e-9);
    EXPECT_LT(vec(at_path.velocity()).norm(), 1e-12) << "at rest where the path starts";
    const double dt = 1.0 / request.motion().cycle_rate_hz();
    for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
      for (int j = 0; j < 7; ++j) {
        const double v = (samples[k].joints(j) - samples[k - 1].joints(j)) / (samples[k].t() - samples[k - 1].t());
        ASSERT_LE(std::abs(v), pa10.limits(j).max_velocity() * (1 + 1e-6)) << "sample " << k << " joint " << j;
        if (std::abs(samples[k + 1].t() - samples[k].t() - dt) < 1e-9 && std::abs(samples[k].t() - samples[k - 1].t() - dt) < 1e-9) {
          const double a = (samples[k + 1].joints(j) - 2 * samples[k].joints(j) + samples[k - 1].joints(j)) / (dt * dt);
          ASSERT_LE(std::abs(a), pa10.limits(j).max_acceleration() * 1.02) << "sample " << k << " joint " << j;
        }
      }
    }
  }
  // Already at the start: no approach, the path alone.
  auto at_home = pa10_path_a(60.0, false);
  at_home.mutable_robot()->set_approach(v1::APPROACH_MOVE_JOINT);
  v1::PlanResponse response;
  ASSERT_TRUE(plan(at_home, response).ok());
  EXPECT_EQ(response.steps_size(), 0);
  EXPECT_GT(response.segments_size(), 0);
  // An unknown value is named.
  at_home.mutable_robot()->set_approach(static_cast<v1::ApproachMove>(7));
  EXPECT_THAT(violation_of(refused(at_home), "robot.approach"), HasSubstr("unknown value 7"));
}

// The joint approach ends where the joints have room: among the IK solutions of the path's
// start, the one with the largest margin to the joint limits. For this seam the solution
// nearest the Panda's home has panda_joint2 2.7e-6 rad from its limit (the path then held it
// there and broke the acceleration limits); the plan says which solution it took and why.
TEST_F(RobotTest, TheJointApproachEndsWithTheLargestMarginToTheJointLimits) {
  const auto request = from_json<v1::PlanRequest>(R"({
    "path": {"frames": [
      {"position": {"x": 0.45, "y": -0.12, "z": 0.25}, "tangent": {"y": 1}, "normal": {"x": 1},
       "orientationMode": "ORIENTATION_MODE_CUSTOM", "orientation": {"w": 0, "x": 1}, "easeOrientation": true},
      {"position": {"x": 0.45, "y": 0.12, "z": 0.25}, "tangent": {"y": 1}, "normal": {"x": 1}}]},
    "motion": {"durationS": 0, "cycleRateHz": 250, "maxSpeed": 0.05},
    "robot": {"name": "panda", "approach": "APPROACH_MOVE_JOINT"}})");
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(response.steps_size(), 2);
  EXPECT_TRUE(response.robot().feasible());
  EXPECT_THAT(response.steps(0).goal_choice(), HasSubstr("the largest margin to the joint limits"));
  EXPECT_THAT(response.steps(0).goal_choice(), HasSubstr("the nearest the start has 2.7"));
  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  const auto panda = robot_model("panda");
  const auto& at_path = samples[response.steps(1).first_sample()];
  double margin = 1e9;
  for (int j = 0; j < panda.limits_size(); ++j) {
    margin = std::min({margin, at_path.joints(j) - panda.limits(j).min_position(),
                       panda.limits(j).max_position() - at_path.joints(j)});
  }
  EXPECT_GT(margin, 0.5) << "rad, at the path's start";
}

TEST_F(RobotTest, JointMoveNeedsARobot) {
  auto request = from_json<v1::PlanRequest>(
      R"({"jointMove": {"goal": [0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8]}, "motion": {"durationS": 3}})");
  const auto violations = refused(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "robot");
  EXPECT_THAT(violations[0].description, HasSubstr("jointMove"));
}

TEST_F(RobotTest, JointMoveGoalOutsideTheLimits) {
  auto request = from_json<v1::PlanRequest>(
      R"({"jointMove": {"goal": [0.6, 2.0, -0.3, 1.5, 0.4, 0.6, -5.0]}, "robot": {"name": "pa10"},
          "motion": {"durationS": 3}})");
  const auto violations = refused(request);
  ASSERT_EQ(violations.size(), 2u) << describe(violations);
  EXPECT_THAT(violation_of(violations, "jointMove.goal[1]"), HasSubstr("limits")) << describe(violations);
  EXPECT_THAT(violation_of(violations, "jointMove.goal[6]"), HasSubstr("limits")) << describe(violations);
}

TEST_F(RobotTest, LinearMoveWithoutStartNeedsARobot) {
  auto request = from_json<v1::PlanRequest>(
      R"({"linearMove": {"goal": {"position": {"x": 0.4, "y": 0.1, "z": 0.5}}}, "motion": {"durationS": 2}})");
  const auto violations = refused(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "linearMove.start");
  EXPECT_THAT(violations[0].description, HasSubstr("robot"));
}

// ---------------------------------------------------------------------------------------
// The basic moves (thesis 6.2.2)

// A minimum-time joint move of the PA-10 (durationS 0) from its home (start absent).
v1::PlanRequest minimum_time_joint_move() {
  return from_json<v1::PlanRequest>(R"({"jointMove": {"goal": [0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8]},
      "robot": {"name": "pa10"}, "motion": {"durationS": 0, "cycleRateHz": 500}})");
}

// A minimum-time joint move: the slowest joint moves at one of its limits, the others are
// scaled to finish with it; the stream starts at home and ends on the goal exactly.
TEST_F(RobotTest, MinimumTimeJointMoveOnThePa10) {
  auto request = minimum_time_joint_move();
  // A joint move does not use the Cartesian maxSpeed and maxAcceleration (moves.hpp): given
  // with values that would bind a path, they change nothing.
  request.mutable_motion()->set_max_speed(0.01);
  request.mutable_motion()->set_max_acceleration(0.01);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const auto& r = response.robot();
  EXPECT_TRUE(r.feasible());
  ASSERT_EQ(r.joints_size(), 7);
  double usage = 0.0;
  for (const auto& j : r.joints()) {
    EXPECT_LE(j.velocity_usage(), 1.0 + 1e-9) << "joint " << j.joint();
    EXPECT_LE(j.acceleration_usage(), 1.0 + 1e-9) << "joint " << j.joint();
    usage = std::max({usage, j.velocity_usage(), j.acceleration_usage()});
  }
  EXPECT_GT(usage, 0.999);
  EXPECT_GT(response.motion().duration_s(), 0.0);
  EXPECT_GT(response.motion().peak_speed(), 0.01);  // the Cartesian maxSpeed is not applied

  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), response.motion().sample_count());
  EXPECT_DOUBLE_EQ(samples.back().t(), response.motion().duration_s());
  const auto pa10 = robot_model("pa10");
  for (int j = 0; j < 7; ++j) {
    EXPECT_EQ(samples.front().joints(j), pa10.home(j)) << "joint " << j;  // start absent: the home
    EXPECT_EQ(samples.back().joints(j), request.joint_move().goal(j)) << "joint " << j;
    EXPECT_EQ(samples.front().joint_velocities(j), 0.0);
    EXPECT_EQ(samples.back().joint_velocities(j), 0.0);
  }
  // The tool follows the joints.
  for (const auto& s : samples) {
    EXPECT_LT((forward_kinematics(pa10, s.joints()).translation() - vec(s.position())).norm(), 1e-12);
  }
}

// A minimum-time joint move needs no Cartesian limits: its time comes from the joints'.
TEST_F(RobotTest, MinimumTimeJointMoveNeedsNoCartesianLimits) {
  const auto request = minimum_time_joint_move();
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_TRUE(response.robot().feasible());
  grpc::Status stream_status;
  EXPECT_EQ(stream_all(request, stream_status).size(), response.motion().sample_count());
  EXPECT_TRUE(stream_status.ok()) << stream_status.error_message();
}

// Appendix C's joint move to a pose: the UR5 from its home to the pose of other joints, in
// minimum time. The goal's joints are the IK solution nearest the start: no other branch of
// the pose (ComputeInverseKinematics, allSolutions) is nearer the home; the stream ends on
// the pose, the joints at rest.
TEST_F(RobotTest, JointMoveToAPoseEndsOnItsNearestBranch) {
  const auto ur5 = robot_model("ur5");
  const Eigen::Isometry3d goal = forward_kinematics(ur5, std::vector<double>{0.9, -1.0, 1.2, -1.5, -1.3, 0.4});
  v1::PlanRequest request;
  set_pose(*request.mutable_joint_move()->mutable_goal_pose(), goal);
  request.mutable_robot()->set_name("ur5");
  request.mutable_motion()->set_duration_s(0.0);
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_GE(samples.size(), 2u);
  const auto& last = samples.back();
  const Eigen::Isometry3d reached = forward_kinematics(ur5, last.joints());
  EXPECT_LT((reached.translation() - goal.translation()).norm(), 1e-9);
  EXPECT_LT(Eigen::AngleAxisd(reached.linear() * goal.linear().transpose()).angle(), 1e-9);
  for (double qd : last.joint_velocities()) EXPECT_EQ(qd, 0.0);
  double travelled = 0.0;
  for (int j = 0; j < 6; ++j) travelled += std::pow(last.joints(j) - ur5.home(j), 2);

  v1::InverseKinematicsRequest ik;
  ik.mutable_robot()->set_name("ur5");
  set_pose(*ik.mutable_target(), goal);
  ik.set_all_solutions(true);
  ik.set_restarts(1999);
  v1::InverseKinematicsResponse branches;
  ASSERT_TRUE(stub_->ComputeInverseKinematics(context().get(), ik, &branches).ok());
  ASSERT_GE(branches.solutions_size(), 2);
  for (const auto& b : branches.solutions()) {
    EXPECT_GE(b.distance_from_seed(), std::sqrt(travelled) - 1e-6) << "a nearer branch was not taken";
  }
}

TEST_F(RobotTest, JointMoveToAPoseOutOfReachIsAFailedPrecondition) {
  auto request = from_json<v1::PlanRequest>(R"({"jointMove": {"goalPose": {"position": {"x": 2.5}}},
      "robot": {"name": "pa10"}, "motion": {"durationS": 2}})");
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  const auto violations = precondition_violations(status);
  ASSERT_EQ(violations.size(), 1u);
  EXPECT_EQ(violations[0].subject(), "jointMove.goalPose");
  EXPECT_THAT(violations[0].description(), HasSubstr("out of the robot's reach: the closest pose it reaches is"));
}

// Appendix C's straight-line move to joints: the UR5's tool on the line from its home pose
// to the pose of the goal joints, ending at those joints (on the home's branch).
TEST_F(RobotTest, LinearMoveToJointsEndsAtThem) {
  const auto ur5 = robot_model("ur5");
  std::vector<double> goal(ur5.home().begin(), ur5.home().end());
  goal[0] += 0.3;
  goal[2] -= 0.2;
  goal[4] += 0.25;
  v1::PlanRequest request;
  for (double q : goal) request.mutable_linear_move()->add_goal_joints(q);
  request.mutable_robot()->set_name("ur5");
  request.mutable_motion()->set_duration_s(2.0);
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(samples.back().joints(j), goal[static_cast<std::size_t>(j)], 1e-6);
  // The tool on the segment from the home pose to the goal's.
  const Eigen::Vector3d p0 = forward_kinematics(ur5, ur5.home()).translation();
  const Eigen::Vector3d p1 = forward_kinematics(ur5, goal).translation();
  const Eigen::Vector3d d = (p1 - p0).normalized();
  for (const auto& s : samples) {
    const Eigen::Vector3d p = vec(s.position());
    EXPECT_LT(((p - p0) - (p - p0).dot(d) * d).norm(), 1e-12);
  }
}

TEST_F(RobotTest, LinearMoveGoalsAreOneOrTheOther) {
  auto request = from_json<v1::PlanRequest>(R"({"linearMove": {"goal": {"position": {"x": 0.4}},
      "goalJoints": [0, 0, 0, 0, 0, 0]}, "robot": {"name": "ur5"}, "motion": {"durationS": 2}})");
  auto violations = refused(request);
  EXPECT_THAT(violation_of(violations, "linearMove.goal"), HasSubstr("not both")) << describe(violations);
  request = from_json<v1::PlanRequest>(R"({"linearMove": {"goalJoints": [0, 0, 0]}, "robot": {"name": "ur5"},
      "motion": {"durationS": 2}})");
  violations = refused(request);
  EXPECT_THAT(violation_of(violations, "linearMove.goalJoints"), HasSubstr("3 values for a 6-joint robot"))
      << describe(violations);
  request = from_json<v1::PlanRequest>(R"({"jointMove": {"goal": [0, 0, 0, 0, 0, 0], "goalPose": {}},
      "robot": {"name": "ur5"}, "motion": {"durationS": 2}})");
  violations = refused(request);
  EXPECT_THAT(violation_of(violations, "jointMove.goal"), HasSubstr("not both")) << describe(violations);
}

// A straight line from the UR5's home pose (start absent), 10 cm along x, the orientation
// kept: the tool stays on the segment and the joints reproduce it.
TEST_F(RobotTest, LinearMoveOnTheUr5) {
  const auto ur5 = robot_model("ur5");
  const Eigen::Isometry3d X_home = forward_kinematics(ur5, ur5.home());
  const Eigen::Vector3d p0 = X_home.translation();
  const Eigen::Vector3d p1 = p0 + Eigen::Vector3d(0.1, 0.0, 0.0);
  const Eigen::Quaterniond q_home(X_home.linear());

  v1::PlanRequest request;
  auto* goal = request.mutable_linear_move()->mutable_goal();
  goal->mutable_position()->set_x(p1.x());
  goal->mutable_position()->set_y(p1.y());
  goal->mutable_position()->set_z(p1.z());
  goal->mutable_orientation()->set_w(q_home.w());
  goal->mutable_orientation()->set_x(q_home.x());
  goal->mutable_orientation()->set_y(q_home.y());
  goal->mutable_orientation()->set_z(q_home.z());
  request.mutable_robot()->set_name("ur5");
  request.mutable_motion()->set_duration_s(2.0);
  request.mutable_motion()->set_cycle_rate_hz(500.0);

  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_TRUE(response.robot().feasible());
  EXPECT_EQ(response.robot().samples(), 1001u);

  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), 1001u);
  const Eigen::Vector3d d_hat = (p1 - p0).normalized();
  double previous_s = -1.0;
  for (const auto& s : samples) {
    ASSERT_EQ(s.joints_size(), 6);
    ASSERT_EQ(s.joint_velocities_size(), 6);
    const Eigen::Vector3d p = vec(s.position());
    const double along = (p - p0).dot(d_hat);
    EXPECT_LT((p - p0 - along * d_hat).norm(), 1e-12) << "off the line at t = " << s.t();
    EXPECT_GE(along, -1e-12);
    EXPECT_LE(along, 0.1 + 1e-12);
    EXPECT_GE(along, previous_s - 1e-15) << "goes back at t = " << s.t();
    previous_s = along;
    EXPECT_LT(q_home.angularDistance(quat(s.orientation())), 1e-9) << "turns at t = " << s.t();
    EXPECT_LT((forward_kinematics(ur5, s.joints()).translation() - p).norm(), 1e-8) << "at t = " << s.t();
  }
  EXPECT_LT((vec(samples.front().position()) - p0).norm(), 1e-12);
  EXPECT_LT((vec(samples.back().position()) - p1).norm(), 1e-12);
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(samples.front().joints(j), ur5.home(j), 1e-9) << "joint " << j;
}

// linear_move_ur5.json with durationS 0 and no Cartesian limits: the fastest line within the
// UR5's joint limits (the time-optimal sweep of the straight path), streamed at 100 Hz, 1 kHz
// and 10 kHz: on the segment, every joint's velocity and acceleration by finite differences
// within its limits, one of them reached, the goal reached; with a duration of 2 s and
// optimize.timing.timeOptimal the same.
TEST_F(RobotTest, FastestLinearMoveWithinTheJointLimits) {
  const auto ur5 = robot_model("ur5");
  auto request = example<v1::PlanRequest>("linear_move_ur5.json");
  request.mutable_motion()->set_duration_s(0.0);
  const Eigen::Vector3d p0 = forward_kinematics(ur5, ur5.home()).translation();
  const Eigen::Vector3d p1 = vec(request.linear_move().goal().position());
  double duration = 0.0;
  for (const double rate : {100.0, 1000.0, 10000.0}) {
    SCOPED_TRACE("rate " + std::to_string(rate));
    request.mutable_motion()->set_cycle_rate_hz(rate);
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    if (duration == 0.0) duration = response.motion().duration_s();
    EXPECT_NEAR(response.motion().duration_s(), duration, 0.01 * duration) << "the rate does not change it much";
    grpc::Status stream_status;
    const auto samples = stream_all(request, stream_status);
    ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
    const double dt = 1.0 / rate;
    double usage = 0.0;
    for (std::size_t k = 1; k < samples.size(); ++k) {
      const Eigen::Vector3d p = vec(samples[k].position());
      const Eigen::Vector3d d = (p1 - p0).normalized();
      ASSERT_LT((p - p0 - (p - p0).dot(d) * d).norm(), 1e-9) << "off the line at t = " << samples[k].t();
      const double h = samples[k].t() - samples[k - 1].t();
      for (int j = 0; j < 6; ++j) {
        const auto& limits = ur5.limits(j);
        const double v = (samples[k].joints(j) - samples[k - 1].joints(j)) / h;
        usage = std::max(usage, std::abs(v) / limits.max_velocity());
        ASSERT_LE(std::abs(v), limits.max_velocity() * (1 + 1e-6)) << "joint " << j << " t " << samples[k].t();
        if (k + 1 < samples.size() && std::abs(samples[k + 1].t() - samples[k].t() - dt) < 1e-9 &&
            std::abs(h - dt) < 1e-9) {
          const double a = (samples[k + 1].joints(j) - 2 * samples[k].joints(j) + samples[k - 1].joints(j)) / (dt * dt);
          usage = std::max(usage, std::abs(a) / limits.max_acceleration());
          ASSERT_LE(std::abs(a), limits.max_acceleration() * (1 + 2e-2)) << "joint " << j << " t " << samples[k].t();
        }
      }
    }
    EXPECT_GT(usage, 0.95) << "a joint limit binds";
    EXPECT_LT((vec(samples.back().position()) - p1).norm(), 1e-9);
  }
  std::printf("[ measured ] fastest UR5 line of linear_move_ur5.json: %.4f s\n", duration);
  EXPECT_LT(duration, 2.0) << "faster than the example's 2 s";

  // Asked for explicitly, the time-optimal sweep (thesis 6.4) without the default jerk
  // bound: faster, by at most the ramps' time (0.05 s at each end and at each switch).
  auto timed = example<v1::PlanRequest>("linear_move_ur5.json");
  timed.mutable_optimize()->mutable_timing()->set_time_optimal(true);
  v1::PlanResponse response;
  ASSERT_TRUE(plan(timed, response).ok());
  EXPECT_FALSE(response.robot().has_default_jerk());
  EXPECT_LT(response.motion().duration_s(), duration);
  EXPECT_GT(response.motion().duration_s(), duration - 0.2);
  ASSERT_TRUE(response.optimization().has_timing());
  EXPECT_GT(response.optimization().timing().check_rate_hz(), 0.0);

  timed.mutable_optimize()->mutable_tangent_scales();
  const auto violations = refused(timed);
  EXPECT_THAT(violation_of(violations, "optimize.tangentScales"), HasSubstr("straight")) << describe(violations);
}

// The thesis's path C on the Franka Panda (plan_panda_path_c.json: a URDF arm, the tool
// pointing down, time-optimal at 1 kHz after a joint approach from home), streamed: every
// joint within its position limits, and its velocity, acceleration and jerk by finite
// differences of the streamed joints within the Panda's limits; the same arm given inline as
// its URDF text streams the same samples.
TEST_F(RobotTest, PathCOnThePandaWithinItsLimits) {
  const auto panda = robot_model("panda");
  auto request = example<v1::PlanRequest>("plan_panda_path_c.json");
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_GT(samples.size(), 1000u);
  const double dt = 1.0 / request.motion().cycle_rate_hz();
  double usage = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    for (int j = 0; j < 7; ++j) {  // position; velocity and acceleration by (non-uniform) differences
      const auto& l = panda.limits(j);
      ASSERT_GE(samples[k].joints(j), l.min_position() - 1e-9) << "joint " << j << " t " << samples[k].t();
      ASSERT_LE(samples[k].joints(j), l.max_position() + 1e-9) << "joint " << j << " t " << samples[k].t();
      if (k == 0) continue;
      // One step is shorter: the approach ends between two ticks, where the arm rests.
      const double h1 = samples[k].t() - samples[k - 1].t();
      ASSERT_LE(h1, dt + 1e-9);
      const double v = (samples[k].joints(j) - samples[k - 1].joints(j)) / h1;
      usage = std::max(usage, std::abs(v) / l.max_velocity());
      ASSERT_LE(std::abs(v), l.max_velocity() * (1 + 1e-3)) << "joint " << j << " t " << samples[k].t();
      if (k + 1 < samples.size()) {
        const double h2 = samples[k + 1].t() - samples[k].t();
        const double a = 2.0 * ((samples[k + 1].joints(j) - samples[k].joints(j)) / h2 - v) / (h1 + h2);
        usage = std::max(usage, std::abs(a) / l.max_acceleration());
        ASSERT_LE(std::abs(a), l.max_acceleration() * (1 + 2e-2)) << "joint " << j << " t " << samples[k].t();
      }
    }
  }
  EXPECT_GT(usage, 0.98) << "time-optimal: a limit binds";
  // The inline URDF is the same arm.
  auto inline_request = request;
  inline_request.mutable_robot()->set_urdf(std::string(planner::builtin_urdf("panda")));
  inline_request.mutable_robot()->set_tip_link("panda_link8");
  const auto same = stream_all(inline_request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(same.size(), samples.size());
  for (std::size_t k = 0; k < samples.size(); k += 97) {
    for (int j = 0; j < 7; ++j) EXPECT_EQ(same[k].joints(j), samples[k].joints(j));
  }
  std::printf("[ measured ] path C on the Panda: %.4f s in all (joint approach, then the path), %zu samples at 1 kHz\n",
              samples.back().t(), samples.size());

  // Without the ease, the turn of the first segment ends at frame 1 with the tool still
  // turning at 1.3 rad/s and then holds: the joint velocities step there. The plan says so
  // (an acceleration between samples far above the limit) instead of streaming it.
  auto stepping = request;
  stepping.mutable_path()->mutable_frames(0)->set_ease_orientation(false);
  v1::PlanResponse response;
  const auto refused_status = plan(stepping, response);
  ASSERT_EQ(refused_status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << refused_status.error_message();
  EXPECT_THAT(refused_status.error_message(), HasSubstr("acceleration"));
}

// Tool angular limits (motion.maxAngularSpeed, maxAngularAcceleration): the UR5's line of
// linear_move_ur5.json (a 90 degree turn over 0.27 m) as fast as the joints and 1 rad/s,
// 2 rad/s^2 allow, streamed at 1 kHz: |omega| within 1 rad/s, |alpha| by differences of the
// streamed omega within 2 rad/s^2, one of them reached; the same line without a robot in
// the closed form the angular limits set; refused where they would not be imposed.
TEST_F(RobotTest, ToolAngularLimitsHoldOnTheFastestLine) {
  auto request = example<v1::PlanRequest>("linear_move_ur5.json");
  auto& motion = *request.mutable_motion();
  motion.set_duration_s(0.0);
  motion.set_cycle_rate_hz(1000.0);
  motion.set_max_angular_speed(1.0);
  motion.set_max_angular_acceleration(2.0);
  v1::PlanResponse response;
  auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  double peak_w = 0.0, peak_a = 0.0;
  for (std::size_t k = 1; k < samples.size(); ++k) {
    const double h = samples[k].t() - samples[k - 1].t();
    peak_w = std::max(peak_w, vec(samples[k].angular_velocity()).norm());
    peak_a = std::max(peak_a, (vec(samples[k].angular_velocity()) - vec(samples[k - 1].angular_velocity())).norm() / h);
  }
  std::printf("[ measured ] UR5 line under 1 rad/s, 2 rad/s^2: %.4f s, peak |omega| %.6f rad/s, peak |alpha| %.6f "
              "rad/s^2 (differences)\n",
              response.motion().duration_s(), peak_w, peak_a);
  EXPECT_LE(peak_w, 1.0 * (1 + 1e-6));
  EXPECT_LE(peak_a, 2.0 * (1 + 1e-3));
  EXPECT_GT(std::max(peak_w / 1.0, peak_a / 2.0), 0.97) << "an angular limit binds";
  EXPECT_GT(response.motion().duration_s(), 0.8592) << "slower than the joints alone allow";

  // Without a robot: the trapezoid under maxSpeed, maxAcceleration and the caps
  // omega_max L / theta, alpha_max L / theta.
  auto cartesian = request;
  cartesian.clear_robot();
  const auto ur5 = robot_model("ur5");
  const Eigen::Isometry3d X_home = forward_kinematics(ur5, ur5.home());
  set_pose(*cartesian.mutable_linear_move()->mutable_start(), X_home);
  cartesian.mutable_motion()->set_max_speed(1.0);
  cartesian.mutable_motion()->set_max_acceleration(10.0);
  ASSERT_TRUE(plan(cartesian, response).ok());
  const double L = (vec(cartesian.linear_move().goal().position()) - X_home.translation()).norm();
  const double theta = quat(cartesian.linear_move().goal().orientation())
                           .angularDistance(Eigen::Quaterniond(X_home.linear()));
  const double v = std::min(1.0, 1.0 * L / theta), a = std::min(10.0, 2.0 * L / theta);
  const double t_ref = v * v / a < L ? L / v + v / a : 2.0 * std::sqrt(L / a);
  EXPECT_NEAR(response.motion().duration_s(), t_ref, 1e-9);
  EXPECT_NEAR(response.motion().peak_angular_speed(), std::min(1.0, v * theta / L), 1e-6);

  // Refused where they would not bound the motion.
  auto timed = request;
  timed.mutable_motion()->set_duration_s(2.0);
  EXPECT_THAT(violation_of(refused(timed), "motion.maxAngularSpeed"), HasSubstr("duration"));
  auto jerk = request;
  jerk.mutable_optimize()->mutable_timing()->set_jerk_limited(true);
  EXPECT_THAT(violation_of(refused(jerk), "motion.maxAngularSpeed"), HasSubstr("jerkLimited"));
  auto negative = request;
  negative.mutable_motion()->set_max_angular_acceleration(-1.0);
  EXPECT_NE(violation_of(refused(negative), "motion.maxAngularAcceleration"), "");
}

// ---------------------------------------------------------------------------------------
// Robot model files served by geotrajd

// A file in the test's temporary directory, removed at the end of the test.
class TempFile {
 public:
  TempFile(const std::string& name, const std::string& text)
      : path_(::testing::TempDir() + "geotraj_robot_test_" + std::to_string(::getpid()) + "_" + name) {
    std::ofstream(path_) << text;
  }
  ~TempFile() { std::remove(path_.c_str()); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

std::string to_json(const google::protobuf::Message& message) {
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  EXPECT_TRUE(google::protobuf::util::MessageToJsonString(message, &json, options).ok());
  return json;
}

// Starts geotrajd with `args`, expecting it to exit non-zero without serving; its standard
// error.
std::string refused_start(const std::vector<std::string>& args) {
  Daemon daemon(args);
  EXPECT_TRUE(daemon.started());
  const std::string serving = daemon.line();
  if (!serving.empty()) {  // it serves: stop it rather than wait for its exit
    ADD_FAILURE() << "geotrajd started: " << serving;
    daemon.signal(SIGKILL);
  }
  std::string errors = daemon.errors();
  EXPECT_NE(daemon.wait(), 0) << errors;
  return errors;
}

TEST_F(RobotTest, GeotrajdServesARobotModelFile) {
  auto arm = robot_model("pa10");
  arm.set_name("my-arm");
  arm.set_description("the PA-10 under another name");
  const TempFile file("my_arm.json", to_json(arm));

  Daemon daemon({"--address", "127.0.0.1:0", "--drain-seconds", "0.2", "--robot-model", file.path()});
  ASSERT_TRUE(daemon.started());
  const std::string serving = daemon.line();
  const int port = port_of(serving);
  ASSERT_GT(port, 0) << serving << daemon.errors();
  auto stub = v1::TrajectoryService::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials()));

  v1::ListRobotsResponse robots;
  ASSERT_TRUE(stub->ListRobots(context().get(), v1::ListRobotsRequest{}, &robots).ok());
  std::vector<std::string> names;
  const v1::RobotModel* served = nullptr;
  for (const auto& m : robots.robots()) {
    names.push_back(m.name());
    if (m.name() == "my-arm") served = &m;
  }
  EXPECT_THAT(names, ::testing::UnorderedElementsAre("pa10", "ur5", "panda", "iiwa14", "ur5e", "my-arm"));
  ASSERT_NE(served, nullptr);
  EXPECT_EQ(served->links_size(), 7);
  EXPECT_EQ(served->description(), "the PA-10 under another name");
  EXPECT_EQ(served->dh_convention(), v1::DH_CONVENTION_MODIFIED);

  // Usable by name, with the same answer as the built-in model it copies.
  auto request = pa10_path_a(60.0, /*report_only=*/false);
  request.mutable_robot()->set_name("my-arm");
  v1::PlanResponse mine, builtin;
  const auto status = stub->PlanTrajectory(context().get(), request, &mine);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(mine.robot().name(), "my-arm");
  EXPECT_TRUE(mine.robot().feasible());
  ASSERT_TRUE(plan(pa10_path_a(60.0, false), builtin).ok());
  EXPECT_EQ(mine.robot().samples(), builtin.robot().samples());
  EXPECT_EQ(mine.robot().joints(0).max_position(), builtin.robot().joints(0).max_position());

  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(), 0);
}

// A stub on the daemon's port (null when it did not start or print its port).
std::unique_ptr<v1::TrajectoryService::Stub> stub_of(Daemon& daemon) {
  if (!daemon.started()) return nullptr;
  const int port = port_of(daemon.line());
  if (port <= 0) return nullptr;
  return v1::TrajectoryService::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials()));
}

// `--robot-model arm.urdf`: a URDF document served by its robot name, its <geotraj> block
// read; a bad one refused at start-up with the file and the line.
TEST_F(RobotTest, GeotrajdServesAUrdfFile) {
  v1::ListRobotsResponse builtin;
  ASSERT_TRUE(stub_->ListRobots(context().get(), v1::ListRobotsRequest{}, &builtin).ok());
  std::string text = R"(<?xml version="1.0"?>
<robot name="two-link">
  <link name="base"/><link name="upper"/><link name="lower"/><link name="flange"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="1.5"/></joint>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="lower"/><origin xyz="0 0 0.4" rpy="0 0 1.5707963267948966"/>
    <axis xyz="1 0 0"/><limit effort="10" velocity="2"/></joint>
  <joint name="tip" type="fixed"><parent link="lower"/><child link="flange"/><origin xyz="0 0 0.25"/></joint>
  <geotraj description="a two-link test arm"><joint name="shoulder" max_acceleration="3" home="0.1"/>
    <joint name="elbow" max_acceleration="4" max_jerk="40"/></geotraj>
</robot>
)";
  const TempFile file("two_link.urdf", text);
  Daemon daemon({"--address", "127.0.0.1:0", "--drain-seconds", "0.2", "--robot-model", file.path()});
  const auto stub = stub_of(daemon);
  ASSERT_TRUE(stub) << daemon.errors();
  v1::ListRobotsResponse robots;
  ASSERT_TRUE(stub->ListRobots(context().get(), v1::ListRobotsRequest{}, &robots).ok());
  ASSERT_EQ(robots.robots_size(), builtin.robots_size() + 1);
  const v1::RobotModel& arm = robots.robots(robots.robots_size() - 1);
  EXPECT_EQ(arm.name(), "two-link");
  EXPECT_EQ(arm.description(), "a two-link test arm");
  ASSERT_EQ(arm.joints_size(), 2);
  EXPECT_EQ(arm.joints(1).joint_type(), v1::JOINT_TYPE_CONTINUOUS);
  EXPECT_FALSE(arm.limits(1).has_max_jerk() && arm.limits(0).has_max_jerk());
  EXPECT_EQ(arm.limits(1).max_jerk(), 40.0);
  EXPECT_EQ(arm.home(0), 0.1);
  // Its tool at (q1, q2): the elbow turns about the upper link's y (x turned by 90 degrees about z).
  v1::ForwardKinematicsRequest fk;
  fk.mutable_robot()->set_name("two-link");
  fk.add_joints(0.3);
  fk.add_joints(12.0);  // a continuous joint: any angle
  v1::ForwardKinematicsResponse response;
  const auto status = stub->ComputeForwardKinematics(context().get(), fk, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_TRUE(response.within_limits());
  const Eigen::Isometry3d expected = Eigen::Translation3d(0, 0, 0.3) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) *
                                     Eigen::Translation3d(0, 0, 0.4) * Eigen::AngleAxisd(1.5707963267948966, Eigen::Vector3d::UnitZ()) *
                                     Eigen::AngleAxisd(12.0, Eigen::Vector3d::UnitX()) * Eigen::Translation3d(0, 0, 0.25);
  EXPECT_LT((vec(response.pose().position()) - expected.translation()).norm(), 1e-12);
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(), 0);

  // As shipped, without the elbow's acceleration: served all the same (a warning at start-up),
  // its acceleration listed as not known; the kinematics answer, a motion is refused naming
  // the joint and the three ways to give it, and planned once the request gives it, the
  // report saying where each limit came from.
  const std::string entry = "<joint name=\"elbow\" max_acceleration=\"4\" max_jerk=\"40\"/>";
  const std::string shipped = text.replace(text.find(entry), entry.size(), "");
  const TempFile bare("shipped.urdf", shipped);
  Daemon as_shipped({"--address", "127.0.0.1:0", "--drain-seconds", "0.2", "--robot-model", bare.path()});
  const auto served = stub_of(as_shipped);
  ASSERT_TRUE(served) << as_shipped.errors();
  ASSERT_TRUE(served->ListRobots(context().get(), v1::ListRobotsRequest{}, &robots).ok());
  const v1::RobotModel& listed = robots.robots(robots.robots_size() - 1);
  EXPECT_EQ(listed.limits(1).max_acceleration(), 0.0);
  EXPECT_THAT(listed.limits(1).sources().acceleration(), HasSubstr("not known"));
  EXPECT_THAT(listed.limits(0).sources().acceleration(), HasSubstr("URDF <geotraj> block, line 9, joint 'shoulder'"));
  EXPECT_THAT(listed.limits(0).sources().velocity(), HasSubstr("URDF <limit velocity>, line 4, joint 'shoulder'"));
  ASSERT_TRUE(served->ComputeForwardKinematics(context().get(), fk, &response).ok());
  v1::PlanRequest move;
  move.mutable_joint_move()->add_goal(0.5);
  move.mutable_joint_move()->add_goal(1.0);
  move.mutable_motion()->set_duration_s(0.0);
  move.mutable_robot()->set_name("two-link");
  v1::PlanResponse planned;
  auto refusal = served->PlanTrajectory(context().get(), move, &planned);
  ASSERT_EQ(refusal.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << refusal.error_message();
  const std::string why = violation_of(bad_request_violations(refusal), "robot.jointLimits");
  EXPECT_THAT(why, HasSubstr("joint 1 (elbow) has no acceleration limit"));
  EXPECT_THAT(why, HasSubstr("robot.jointLimitsYaml, or geotrajd --joint-limits FILE"));
  EXPECT_THAT(why, HasSubstr("<geotraj><joint name=\"elbow\" max_acceleration="));
  auto* given = move.mutable_robot()->add_joint_limits();
  given->set_joint("elbow");
  given->set_max_acceleration(2.0);
  const auto ok = served->PlanTrajectory(context().get(), move, &planned);
  ASSERT_TRUE(ok.ok()) << ok.error_message();
  EXPECT_NEAR(planned.robot().joints(1).acceleration_usage(), 1.0, 1e-6);  // the elbow's 2 rad/s^2 binds
  EXPECT_EQ(planned.robot().joints(1).limit_sources().acceleration(), "robot.jointLimits[0]");
  EXPECT_THAT(planned.robot().joints(0).limit_sources().acceleration(), HasSubstr("URDF <geotraj> block"));
  EXPECT_THAT(planned.robot().joints(1).limit_sources().velocity(), HasSubstr("URDF <limit velocity>, line 6"));
  as_shipped.signal(SIGTERM);
  EXPECT_EQ(as_shipped.wait(), 0);
  EXPECT_THAT(as_shipped.errors(), HasSubstr("serves the kinematics only until its limits are given"));

  // A camera frame beside the flange: two leaves through both joints, listed; FILE:TIP_LINK
  // names the tip.
  std::string camera = shipped;
  camera.insert(camera.find("</robot>"), "<link name=\"camera\"/><joint name=\"camera_mount\" type=\"fixed\">"
                                         "<parent link=\"lower\"/><child link=\"camera\"/></joint>\n");
  const TempFile with_camera("camera.urdf", camera);
  EXPECT_THAT(refused_start({"--address", "127.0.0.1:0", "--robot-model", with_camera.path()}),
              HasSubstr("'camera', 'flange'"));
  Daemon to_flange({"--address", "127.0.0.1:0", "--drain-seconds", "0.2", "--robot-model", with_camera.path() + ":flange"});
  const auto flange = stub_of(to_flange);
  ASSERT_TRUE(flange) << to_flange.errors();
  v1::ForwardKinematicsResponse at_flange;
  ASSERT_TRUE(flange->ComputeForwardKinematics(context().get(), fk, &at_flange).ok());
  EXPECT_LT((vec(at_flange.pose().position()) - vec(response.pose().position())).norm(), 1e-12);
  to_flange.signal(SIGTERM);
  EXPECT_EQ(to_flange.wait(), 0);
  EXPECT_THAT(refused_start({"--address", "127.0.0.1:0", "--robot-model", with_camera.path() + ":nowhere"}),
              HasSubstr("nowhere"));
}

// `--joint-limits joint_limits.yaml`: MoveIt's file gives the accelerations the URDF lacks
// (the elbow's, removed from the block), a jerk and a tighter velocity; a joint of the file off
// every model (a gripper's) is not read; a file naming no model's joint, or not YAML, refused
// at start-up naming the file.
TEST_F(RobotTest, GeotrajdReadsMoveItsJointLimits) {
  const std::string text = R"(<?xml version="1.0"?>
<robot name="two-link-moveit">
  <link name="base"/><link name="upper"/><link name="lower"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="1.5"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="2"/></joint>
</robot>
)";
  const TempFile urdf("two_link_moveit.urdf", text);
  const TempFile yaml("joint_limits.yaml", R"(joint_limits:
  shoulder:
    has_velocity_limits: true
    max_velocity: 1.2
    has_acceleration_limits: true
    max_acceleration: 3
  elbow:
    has_acceleration_limits: true
    max_acceleration: 4
    has_jerk_limits: true
    max_jerk: 40
  gripper_finger_joint:
    has_velocity_limits: true
    max_velocity: 0.1
)");
  Daemon daemon({"--address", "127.0.0.1:0", "--drain-seconds", "0.2", "--robot-model", urdf.path(),
                 "--joint-limits", yaml.path()});
  const auto stub = stub_of(daemon);
  ASSERT_TRUE(stub) << daemon.errors();
  v1::ListRobotsResponse robots;
  ASSERT_TRUE(stub->ListRobots(context().get(), v1::ListRobotsRequest{}, &robots).ok());
  const v1::RobotModel& arm = robots.robots(robots.robots_size() - 1);
  ASSERT_EQ(arm.name(), "two-link-moveit");
  EXPECT_EQ(arm.limits(0).max_velocity(), 1.2);
  EXPECT_EQ(arm.limits(0).max_acceleration(), 3.0);
  EXPECT_EQ(arm.limits(1).max_velocity(), 2.0) << "the URDF's, the file gives none";
  EXPECT_EQ(arm.limits(1).max_acceleration(), 4.0);
  EXPECT_EQ(arm.limits(1).max_jerk(), 40.0);
  EXPECT_EQ(arm.limits(1).sources().acceleration(), "joint_limits.yaml \"" + yaml.path() + "\" (geotrajd --joint-limits)");
  EXPECT_EQ(arm.limits(1).sources().jerk(), arm.limits(1).sources().acceleration());
  EXPECT_THAT(arm.limits(1).sources().velocity(), HasSubstr("URDF <limit velocity>"));
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(), 0);

  std::string blocked = text;  // with its accelerations in a <geotraj> block
  blocked.insert(blocked.find("</robot>"), "<geotraj><joint name=\"shoulder\" max_acceleration=\"3\"/>"
                                           "<joint name=\"elbow\" max_acceleration=\"4\"/></geotraj>\n");
  const TempFile complete("two_link_complete.urdf", blocked);
  const TempFile other("other_limits.yaml", "joint_limits:\n  wrist:\n    has_velocity_limits: true\n    max_velocity: 1\n");
  EXPECT_THAT(refused_start({"--address", "127.0.0.1:0", "--robot-model", complete.path(), "--joint-limits", other.path()}),
              HasSubstr("--joint-limits names no joint of the --robot-model models"));
  const TempFile broken("broken_limits.yaml", "joint_limits: {shoulder: [");
  const std::string errors =
      refused_start({"--address", "127.0.0.1:0", "--robot-model", urdf.path(), "--joint-limits", broken.path()});
  EXPECT_THAT(errors, HasSubstr(broken.path()));
  EXPECT_THAT(errors, HasSubstr("is not YAML"));
}

// The same file in a request (RobotSpec.jointLimitsYaml): a built-in arm's limits over its
// own, the plan slower for a lower velocity.
TEST_F(RobotTest, ARequestsJointLimitsYamlIsTheRobotsLimits) {
  v1::PlanRequest request = example<v1::PlanRequest>("plan_joint_path_panda.json");
  const double fast = plan_ok(request).motion().duration_s();
  std::string yaml = "joint_limits:\n";
  for (int j = 1; j <= 7; ++j)
    yaml += "  panda_joint" + std::to_string(j) + ":\n    has_velocity_limits: true\n    max_velocity: 1.0\n";
  request.mutable_robot()->set_joint_limits_yaml(yaml);
  const auto slow = plan_ok(request);
  EXPECT_GT(slow.motion().duration_s(), fast * 1.1);
  for (const auto& j : slow.robot().joints()) EXPECT_LE(j.peak_velocity(), 1.0 * (1 + 1e-9)) << "joint " << j.joint();
  request.mutable_robot()->set_joint_limits_yaml("joint_limits:\n  panda_joint1:\n    has_velocity_limits: yes please\n");
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "robot.jointLimitsYaml"),
              HasSubstr("line 3, joint_limits.panda_joint1.has_velocity_limits: must be true or false"));
}

// A URDF as its maker ships it (no <geotraj> block): kinematics calls take it as it is; a
// motion needs accelerations, refused naming the joints and where to give them, and planned
// once robot.jointLimits gives them. jointLimits also tighten a built-in model's limits.
TEST_F(RobotTest, UrdfWithoutAccelerationsServesKinematicsAndTakesJointLimits) {
  std::string urdf(planner::builtin_urdf("ur5e"));
  urdf = urdf.substr(0, urdf.find("<geotraj description")) + "</robot>\n";
  v1::ForwardKinematicsRequest fk;
  fk.mutable_robot()->set_urdf(urdf);
  for (int i = 0; i < 6; ++i) fk.add_joints(0.1 * i);
  v1::ForwardKinematicsResponse pose;
  auto status = stub_->ComputeForwardKinematics(context().get(), fk, &pose);
  ASSERT_TRUE(status.ok()) << status.error_message();
  v1::ForwardKinematicsRequest by_name = fk;
  by_name.mutable_robot()->set_name("ur5e");
  v1::ForwardKinematicsResponse expected;
  ASSERT_TRUE(stub_->ComputeForwardKinematics(context().get(), by_name, &expected).ok());
  EXPECT_LT((vec(pose.pose().position()) - vec(expected.pose().position())).norm(), 1e-15);

  v1::PlanRequest request;  // a joint move of every joint, as fast as the joints allow
  for (const double q : {0.5, -1.2, 1.2, -1.5, -1.4, 0.3}) request.mutable_joint_move()->add_goal(q);
  request.mutable_motion()->set_duration_s(0.0);
  request.mutable_robot()->set_urdf(urdf);
  const v1::RobotModel ur5e = robot_model("ur5e");
  for (const double q : ur5e.home()) request.mutable_robot()->add_initial_joints(q);  // no block: no home
  auto violations = refused(request);
  const std::string why = violation_of(violations, "robot.jointLimits");
  EXPECT_THAT(why, HasSubstr("joints 0 (shoulder_pan_joint), 1 (shoulder_lift_joint)"));
  EXPECT_THAT(why, HasSubstr("no acceleration limit"));
  EXPECT_THAT(why, HasSubstr("robot.jointLimitsYaml"));
  const char* names[] = {"shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                         "wrist_3_joint"};
  for (const char* name : names) {
    auto* l = request.mutable_robot()->add_joint_limits();
    l->set_joint(name);
    l->set_max_acceleration(6.283185307179586);  // what the built-in file's block says
  }
  v1::PlanResponse inline_plan, named_plan;
  status = plan(request, inline_plan);
  ASSERT_TRUE(status.ok()) << status.error_message();
  auto named = request;
  named.mutable_robot()->set_name("ur5e");
  named.mutable_robot()->clear_joint_limits();
  ASSERT_TRUE(plan(named, named_plan).ok());
  EXPECT_NEAR(inline_plan.motion().duration_s(), named_plan.motion().duration_s(), 1e-6);  // the file rounds 2 pi
  for (int j = 0; j < 6; ++j) {
    EXPECT_EQ(inline_plan.robot().joints(j).limit_sources().acceleration(), "robot.jointLimits[" + std::to_string(j) + "]");
    EXPECT_EQ(named_plan.robot().joints(j).limit_sources().acceleration(), "the model's");
  }

  // Tighter: the elbow's acceleration a sixth of the model's, the line takes longer and the
  // elbow stays within the given limit.
  const v1::PlanResponse& fastest = named_plan;
  v1::PlanResponse tighter;
  auto* elbow = named.mutable_robot()->add_joint_limits();
  elbow->set_joint("elbow_joint");
  elbow->set_max_acceleration(1.0);
  status = plan(named, tighter);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_GT(tighter.motion().duration_s(), fastest.motion().duration_s());
  EXPECT_LE(tighter.robot().joints(2).peak_acceleration(), 1.0 * (1 + 1e-6));
  EXPECT_NEAR(tighter.robot().joints(2).acceleration_usage(), 1.0, 1e-6);  // the elbow sets the time now

  // Unknown joints and bad values are named.
  elbow->set_joint("knee");
  elbow->set_max_jerk(-3.0);
  violations = refused(named);
  EXPECT_THAT(violation_of(violations, "robot.jointLimits[0].maxJerk"), HasSubstr("> 0")) << describe(violations);
  elbow->clear_max_jerk();
  violations = refused(named);
  EXPECT_THAT(violation_of(violations, "robot.jointLimits[0].joint"), HasSubstr("'elbow_joint'")) << describe(violations);
  // Every problem at once: a bad limit beside a bad document.
  request.mutable_robot()->mutable_joint_limits(0)->set_max_velocity(-1.0);
  request.mutable_robot()->set_urdf("<robot name=\"broken\">");
  violations = refused(request);
  EXPECT_THAT(violation_of(violations, "robot.jointLimits[0].maxVelocity"), HasSubstr("> 0")) << describe(violations);
  EXPECT_THAT(violation_of(violations, "robot.urdf"), HasSubstr("not well-formed")) << describe(violations);
}

TEST_F(RobotTest, GeotrajdRefusesABadRobotModelFile) {
  auto inverted = robot_model("ur5");
  inverted.set_name("inverted");
  inverted.mutable_limits(3)->set_min_position(1.0);
  inverted.mutable_limits(3)->set_max_position(-1.0);
  auto duplicate = robot_model("ur5");  // a second "ur5"
  struct Case {
    std::string file;
    std::string text;
    std::string why;  // in geotrajd's message
  };
  for (const Case& c : {Case{"not_json.json", "{\"name\": \"x\", \"links\": 3}", "RobotModel"},
                        Case{"inverted.json", to_json(inverted), "limits[3].minPosition"},
                        Case{"duplicate.json", to_json(duplicate), "ur5"}}) {
    SCOPED_TRACE(c.file);
    const TempFile file(c.file, c.text);
    const std::string errors = refused_start({"--address", "127.0.0.1:0", "--robot-model", file.path()});
    EXPECT_THAT(errors, HasSubstr(file.path()));
    EXPECT_THAT(errors, HasSubstr(c.why));
  }
  const std::string errors = refused_start({"--address", "127.0.0.1:0", "--robot-model", "/nonexistent/robot.json"});
  EXPECT_THAT(errors, HasSubstr("/nonexistent/robot.json"));
}

}  // namespace
}  // namespace geotraj::testing
