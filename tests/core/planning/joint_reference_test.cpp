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
    Eigen::Isometry3d X;
    JointJacobian J;
    forward_kinematics(model, q, X, J);
    const Eigen::MatrixXd dense = J;
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(dense);
    const Eigen::VectorXd kernel = lu.kernel().col(0).normalized();
    const JointVector n = kernel(0) < 0.0 ? JointVector(-kernel) : JointVector(kernel);
    const IkResult ik = solve_ik(model, x.X_WT, q + 0.2 * std::sin(std::numbers::pi * t) * n, precise);
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

}  // namespace
}  // namespace geotraj::core
