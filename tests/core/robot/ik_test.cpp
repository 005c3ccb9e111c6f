// solve_ik (ik.hpp) in the regimes a round trip does not reach on purpose: an exact seed
// (no iteration), an orientation error near pi, joint limits that exclude the nearest
// solution, a singular target, restarts that are deterministic, and bad input (fewer than
// six joints) that is reported as not converged rather than stopping the process.
#include <cmath>
#include <numbers>
#include <thread>

#include <gtest/gtest.h>

#include "core/planning/joint_motion.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::test {
namespace {

using core::IkOptions;
using core::JointVector;
using core::RobotModel;

const RobotModel& pa10() { return *core::find_builtin_robot("pa10"); }
const RobotModel& ur5() { return *core::find_builtin_robot("ur5"); }

JointVector joints(std::initializer_list<double> v) {
  JointVector q(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double x : v) q(i++) = x;
  return q;
}

/// Residuals of q against the target, by the public forward kinematics.
void expect_solves(const RobotModel& m, const core::IkResult& r, const Eigen::Isometry3d& target) {
  ASSERT_TRUE(r.converged) << r.position_error << " m " << r.orientation_error << " rad";
  const Eigen::Isometry3d X = core::forward_kinematics(m, r.q);
  EXPECT_LE((X.translation() - target.translation()).norm(), 1e-9 + 1e-14);
  EXPECT_LE(Eigen::AngleAxisd(target.linear() * X.linear().transpose()).angle(), 1e-9 + 1e-14);
  EXPECT_TRUE(r.within_limits);
}

TEST(SolveIk, ExactSeedNeedsNoIteration) {
  for (const RobotModel* m : {&pa10(), &ur5()}) {
    const JointVector q = core::home_configuration(*m);
    const core::IkResult r = core::solve_ik(*m, core::forward_kinematics(*m, q), q);
    EXPECT_TRUE(r.converged) << m->name;
    EXPECT_EQ(r.iterations, 0) << m->name;
    EXPECT_EQ(r.q, q) << m->name;
  }
}

// The home of the PA-10 is the thesis's start pose (frame 1 of Table 7.8).
TEST(SolveIk, Pa10HomeIsTheThesisStartPose) {
  const Eigen::Isometry3d X = core::forward_kinematics(pa10(), core::home_configuration(pa10()));
  EXPECT_LE((X.translation() - Eigen::Vector3d(0.106, 0.0, 0.975)).norm(), 1e-6);
  EXPECT_LE((X.linear().col(2) - Eigen::Vector3d::UnitX()).norm(), 1e-6);   // tool z along T = +x
  EXPECT_LE((X.linear().col(1) + Eigen::Vector3d::UnitY()).norm(), 1e-6);   // tool y along N = -y
}

// A target turned by nearly pi about the tool axis from the seed: the rotation vector of
// the error is taken the shorter way round (angle in [0, pi]) and Newton still converges.
TEST(SolveIk, OrientationErrorNearPi) {
  const JointVector q = joints({0.3, 0.4, -0.2, 1.3, 0.5, 0.8, 0.1});
  JointVector seed = q;
  seed(6) += std::numbers::pi - 1e-3;  // the last joint turns the tool about its z axis
  const Eigen::Isometry3d target = core::forward_kinematics(pa10(), q);
  const core::IkResult r = core::solve_ik(pa10(), target, seed);
  expect_solves(pa10(), r, target);
}

// The seed's nearest solution needs joint 0 beyond a (shrunk) limit: the result stays within
// it, converged through the other joints where the redundant arm can (the held joint's
// column leaves J J^T), else not converged, but never outside.
TEST(SolveIk, JointLimitsAreRespected) {
  RobotModel m = pa10();
  const JointVector q = joints({0.9, 0.4, -0.2, 1.3, 0.5, 0.8, 0.1});
  const Eigen::Isometry3d target = core::forward_kinematics(m, q);
  m.limits[0].max_position = 0.8;  // q(0) = 0.9 is outside now
  const core::IkResult r = core::solve_ik(m, target, q);
  EXPECT_TRUE(r.within_limits);
  EXPECT_LE(r.q(0), 0.8);
  expect_solves(m, r, target);  // the self-motion of the PA-10 reaches it with q(0) <= 0.8

  // A non-redundant arm cannot: the limit excludes the only nearby solution.
  RobotModel u = ur5();
  const JointVector qu = joints({0.9, -1.2, 1.4, -1.5, -1.3, 0.4});
  const Eigen::Isometry3d target_u = core::forward_kinematics(u, qu);
  u.limits[0].max_position = 0.8;
  const core::IkResult ru = core::solve_ik(u, target_u, qu);
  EXPECT_TRUE(ru.within_limits);
  EXPECT_LE(ru.q(0), 0.8);
  EXPECT_FALSE(ru.converged);
  EXPECT_GT(ru.position_error + ru.orientation_error, 1e-3);
}

// The seed outside the limits is clamped into them first; a revolute joint whose range
// spans 2 pi (the UR5) comes back inside by a whole turn, the same pose.
TEST(SolveIk, SeedOutsideLimits) {
  const JointVector q = joints({0.3, 0.4, -0.2, 1.3, 0.5, 0.8, 0.1});
  JointVector seed = q;
  seed(1) = 3.0;  // beyond S2's 94 degrees
  const Eigen::Isometry3d target = core::forward_kinematics(pa10(), q);
  IkOptions options;
  options.restarts = 10;
  const core::IkResult r = core::solve_ik(pa10(), target, seed, options);
  expect_solves(pa10(), r, target);
}

// The PA-10 stretched straight up (q = 0) is singular (J J^T loses rank: the shoulder and
// the wrist rolls are aligned): the damped steps keep the iteration finite and it converges
// to a nearby pose from a perturbed seed.
TEST(SolveIk, SingularTarget) {
  const JointVector q = JointVector::Zero(7);
  core::JointJacobian J;
  Eigen::Isometry3d target;
  core::forward_kinematics(pa10(), q, target, J);
  EXPECT_LT(core::manipulability(J), 1e-12);
  JointVector seed = q;
  seed << 0.05, -0.04, 0.03, 0.06, -0.02, 0.05, 0.01;
  const core::IkResult r = core::solve_ik(pa10(), target, seed);
  EXPECT_TRUE(r.q.allFinite());
  EXPECT_TRUE(r.within_limits);
  expect_solves(pa10(), r, target);
}

// The seed sits across the gap of S1's range (+-177 deg) from the solution: Newton from it
// cannot get there (S1 is held at its limit); restarts from random configurations within the
// limits can, and they are the same on every call.
TEST(SolveIk, RestartsAreDeterministic) {
  const JointVector q = joints({2.801, 0.142, 1.487, -0.007, -0.707, 0.795, 3.798});
  const JointVector seed = joints({-3.0, 0.142, 1.487, 0.15, -0.707, 0.795, 3.798});
  const Eigen::Isometry3d target = core::forward_kinematics(pa10(), q);
  IkOptions options;
  const core::IkResult alone = core::solve_ik(pa10(), target, seed, options);
  EXPECT_FALSE(alone.converged);
  EXPECT_TRUE(alone.within_limits);
  options.restarts = 10;
  const core::IkResult a = core::solve_ik(pa10(), target, seed, options);
  const core::IkResult b = core::solve_ik(pa10(), target, seed, options);
  EXPECT_EQ(a.q, b.q);
  EXPECT_EQ(a.iterations, b.iterations);
  expect_solves(pa10(), a, target);
  EXPECT_GT(a.iterations, options.max_iterations);  // it took a restart
}

// Bad input: fewer than six joints cannot reach a general pose. The result is "not
// converged" at the seed (no iteration), not a crash; the tracker says the same.
TEST(SolveIk, FewerThanSixJointsIsNotConverged) {
  RobotModel m = pa10();
  core::DhTable t = *m.dh;
  t.links.resize(5);
  core::set_dh(m, std::move(t));
  m.limits.resize(5);
  m.home.resize(5);
  ASSERT_TRUE(core::validate_robot(m).empty());
  const JointVector seed = core::home_configuration(m);
  const Eigen::Isometry3d target = core::forward_kinematics(pa10(), core::home_configuration(pa10()));
  const core::IkResult r = core::solve_ik(m, target, seed);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(r.q, seed);
  EXPECT_GT(r.position_error, 0.0);
  EXPECT_TRUE(std::isfinite(r.orientation_error));
  EXPECT_TRUE(r.within_limits);

  core::JointTracker tracker(m, seed);
  core::CartesianState x;
  x.X_WT = target;
  core::JointSample s;
  EXPECT_FALSE(tracker.track(x, s));
  EXPECT_FALSE(s.converged);
}


// The per-call entry points keep each thread's chain of the model they met last
// (detail::cached_chain): a model edited in place, two models taken in turn and other threads
// must each get their own chain's answer, the one a fresh copy of the model gives.
TEST(ForwardKinematics, FollowsAModelEditedInPlaceAndModelsTakenInTurn) {
  const core::JointVector q = (core::JointVector(7) << 0.3, -0.4, 0.2, 1.1, -0.5, 0.7, 0.1).finished();
  RobotModel m = pa10();
  const Eigen::Isometry3d before = core::forward_kinematics(m, q);
  m.tool.translation().z() += 0.1;  // in place: same object, same address
  const Eigen::Isometry3d with_tool = core::forward_kinematics(m, q);
  EXPECT_NEAR((with_tool.translation() - before.translation()).norm(), 0.1, 1e-12);
  m.joints[3].origin.translation().x() += 0.05;
  const RobotModel copy = m;  // a fresh model: what the edited one must give
  EXPECT_TRUE(core::forward_kinematics(m, q).isApprox(core::forward_kinematics(copy, q), 0.0));
  EXPECT_FALSE(core::forward_kinematics(m, q).isApprox(with_tool, 1e-6));
  // Two models in turn, each its own answer every time.
  const core::JointVector q6 = q.head(6);
  const Eigen::Isometry3d ur5_pose = core::forward_kinematics(ur5(), q6);
  for (int k = 0; k < 3; ++k) {
    EXPECT_TRUE(core::forward_kinematics(pa10(), q).isApprox(before, 0.0));
    EXPECT_TRUE(core::forward_kinematics(ur5(), q6).isApprox(ur5_pose, 0.0));
  }
  // Position limits edited in place reach the IK's bounds.
  RobotModel narrow = pa10();
  const auto r = core::solve_ik(narrow, before, q);
  ASSERT_TRUE(r.converged);
  narrow.limits[3].max_position = q(3) - 0.2;  // the solution's joint 3 is now out of range
  const auto narrowed = core::solve_ik(narrow, before, q);
  EXPECT_FALSE(narrowed.within_limits && narrowed.q(3) > narrow.limits[3].max_position)
      << "a stale bound let joint 3 through at " << narrowed.q(3);
  // Another thread: its own chain, the same answer.
  Eigen::Isometry3d other;
  std::thread([&] { other = core::forward_kinematics(copy, q); }).join();
  EXPECT_TRUE(other.isApprox(core::forward_kinematics(copy, q), 0.0));
}

}  // namespace
}  // namespace geotraj::test
