// Forward kinematics, the Jacobian (Eqs. 1.8-1.9) and the second-order term (1.10-1.11)
// against Orocos KDL, an independent implementation: the built-in arms and random arms
// (both DH conventions, revolute and prismatic joints with offsets, random base and tool) at
// random configurations. Tolerance 1e-12 relative to the magnitude compared (both sides
// are exact to rounding; the chains are at most 12 joints of links up to ~1.7 m).
// The influence coefficients H[j] = dJ/dq_j are checked against jacobian_dot_qdot and
// against central differences of the Jacobian.
#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainjnttojacdotsolver.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/jntarrayvel.hpp>

#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "kdl_chain.hpp"
#include "random_robot.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::JointJacobian;
using core::JointVector;
using core::RobotModel;
using core::Vector6d;

constexpr double kTol = 1e-12;  // relative to max(1, magnitude)

// |a - b|_inf <= kTol max(1, |b|_inf), printing both.
template <class A, class B>
::testing::AssertionResult Close(const A& a, const B& b, double tol = kTol) {
  const double scale = std::max(1.0, b.cwiseAbs().maxCoeff());
  const double err = (a - b).cwiseAbs().maxCoeff();
  if (err <= tol * scale) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "error " << err << " > " << tol * scale << "\nactual:\n"
                                       << a << "\nexpected:\n"
                                       << b;
}

struct KdlResult {
  Eigen::Isometry3d X_WT;
  Eigen::Matrix<double, 6, Eigen::Dynamic> J;
  Vector6d Jdot_qdot;        ///< KDL's J_dot (hybrid) times q_dot
  Vector6d Jdot_qdot_twist;  ///< KDL's own product (its Twist overload)
};

KdlResult kdl_kinematics(const RobotModel& m, const JointVector& q, const JointVector& q_dot) {
  const KDL::Chain chain = to_kdl_chain(m);
  EXPECT_EQ(chain.getNrOfJoints(), m.dof());
  KdlResult out;
  KDL::Frame F;
  KDL::ChainFkSolverPos_recursive fk(chain);
  EXPECT_EQ(fk.JntToCart(to_kdl(q), F), 0);
  out.X_WT = from_kdl(F);
  KDL::Jacobian J(chain.getNrOfJoints());
  KDL::ChainJntToJacSolver jac(chain);
  EXPECT_EQ(jac.JntToJac(to_kdl(q), J), 0);
  out.J = J.data;  // reference point: the tool origin; reference frame: the chain root (W)
  KDL::ChainJntToJacDotSolver jac_dot(chain);
  jac_dot.setHybridRepresentation();  // frame W, point the tool origin: our convention
  KDL::JntArrayVel qv(to_kdl(q), to_kdl(q_dot));
  KDL::Jacobian J_dot(chain.getNrOfJoints());
  EXPECT_EQ(jac_dot.JntToJacDot(qv, J_dot), 0);
  out.Jdot_qdot = J_dot.data * q_dot;
  KDL::Twist t;
  EXPECT_EQ(jac_dot.JntToJacDot(qv, t), 0);
  out.Jdot_qdot_twist << t.vel.x(), t.vel.y(), t.vel.z(), t.rot.x(), t.rot.y(), t.rot.z();
  return out;
}

// One model at one configuration: FK, J, J_dot q_dot against KDL; H against both.
void check_against_kdl(const RobotModel& m, const JointVector& q, const JointVector& q_dot) {
  SCOPED_TRACE(describe_robot(m, q, q_dot));
  const KdlResult kdl = kdl_kinematics(m, q, q_dot);
  Eigen::Isometry3d X;
  JointJacobian J;
  core::forward_kinematics(m, q, X, J);
  EXPECT_TRUE(Close(X.matrix(), kdl.X_WT.matrix())) << "tool pose X_WT";
  EXPECT_TRUE(Close(core::forward_kinematics(m, q).matrix(), kdl.X_WT.matrix())) << "pose-only overload";
  EXPECT_TRUE(Close(J, kdl.J)) << "Jacobian";
  const Vector6d Jdqd = core::jacobian_dot_qdot(m, q, q_dot);
  EXPECT_TRUE(Close(Jdqd, kdl.Jdot_qdot)) << "J_dot q_dot";
  EXPECT_TRUE(Close(Jdqd, kdl.Jdot_qdot_twist)) << "J_dot q_dot (KDL's Twist overload)";

  // H[j] = dJ/dq_j: sum_j q_dot_j H[j] q_dot is J_dot q_dot (1.11).
  const std::vector<JointJacobian> H = core::influence_hessian(m, q);
  ASSERT_EQ(H.size(), m.dof());
  Vector6d sum = Vector6d::Zero();
  for (std::size_t j = 0; j < H.size(); ++j) sum += q_dot(static_cast<Eigen::Index>(j)) * (H[j] * q_dot);
  EXPECT_TRUE(Close(sum, Jdqd)) << "q_dot^T H q_dot";
}

TEST(KdlCrossCheck, ChainsAgreeAtZeroWithoutOffsets) {
  // A sanity check of the chain construction itself: zero joints of a plain model.
  for (const auto& m : core::builtin_robots()) {
    SCOPED_TRACE(m.name);
    const JointVector zero = JointVector::Zero(static_cast<Eigen::Index>(m.dof()));
    check_against_kdl(m, zero, zero);
  }
}

TEST(KdlCrossCheck, BuiltinRobotsAtRandomConfigurations) {
  std::mt19937_64 rng(kPropertySeed);
  for (const auto& m : core::builtin_robots()) {
    SCOPED_TRACE(m.name);
    check_against_kdl(m, core::home_configuration(m), random_rates(m, rng));
    for (int k = 0; k < 200; ++k) check_against_kdl(m, random_joints(m, rng), random_rates(m, rng));
  }
}

TEST(KdlCrossCheck, RandomRobotsAtRandomConfigurations) {
  std::mt19937_64 rng(kPropertySeed + 1);
  const int cases = property_case_count(500);
  int prismatic = 0, modified = 0;
  for (int k = 0; k < cases; ++k) {
    RobotModel m = random_robot(rng);
    ASSERT_TRUE(core::validate_robot(m).empty());
    modified += m.dh->convention == core::DhConvention::kModified;
    for (const auto& l : m.dh->links) prismatic += l.type == core::JointType::kPrismatic;
    check_against_kdl(m, random_joints(m, rng), random_rates(m, rng));
    if (HasFailure()) break;  // one replayable case is enough
  }
  // The generator covered what it is meant to cover.
  EXPECT_GT(prismatic, 0);
  EXPECT_GT(modified, 0);
  EXPECT_LT(modified, cases);
}

// General chains (URDF-like: rotated origins, arbitrary unit axes, continuous and prismatic
// joints, a flange) against KDL built joint by joint.
TEST(KdlCrossCheck, RandomGeneralChainsAtRandomConfigurations) {
  std::mt19937_64 rng(kPropertySeed + 4);
  const int cases = property_case_count(500);
  int prismatic = 0, continuous = 0, oblique = 0;
  for (int k = 0; k < cases; ++k) {
    RobotModel m = random_general_robot(rng);
    ASSERT_TRUE(core::validate_robot(m).empty());
    for (const auto& j : m.joints) {
      prismatic += j.type == core::JointType::kPrismatic;
      continuous += j.type == core::JointType::kContinuous;
      oblique += j.axis.cwiseAbs().maxCoeff() < 0.99;
    }
    check_against_kdl(m, random_joints(m, rng), random_rates(m, rng));
    if (HasFailure()) break;
  }
  EXPECT_GT(prismatic, 0);
  EXPECT_GT(continuous, 0);
  EXPECT_GT(oblique, 0);
}

// A DH model and the same chain with its table dropped (the general form core::set_dh wrote)
// are one arm: the DH table reaches KDL through KDL's own DH frames, the general chain
// through its joints.
TEST(KdlCrossCheck, DhTablesWrittenAsGeneralChainsAgreeWithKdlsDhFrames) {
  std::mt19937_64 rng(kPropertySeed + 5);
  for (int k = 0; k < property_case_count(200); ++k) {
    RobotModel m = random_robot(rng);
    const JointVector q = random_joints(m, rng), q_dot = random_rates(m, rng);
    RobotModel general = m;
    general.dh.reset();
    SCOPED_TRACE(describe_robot(m, q, q_dot));
    const KdlResult dh = kdl_kinematics(m, q, q_dot);
    const KdlResult joints = kdl_kinematics(general, q, q_dot);
    EXPECT_TRUE(Close(joints.X_WT.matrix(), dh.X_WT.matrix()));
    check_against_kdl(general, q, q_dot);
    if (HasFailure()) break;
  }
}

TEST(KdlCrossCheck, InfluenceCoefficientsMatchCentralDifferencesOfTheJacobian) {
  // H[j] against (J(q + h e_j) - J(q - h e_j)) / 2h with h = 1e-6: truncation h^2 |J'''| / 6
  // ~ 1e-12 and rounding ~ 1e-16 / h = 1e-10 on links of ~1 m, so 1e-8 relative.
  std::mt19937_64 rng(kPropertySeed + 2);
  constexpr double h = 1e-6;
  std::vector<RobotModel> models(core::builtin_robots().begin(), core::builtin_robots().end());
  for (int k = 0; k < 100; ++k) models.push_back(random_robot(rng));
  for (int k = 0; k < 100; ++k) models.push_back(random_general_robot(rng));
  for (const auto& m : models) {
    const JointVector q = random_joints(m, rng);
    SCOPED_TRACE(describe_robot(m, q, q));
    const std::vector<JointJacobian> H = core::influence_hessian(m, q);
    for (std::size_t j = 0; j < m.dof(); ++j) {
      JointVector qp = q, qm = q;
      qp(static_cast<Eigen::Index>(j)) += h;
      qm(static_cast<Eigen::Index>(j)) -= h;
      Eigen::Isometry3d X;
      JointJacobian Jp, Jm;
      core::forward_kinematics(m, qp, X, Jp);
      core::forward_kinematics(m, qm, X, Jm);
      const JointJacobian fd = (Jp - Jm) / (2 * h);
      EXPECT_TRUE(Close(H[j], fd, 1e-8)) << "H[" << j << "]";
    }
    if (HasFailure()) break;
  }
}

TEST(KdlCrossCheck, JacobianMatchesCentralDifferencesOfTheToolPose) {
  // Independent of both implementations' Jacobians: columns from the pose itself,
  // v = dp/dq_j and omega from dR/dq_j R^T (its axial vector).
  std::mt19937_64 rng(kPropertySeed + 3);
  constexpr double h = 1e-6;
  for (int k = 0; k < 200; ++k) {
    const RobotModel m = k % 2 ? random_general_robot(rng) : random_robot(rng);
    const JointVector q = random_joints(m, rng);
    SCOPED_TRACE(describe_robot(m, q, q));
    Eigen::Isometry3d X;
    JointJacobian J;
    core::forward_kinematics(m, q, X, J);
    for (std::size_t j = 0; j < m.dof(); ++j) {
      JointVector qp = q, qm = q;
      qp(static_cast<Eigen::Index>(j)) += h;
      qm(static_cast<Eigen::Index>(j)) -= h;
      const Eigen::Isometry3d Xp = core::forward_kinematics(m, qp), Xm = core::forward_kinematics(m, qm);
      const Eigen::Matrix3d W = (Xp.linear() - Xm.linear()) / (2 * h) * X.linear().transpose();  // [omega]x
      Vector6d col;
      col << (Xp.translation() - Xm.translation()) / (2 * h), 0.5 * (W(2, 1) - W(1, 2)), 0.5 * (W(0, 2) - W(2, 0)),
          0.5 * (W(1, 0) - W(0, 1));
      EXPECT_TRUE(Close(Vector6d(J.col(static_cast<Eigen::Index>(j))), col, 1e-8)) << "column " << j;
    }
    if (HasFailure()) break;
  }
}

}  // namespace
}  // namespace geotraj::test
