// Kinematics with closed forms as oracles: a planar 2R arm (both DH conventions) and a
// polar R-P arm (a prismatic joint). Position, Jacobian (1.8-1.9) and J_dot q_dot (1.11)
// against the formulas, to 1e-13 m (a few ulps of unit-length links).
#include <array>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::test {
namespace {

using core::DhConvention;
using core::JointJacobian;
using core::JointType;
using core::JointVector;
using core::RobotModel;
using core::Vector6d;
using Eigen::Vector3d;

constexpr double kTol = 1e-13;

core::JointLimits wide() { return {-10.0, 10.0, 1.0, 1.0, std::nullopt}; }

JointVector joints(double a, double b) {
  JointVector q(2);
  q << a, b;
  return q;
}

// Planar 2R in the x-y plane, links l1, l2: standard DH rows (a = l_i, alpha = 0).
RobotModel planar_2r_standard(double l1, double l2) {
  RobotModel m;
  core::set_dh(m, {DhConvention::kStandard, {{l1, 0.0, 0.0, 0.0}, {l2, 0.0, 0.0, 0.0}}});
  m.limits = {wide(), wide()};
  return m;
}

// The same arm in modified DH (Eq. 1.3): row i holds the length BEFORE joint i, so the
// second link's length is the tool's offset along x.
RobotModel planar_2r_modified(double l1, double l2) {
  RobotModel m;
  core::set_dh(m, {DhConvention::kModified, {{0.0, 0.0, 0.0, 0.0}, {l1, 0.0, 0.0, 0.0}}});
  m.limits = {wide(), wide()};
  m.tool.translation() = Vector3d(l2, 0.0, 0.0);
  return m;
}

void check_planar_2r(const RobotModel& m, double l1, double l2) {
  for (const auto& [q1, q2, w1, w2] : {std::array<double, 4>{0.3, -1.1, 0.7, -0.4}, {2.0, 0.5, -1.5, 2.5},
                                       {-0.8, 3.0, 0.0, 1.0}, {0.0, 0.0, 1.0, 1.0}}) {
    SCOPED_TRACE(::testing::Message() << "q = (" << q1 << ", " << q2 << "), q_dot = (" << w1 << ", " << w2 << ")");
    const double c1 = std::cos(q1), s1 = std::sin(q1), c12 = std::cos(q1 + q2), s12 = std::sin(q1 + q2);
    Eigen::Isometry3d X;
    JointJacobian J;
    core::forward_kinematics(m, joints(q1, q2), X, J);
    EXPECT_LE((X.translation() - Vector3d(l1 * c1 + l2 * c12, l1 * s1 + l2 * s12, 0.0)).norm(), kTol);
    EXPECT_LE((X.linear() - Eigen::AngleAxisd(q1 + q2, Vector3d::UnitZ()).toRotationMatrix()).norm(), kTol);
    Eigen::Matrix<double, 6, 2> J_expected;
    J_expected << -l1 * s1 - l2 * s12, -l2 * s12,  //
        l1 * c1 + l2 * c12, l2 * c12,              //
        0, 0,                                      //
        0, 0,                                      //
        0, 0,                                      //
        1, 1;
    EXPECT_LE((J - J_expected).cwiseAbs().maxCoeff(), kTol) << J;
    // a = d/dt(J q_dot) at q_ddot = 0: centripetal terms of each link.
    Vector6d a_expected;
    const double w12 = w1 + w2;
    a_expected << -l1 * c1 * w1 * w1 - l2 * c12 * w12 * w12, -l1 * s1 * w1 * w1 - l2 * s12 * w12 * w12, 0, 0, 0, 0;
    EXPECT_LE((core::jacobian_dot_qdot(m, joints(q1, q2), joints(w1, w2)) - a_expected).cwiseAbs().maxCoeff(), kTol);
    EXPECT_NEAR(core::manipulability(J), 0.0, kTol);  // planar: rank 3 of 6
  }
}

TEST(KinematicsClosedForm, Planar2RStandardDh) { check_planar_2r(planar_2r_standard(0.7, 0.4), 0.7, 0.4); }

TEST(KinematicsClosedForm, Planar2RModifiedDh) { check_planar_2r(planar_2r_modified(0.7, 0.4), 0.7, 0.4); }

// Polar R-P arm: joint 1 turns about z0; standard DH alpha = pi/2 turns z1 to
// (sin q1, -cos q1, 0); joint 2 slides along it from d = r0 (offset o): r = r0 + o + q2 and
//   p = r (sin q1, -cos q1, 0).
TEST(KinematicsClosedForm, PolarArmWithAPrismaticJoint) {
  const double r0 = 0.3, o = 0.05;
  RobotModel m;
  core::DhLink rev{0.0, std::numbers::pi / 2, 0.0, 0.0};
  core::DhLink pri{0.0, 0.0, r0, 0.0, JointType::kPrismatic, o};
  core::set_dh(m, {DhConvention::kStandard, {rev, pri}});
  m.limits = {wide(), wide()};
  ASSERT_TRUE(core::validate_robot(m).empty());
  for (const auto& [q1, q2, w1, w2] : {std::array<double, 4>{0.4, 0.2, 1.3, -0.6}, {-2.2, -0.1, -0.5, 0.9}}) {
    const double c = std::cos(q1), s = std::sin(q1), r = r0 + o + q2;
    Eigen::Isometry3d X;
    JointJacobian J;
    core::forward_kinematics(m, joints(q1, q2), X, J);
    EXPECT_LE((X.translation() - Vector3d(r * s, -r * c, 0.0)).norm(), kTol);
    Eigen::Matrix<double, 6, 2> J_expected;
    J_expected << r * c, s,  // z0 x p, then the sliding axis
        r * s, -c,           //
        0, 0,                //
        0, 0,                //
        0, 0,                //
        1, 0;
    EXPECT_LE((J - J_expected).cwiseAbs().maxCoeff(), kTol) << J;
    // p_ddot at q_ddot = 0: Coriolis 2 r_dot q1_dot (c, s, 0) and centripetal r q1_dot^2 (-s, c, 0).
    Vector6d a_expected;
    a_expected << 2 * w2 * w1 * c - r * w1 * w1 * s, 2 * w2 * w1 * s + r * w1 * w1 * c, 0, 0, 0, 0;
    EXPECT_LE((core::jacobian_dot_qdot(m, joints(q1, q2), joints(w1, w2)) - a_expected).cwiseAbs().maxCoeff(), kTol);
  }
}

TEST(KinematicsClosedForm, BaseAndToolCompose) {
  // X_WT = base * A_1 ... A_n * tool: moving the base moves the whole chain rigidly.
  RobotModel m = planar_2r_standard(0.7, 0.4);
  const JointVector q = joints(0.3, -0.2);
  const Eigen::Isometry3d plain = core::forward_kinematics(m, q);
  m.base = Eigen::Translation3d(1.0, -2.0, 0.5) * Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized());
  m.tool = Eigen::Translation3d(0.0, 0.0, 0.1) * Eigen::AngleAxisd(-0.4, Vector3d::UnitY());
  const Eigen::Isometry3d moved = core::forward_kinematics(m, q);
  EXPECT_LE((moved.matrix() - (m.base * plain * m.tool).matrix()).cwiseAbs().maxCoeff(), kTol);
}

}  // namespace
}  // namespace geotraj::test
