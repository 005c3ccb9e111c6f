// The kinematics calls through the real service, checked from the outside:
//  - ComputeForwardKinematics against an independent Denavit-Hartenberg forward kinematics
//    written from the proto's conventions (tests/server/support/dh_reference.hpp), its
//    Jacobian against central differences of that reference, its manipulability against
//    sqrt(det(J J^T)) of the Jacobian it returned;
//  - ComputeInverseKinematics: cold solves of random reachable poses of both arms (the
//    reference FK of joints uniform within the limits ListRobots gives), each solution's
//    pose by the reference; the UR5's eight branches; a seeded solve; the closest pose of an
//    unreachable target;
//  - bad requests named field by field.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gmock/gmock.h>

#include "tests/server/support/dh_reference.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

class KinematicsTest : public ServerTest {
 protected:
  grpc::Status fk(const v1::ForwardKinematicsRequest& request, v1::ForwardKinematicsResponse& response) {
    return stub_->ComputeForwardKinematics(context().get(), request, &response);
  }
  grpc::Status ik(const v1::InverseKinematicsRequest& request, v1::InverseKinematicsResponse& response) {
    return stub_->ComputeInverseKinematics(context().get(), request, &response);
  }
};

std::vector<double> uniform_joints(const v1::RobotModel& m, std::mt19937_64& rng) {
  std::vector<double> q;
  for (const auto& l : m.limits()) {
    q.push_back(std::uniform_real_distribution<double>(l.min_position(), l.max_position())(rng));
  }
  return q;
}

void set_pose(v1::Pose& out, const Eigen::Isometry3d& X) {
  out.mutable_position()->set_x(X.translation().x());
  out.mutable_position()->set_y(X.translation().y());
  out.mutable_position()->set_z(X.translation().z());
  const Eigen::Quaterniond q(X.linear());
  out.mutable_orientation()->set_w(q.w());
  out.mutable_orientation()->set_x(q.x());
  out.mutable_orientation()->set_y(q.y());
  out.mutable_orientation()->set_z(q.z());
}

double angle_between(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle();
}

// The model as a request sends it, base and tool moved off the identity.
v1::RobotModel with_base_and_tool(v1::RobotModel m) {
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  base.translation() = Eigen::Vector3d(0.2, -0.1, 0.3);
  base.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.translation() = Eigen::Vector3d(0.0, 0.02, 0.12);
  tool.linear() = Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitX()).toRotationMatrix();
  set_pose(*m.mutable_base(), base);
  set_pose(*m.mutable_tool(), tool);
  return m;
}

TEST_F(KinematicsTest, ForwardKinematicsMatchesAnIndependentSerialChain) {
  std::mt19937_64 rng(20261203);
  for (const char* name : {"pa10", "ur5"}) {
    SCOPED_TRACE(name);
    const v1::RobotModel model = with_base_and_tool(robot_model(name));
    const int n = model.links_size();
    for (int k = 0; k < 25; ++k) {
      const auto q = uniform_joints(model, rng);
      v1::ForwardKinematicsRequest request;
      *request.mutable_robot()->mutable_model() = model;
      for (double x : q) request.add_joints(x);
      v1::ForwardKinematicsResponse response;
      const auto status = fk(request, response);
      ASSERT_TRUE(status.ok()) << status.error_message();
      const Eigen::Isometry3d expected = forward_kinematics(model, q);
      EXPECT_LT((pose(response.pose()).translation() - expected.translation()).norm(), 1e-12);
      EXPECT_LT(angle_between(pose(response.pose()), expected), 1e-12);
      EXPECT_TRUE(response.within_limits());
      ASSERT_EQ(response.axes_size(), n);

      // The Jacobian against central differences of the reference: rows [v; omega] in W.
      ASSERT_EQ(response.jacobian_size(), 6 * n);
      Eigen::MatrixXd J(6, n);
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < n; ++c) J(r, c) = response.jacobian(r * n + c);
      }
      const double h = 1e-6;
      for (int c = 0; c < n; ++c) {
        auto plus = q, minus = q;
        plus[static_cast<std::size_t>(c)] += h;
        minus[static_cast<std::size_t>(c)] -= h;
        const Eigen::Isometry3d Xp = forward_kinematics(model, plus), Xm = forward_kinematics(model, minus);
        const Eigen::Vector3d v = (Xp.translation() - Xm.translation()) / (2 * h);
        const Eigen::AngleAxisd turn(Xp.linear() * Xm.linear().transpose());
        const Eigen::Vector3d omega = turn.angle() * turn.axis() / (2 * h);
        EXPECT_LT((J.block(0, c, 3, 1) - v).norm(), 1e-7) << "column " << c;
        EXPECT_LT((J.block(3, c, 3, 1) - omega).norm(), 1e-7) << "column " << c;
        // The axis is the angular column; the tool's velocity about it is z x (p - o).
        const Eigen::Vector3d z = vec(response.axes(c).direction());
        const Eigen::Vector3d o = vec(response.axes(c).origin());
        EXPECT_LT((z - omega).norm(), 1e-7);
        EXPECT_LT((z.cross(expected.translation() - o) - v).norm(), 1e-7);
      }
      EXPECT_NEAR(response.manipulability(), std::sqrt((J * J.transpose()).determinant()), 1e-9);
      const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J);
      EXPECT_NEAR(response.max_singular_value(), svd.singularValues()(0), 1e-9);
      EXPECT_NEAR(response.min_singular_value(), n >= 6 ? svd.singularValues()(5) : 0.0, 1e-9);
    }
  }
}

TEST_F(KinematicsTest, ForwardKinematicsOutsideTheLimitsIsAnsweredAndSaysSo) {
  v1::ForwardKinematicsRequest request;
  request.mutable_robot()->set_name("pa10");
  for (double x : {0.0, 3.0, 0.0, 0.5, 0.0, 0.0, 0.0}) request.add_joints(x);  // S2 beyond 94 degrees
  v1::ForwardKinematicsResponse response;
  ASSERT_TRUE(fk(request, response).ok());
  EXPECT_FALSE(response.within_limits());
}

// Cold inverse kinematics of random reachable poses, from each arm's home.
TEST_F(KinematicsTest, ColdInverseKinematicsOfRandomReachablePoses) {
  std::mt19937_64 rng(20261204);
  for (const char* name : {"pa10", "ur5"}) {
    SCOPED_TRACE(name);
    const v1::RobotModel model = robot_model(name);
    int solved = 0;
    const int cases = 200;
    for (int k = 0; k < cases; ++k) {
      const Eigen::Isometry3d target = forward_kinematics(model, uniform_joints(model, rng));
      v1::InverseKinematicsRequest request;
      request.mutable_robot()->set_name(name);
      set_pose(*request.mutable_target(), target);
      v1::InverseKinematicsResponse response;
      const auto status = ik(request, response);
      ASSERT_TRUE(status.ok()) << status.error_message();
      if (!response.reachable()) continue;
      ++solved;
      ASSERT_EQ(response.solutions_size(), 1);
      EXPECT_FALSE(response.has_closest());
      const auto& s = response.solutions(0);
      ASSERT_EQ(s.joints_size(), model.links_size());
      for (int i = 0; i < s.joints_size(); ++i) {
        EXPECT_GE(s.joints(i), model.limits(i).min_position());
        EXPECT_LE(s.joints(i), model.limits(i).max_position());
      }
      const Eigen::Isometry3d reached = forward_kinematics(model, s.joints());
      EXPECT_LT((reached.translation() - target.translation()).norm(), 1e-9 + 1e-12);
      EXPECT_LT(angle_between(reached, target), 1e-9 + 1e-12);
      EXPECT_LT((pose(s.pose()).translation() - reached.translation()).norm(), 1e-12);
    }
    std::printf("[ measured ] %s: %d of %d random reachable poses solved cold over the wire\n", name, solved, cases);
    EXPECT_EQ(solved, cases);
  }
}

TEST_F(KinematicsTest, EveryBranchOfAUr5Pose) {
  const v1::RobotModel model = robot_model("ur5");
  const std::vector<double> q = {0.3, -1.2, 1.4, -0.8, 1.1, 0.5};
  const Eigen::Isometry3d target = forward_kinematics(model, q);
  v1::InverseKinematicsRequest request;
  request.mutable_robot()->set_name("ur5");
  for (double x : q) request.mutable_robot()->add_initial_joints(x);
  set_pose(*request.mutable_target(), target);
  request.set_all_solutions(true);
  request.set_restarts(1999);
  v1::InverseKinematicsResponse response;
  ASSERT_TRUE(ik(request, response).ok());
  EXPECT_TRUE(response.reachable());
  EXPECT_EQ(response.attempts(), 2000u);
  ASSERT_EQ(response.solutions_size(), 8);
  for (int k = 0; k < response.solutions_size(); ++k) {
    const auto& s = response.solutions(k);
    const Eigen::Isometry3d reached = forward_kinematics(model, s.joints());
    EXPECT_LT((reached.translation() - target.translation()).norm(), 1e-9 + 1e-12);
    if (k > 0) {
      EXPECT_LE(response.solutions(k - 1).distance_from_seed(), s.distance_from_seed());
    }
  }
  EXPECT_LT(response.solutions(0).distance_from_seed(), 1e-6) << "the seed is a solution";
}

TEST_F(KinematicsTest, ASeededSolveStaysNearItsSeed) {
  const v1::RobotModel model = robot_model("pa10");
  const std::vector<double> q = {0.4, 0.6, -0.3, 1.2, 0.5, 0.8, -0.2};
  v1::InverseKinematicsRequest request;
  request.mutable_robot()->set_name("pa10");
  for (double x : q) request.mutable_robot()->add_initial_joints(x + 0.02);
  set_pose(*request.mutable_target(), forward_kinematics(model, q));
  request.set_restarts(0);
  v1::InverseKinematicsResponse response;
  ASSERT_TRUE(ik(request, response).ok());
  ASSERT_TRUE(response.reachable());
  EXPECT_EQ(response.attempts(), 1u);
  EXPECT_LT(response.solutions(0).distance_from_seed(), 0.1);
}

TEST_F(KinematicsTest, AnUnreachablePoseGetsTheClosestOneAndItsDistance) {
  const v1::RobotModel model = robot_model("ur5");
  v1::InverseKinematicsRequest request;
  request.mutable_robot()->set_name("ur5");
  request.mutable_target()->mutable_position()->set_x(2.0);  // the UR5 reaches about 0.85 m
  request.mutable_target()->mutable_position()->set_z(0.5);
  v1::InverseKinematicsResponse response;
  ASSERT_TRUE(ik(request, response).ok());
  EXPECT_FALSE(response.reachable());
  EXPECT_EQ(response.solutions_size(), 0);
  ASSERT_TRUE(response.has_closest());
  const auto& c = response.closest();
  const Eigen::Isometry3d reached = forward_kinematics(model, c.joints());
  const Eigen::Vector3d target(2.0, 0.0, 0.5);
  EXPECT_NEAR(c.position_error(), (reached.translation() - target).norm(), 1e-9);
  EXPECT_NEAR(c.orientation_error(), angle_between(reached, Eigen::Isometry3d::Identity()), 1e-9);
  EXPECT_GT(c.position_error(), 1.0);
  EXPECT_LT(c.position_error(), 1.6) << "the arm reaches towards the target";
  std::printf("[ measured ] UR5, target 2.06 m away: closest pose %.4f m and %.4f rad off\n", c.position_error(),
              c.orientation_error());
}

TEST_F(KinematicsTest, BadRequestsNameTheirFields) {
  {
    v1::ForwardKinematicsRequest request;
    request.add_joints(0.0);
    v1::ForwardKinematicsResponse response;
    const auto status = fk(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(violation_of(bad_request_violations(status), "robot"), HasSubstr("required"));
  }
  {
    v1::ForwardKinematicsRequest request;
    request.mutable_robot()->set_name("ur5");
    for (double x : {0.0, 0.0, std::nan(""), 0.0, 0.0, 0.0}) request.add_joints(x);
    v1::ForwardKinematicsResponse response;
    const auto violations = bad_request_violations(fk(request, response));
    EXPECT_THAT(violation_of(violations, "joints[2]"), HasSubstr("finite")) << describe(violations);
    request.clear_joints();
    request.add_joints(0.0);
    const auto count = bad_request_violations(fk(request, response));
    EXPECT_THAT(violation_of(count, "joints"), HasSubstr("1 values for a 6-joint robot")) << describe(count);
  }
  {
    v1::InverseKinematicsRequest request;
    request.mutable_robot()->set_name("ur6");
    request.set_restarts(100001);
    request.set_max_solutions(0);
    request.set_position_tolerance(0.0);
    request.set_orientation_tolerance(4.0);
    v1::InverseKinematicsResponse response;
    const auto status = ik(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    const auto violations = bad_request_violations(status);
    EXPECT_THAT(violation_of(violations, "robot.name"), HasSubstr("unknown robot 'ur6'")) << describe(violations);
    EXPECT_THAT(violation_of(violations, "target"), HasSubstr("required")) << describe(violations);
    EXPECT_THAT(violation_of(violations, "restarts"), HasSubstr("at most 100000")) << describe(violations);
    EXPECT_THAT(violation_of(violations, "maxSolutions"), HasSubstr("between 1 and")) << describe(violations);
    EXPECT_THAT(violation_of(violations, "positionTolerance"), HasSubstr("above 0")) << describe(violations);
    EXPECT_THAT(violation_of(violations, "orientationTolerance"), HasSubstr("at most pi")) << describe(violations);
  }
  {  // magnitudes beyond any arm: no pose or error could be computed without overflow
    v1::ForwardKinematicsRequest forward;
    forward.mutable_robot()->set_name("ur5");
    for (double x : {1e300, 0.0, 0.0, 0.0, 0.0, 0.0}) forward.add_joints(x);
    v1::ForwardKinematicsResponse fk_response;
    const auto fk_violations = bad_request_violations(fk(forward, fk_response));
    EXPECT_THAT(violation_of(fk_violations, "joints[0]"), HasSubstr("magnitude of at most")) << describe(fk_violations);
    v1::InverseKinematicsRequest inverse;
    inverse.mutable_robot()->set_name("ur5");
    inverse.mutable_target()->mutable_position()->set_x(1e200);
    v1::InverseKinematicsResponse ik_response;
    const auto ik_violations = bad_request_violations(ik(inverse, ik_response));
    EXPECT_THAT(violation_of(ik_violations, "target.position"), HasSubstr("within 1e+06 m")) << describe(ik_violations);
  }
  {
    v1::InverseKinematicsRequest request;
    request.mutable_robot()->set_name("pa10");
    request.mutable_target()->mutable_orientation()->set_w(2.0);
    v1::InverseKinematicsResponse response;
    const auto violations = bad_request_violations(ik(request, response));
    EXPECT_THAT(violation_of(violations, "target.orientation"), HasSubstr("unit quaternion")) << describe(violations);
  }
}

}  // namespace
}  // namespace geotraj::testing
