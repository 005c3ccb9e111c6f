// Joints chosen ahead for a whole motion (joint_reference.hpp) and the tracker that follows
// them (JointTracker::set_reference): the spline passes through its samples, rests at both
// ends, and its velocity and acceleration are the derivatives of its positions; on the
// PA-10, a motion tracked with a reference made of other joints of the same poses (the
// self-motion turned 0.2 rad) lands on those joints at the reference's samples and follows
// them between samples, every pose held.
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "core/motion/orientation.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/joint_reference.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"

namespace geotraj::core {
namespace {

TEST(JointReference, PassesThroughItsSamplesRestsAtItsEndsAndIsItsOwnDerivative) {
  std::vector<JointVector> q;
  for (int k = 0; k <= 20; ++k) {
    JointVector x(2);
    x << std::sin(0.3 * k), 0.01 * k * k;
    q.push_back(x);
  }
  const JointReference ref(q, 0.05);
  EXPECT_NEAR(ref.duration(), 1.0, 1e-15);
  JointVector p, v, a;
  for (int k = 0; k <= 20; ++k) {
    ref.at(0.05 * k, p, v, a);
    EXPECT_LT((p - q[static_cast<std::size_t>(k)]).norm(), 1e-13) << k;
  }
  ref.at(0.0, p, v, a);
  EXPECT_LT(v.norm(), 1e-12) << "at rest at the start";
  ref.at(1.0, p, v, a);
  EXPECT_LT(v.norm(), 1e-12) << "at rest at the end";
  const double h = 1e-6;
  for (const double t : {0.013, 0.26, 0.51, 0.777, 0.99}) {  // inside intervals: one cubic
    JointVector pm, vm, am, pp, vp, ap;
    ref.at(t - h, pm, vm, am);
    ref.at(t + h, pp, vp, ap);
    ref.at(t, p, v, a);
    EXPECT_LT((v - (pp - pm) / (2 * h)).norm(), 1e-6) << t;
    EXPECT_LT((a - (vp - vm) / (2 * h)).norm(), 1e-5) << t;
  }
  // C2 at the samples: the acceleration is continuous through each knot.
  for (const double t : {0.25, 0.5, 0.75}) {
    JointVector pm, vm, am, pp, vp, ap;
    ref.at(t - 1e-9, pm, vm, am);
    ref.at(t + 1e-9, pp, vp, ap);
    EXPECT_LT((ap - am).norm(), 1e-6) << t;
  }
}

// A 7-joint arm's self-motion direction at q: the unit vector of J(q)'s null space (its first
// coordinate >= 0).
JointVector self_motion(const RobotModel& model, const JointVector& q) {
  Eigen::Isometry3d X;
  JointJacobian J;
  forward_kinematics(model, q, X, J);
  const Eigen::MatrixXd dense = J;
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(dense);
  const Eigen::VectorXd kernel = lu.kernel().col(0).normalized();
  return kernel(0) < 0.0 ? JointVector(-kernel) : JointVector(kernel);
}

TEST(JointReference, ATrackerFollowsTheJointsChosenAhead) {
  const RobotModel& model = *find_builtin_robot("pa10");
  JointVector a(7), b(7);
  a << 0.1, 0.5, 0.2, 1.2, -0.3, 0.6, 0.1;
  b << 0.5, 0.3, -0.1, 1.5, 0.2, 0.3, -0.3;
  const double dt = 0.01;
  const int K = 200;
  std::vector<CartesianState> states;
  std::vector<JointVector> chosen;
  IkOptions precise;
  precise.position_tolerance = precise.orientation_tolerance = 1e-12;
  for (int k = 0; k <= K; ++k) {
    const double t = static_cast<double>(k) / K, blend = t * t * t * (10 - 15 * t + 6 * t * t);
    const JointVector q = a + blend * (b - a);
    CartesianState x;
    x.t = k * dt;
    x.X_WT = forward_kinematics(model, q);
    states.push_back(x);
    // The same pose with the self-motion turned by 0.2 sin(pi t) rad (0 at both ends).
    const IkResult ik =
        solve_ik(model, x.X_WT, q + 0.2 * std::sin(std::numbers::pi * t) * self_motion(model, q), precise);
    ASSERT_TRUE(ik.converged);
    chosen.push_back(k == 0 ? q : ik.q);
  }
  // The tool's velocities and accelerations by differences of the poses are not needed: the
  // tracker's positions are what is checked.
  const JointReference ref(chosen, dt);
  JointTracker tracker(model, a);
  tracker.set_reference(&ref);
  JointSample s;
  double worst = 0.0;
  for (int k = 0; k <= K; ++k) {
    ASSERT_TRUE(tracker.track(states[static_cast<std::size_t>(k)], s)) << k;
    worst = std::max(worst, (s.q - chosen[static_cast<std::size_t>(k)]).cwiseAbs().maxCoeff());
    EXPECT_LE(s.position_error, 1e-9);
  }
  EXPECT_LT(worst, 1e-9) << "on the joints chosen at their samples";
  // Without the reference the tracker chooses its own self-motion, far from those joints.
  JointTracker own(model, a);
  double apart = 0.0;
  for (int k = 0; k <= K; ++k) {
    ASSERT_TRUE(own.track(states[static_cast<std::size_t>(k)], s));
    apart = std::max(apart, (s.q - chosen[static_cast<std::size_t>(k)]).cwiseAbs().maxCoeff());
  }
  EXPECT_GT(apart, 0.05);
}

// In arc length (a redundant arm's joints chosen along a path, to be timed along them): the
// natural spline (q_ss = 0 at both ends) through its samples; a tracker following it lands on
// the samples whatever the timing (the samples reached at other times), and its null-space
// velocity is q_s(s) s_dot: with the tool's twist J q_s s_dot, the joint velocity is exactly
// the reference's.
TEST(JointReference, InArcLengthAnyTimingOfThePathFollowsIt) {
  const RobotModel& model = *find_builtin_robot("pa10");
  JointVector a(7), b(7);
  a << 0.1, 0.5, 0.2, 1.2, -0.3, 0.6, 0.1;
  b << 0.5, 0.3, -0.1, 1.5, 0.2, 0.3, -0.3;
  const int K = 200;
  const double L = 0.8;  // [m]
  IkOptions precise;
  precise.position_tolerance = precise.orientation_tolerance = 1e-12;
  std::vector<JointVector> chosen;
  std::vector<Eigen::Isometry3d> poses;
  for (int k = 0; k <= K; ++k) {
    const double f = static_cast<double>(k) / K;
    const JointVector q = a + (f * f * (3 - 2 * f)) * (b - a);
    poses.push_back(forward_kinematics(model, q));
    const IkResult ik =
        solve_ik(model, poses.back(), q + 0.2 * std::sin(std::numbers::pi * f) * self_motion(model, q), precise);
    ASSERT_TRUE(ik.converged);
    chosen.push_back(k == 0 ? q : ik.q);
  }
  const JointReference ref(chosen, L / K, ReferenceParameter::kArcLength);
  EXPECT_EQ(ref.over(), ReferenceParameter::kArcLength);
  EXPECT_NEAR(ref.duration(), L, 1e-15);
  JointVector p, v, acc;
  for (const double s : {0.0, L}) {
    ref.at(s, p, v, acc);
    EXPECT_LT(acc.norm(), 1e-12) << "natural at s = " << s;
    EXPECT_GT(v.norm(), 1e-3) << "not at rest in s";
  }
  // Two timings of the same path: constant speed over 2 s, and s = L (t / 3)^2 (from rest).
  for (const int timing : {0, 1}) {
    SCOPED_TRACE(timing);
    JointTracker tracker(model, a);
    tracker.set_reference(&ref);
    JointSample js;
    double worst = 0.0, worst_rate = 0.0;
    for (int k = 0; k <= K; ++k) {
      const double s = L * k / K;
      CartesianState x;
      x.t = timing == 0 ? 2.0 * k / K : 3.0 * std::sqrt(static_cast<double>(k) / K);
      x.s = s;
      x.s_dot = timing == 0 ? L / 2.0 : 2.0 * L * x.t / 9.0;
      x.s_ddot = timing == 0 ? 0.0 : 2.0 * L / 9.0;
      x.X_WT = poses[static_cast<std::size_t>(k)];
      ref.at(s, p, v, acc);
      Eigen::Isometry3d X;
      JointJacobian J;
      forward_kinematics(model, chosen[static_cast<std::size_t>(k)], X, J);
      const Eigen::Matrix<double, 6, 1> twist = J * (v * x.s_dot);
      x.v_WT = twist.head<3>();
      x.omega_WT = twist.tail<3>();
      ASSERT_TRUE(tracker.track(x, js)) << k;
      worst = std::max(worst, (js.q - chosen[static_cast<std::size_t>(k)]).cwiseAbs().maxCoeff());
      if (k > 0) worst_rate = std::max(worst_rate, (js.q_dot - v * x.s_dot).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(worst, 1e-9) << "on the joints chosen at their arc lengths";
    EXPECT_LT(worst_rate, 1e-9) << "the joint velocity is q_s s_dot";
  }
}

// The tool turned about its own axis (robot.toolAxisFree): the angular velocity and
// acceleration roll_about_tool_axis gives are the derivatives of the orientation it gives
// (central differences), the axis and the translational state untouched.
TEST(ToolRoll, TheTurnedStateIsItsOwnDerivative) {
  const Eigen::Vector3d a = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();  // the planned turn's axis in W
  const auto planned = [&](double t) {  // R(t) = RotZ0 RotA(theta(t)): omega = theta_dot a, alpha = theta_ddot a
    CartesianState x;
    x.t = t;
    const double theta = 0.7 * t + 0.4 * t * t;
    x.X_WT.linear() = Eigen::AngleAxisd(theta, a).toRotationMatrix() * Eigen::AngleAxisd(0.9, Eigen::Vector3d::UnitX());
    x.X_WT.translation() = Eigen::Vector3d(0.1, 0.2, 0.3 * t);
    x.v_WT = Eigen::Vector3d(0.0, 0.0, 0.3);
    x.omega_WT = (0.7 + 0.8 * t) * a;
    x.alpha_WT = 0.8 * a;
    return x;
  };
  const auto turned = [&](double t) {
    CartesianState x = planned(t);
    roll_about_tool_axis(x, std::sin(2.0 * t), 2.0 * std::cos(2.0 * t), -4.0 * std::sin(2.0 * t));
    return x;
  };
  const auto vee = [](const Eigen::Matrix3d& S) { return Eigen::Vector3d(S(2, 1), S(0, 2), S(1, 0)); };
  const double h = 1e-5;
  for (const double t : {0.0, 0.3, 1.1, 2.5}) {
    const CartesianState x = turned(t), p = planned(t);
    EXPECT_LT((x.X_WT.linear().col(2) - p.X_WT.linear().col(2)).norm(), 1e-15) << "the axis as planned";
    EXPECT_EQ(x.X_WT.translation(), p.X_WT.translation());
    EXPECT_EQ(x.v_WT, p.v_WT);
    const Eigen::Matrix3d R_dot = (turned(t + h).X_WT.linear() - turned(t - h).X_WT.linear()) / (2.0 * h);
    EXPECT_LT((vee(R_dot * x.X_WT.linear().transpose()) - x.omega_WT).norm(), 1e-8) << t;
    EXPECT_LT(((turned(t + h).omega_WT - turned(t - h).omega_WT) / (2.0 * h) - x.alpha_WT).norm(), 1e-8) << t;
    const Eigen::AngleAxisd roll(p.X_WT.linear().transpose() * x.X_WT.linear());
    EXPECT_NEAR(roll.angle() * roll.axis().z(), std::sin(2.0 * t), 1e-12) << "R' = R RotZ(phi)";
  }
}

// A path's roll as a function of its arc length: the natural spline passes through its
// values, and its derivatives are those of its values (central differences).
TEST(ToolRoll, TheRollAlongAPathIsItsOwnDerivative) {
  std::vector<double> phi;
  for (int m = 0; m <= 40; ++m) phi.push_back(std::sin(0.2 * m) + 0.01 * m * m);
  const RollProfile roll(phi, 0.8);
  double p = 0.0, p_s = 0.0, p_ss = 0.0;
  for (int m = 0; m <= 40; ++m) {
    roll.at(0.02 * m, p, p_s, p_ss);
    EXPECT_NEAR(p, phi[static_cast<std::size_t>(m)], 1e-12) << m;
  }
  roll.at(0.0, p, p_s, p_ss);
  EXPECT_NEAR(p_ss, 0.0, 1e-12) << "natural at its ends";
  const double h = 1e-6;
  for (const double s : {0.013, 0.251, 0.51, 0.777}) {  // inside intervals: one cubic
    double a = 0.0, a_s = 0.0, a_ss = 0.0, b = 0.0, b_s = 0.0, b_ss = 0.0;
    roll.at(s, p, p_s, p_ss);
    roll.at(s - h, a, a_s, a_ss);
    roll.at(s + h, b, b_s, b_ss);
    EXPECT_NEAR((b - a) / (2.0 * h), p_s, 1e-7) << s;
    EXPECT_NEAR((b_s - a_s) / (2.0 * h), p_ss, 1e-6) << s;
  }
}

// The arm with its tool's roll as one joint more: its pose is the real arm's turned by the
// roll about the tool's z axis, on every built-in arm and random joints.
TEST(ToolRoll, TheArmWithTheRollIsTheArmTurnedAboutItsToolAxis) {
  for (const RobotModel& builtin : builtin_robots()) {
    SCOPED_TRACE(builtin.name);
    RobotModel model = builtin;
    model.tool = Eigen::Translation3d(0.01, -0.02, 0.15) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY());
    const ValidRobot tooled = *ValidRobot::check(model);
    const ValidRobot rolled = with_tool_roll(tooled);
    ASSERT_EQ(rolled->dof(), model.dof() + 1);
    EXPECT_EQ(rolled->joints.back().name, kToolRollJoint);
    EXPECT_TRUE(validate_robot(rolled).empty());
    for (int trial = 0; trial < 5; ++trial) {
      const JointVector q = JointVector::Random(static_cast<Eigen::Index>(model.dof()));
      const double phi = 3.0 * Eigen::Matrix<double, 1, 1>::Random()(0);
      JointVector q_rolled(q.size() + 1);
      q_rolled << q, phi;
      const Eigen::Isometry3d expected = forward_kinematics(tooled, q) * Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitZ());
      const Eigen::Isometry3d X = forward_kinematics(rolled, q_rolled);
      EXPECT_LT((X.matrix() - expected.matrix()).norm(), 1e-12);
    }
  }
}

}  // namespace
}  // namespace geotraj::core
