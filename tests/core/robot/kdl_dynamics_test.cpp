// Inverse dynamics (core/robot/dynamics.hpp) against Orocos KDL's ChainIdSolver_RNE, an
// independent implementation (link-local spatial algebra where ours works in the world
// frame): the built-in arms and random arms (both DH conventions, general chains with
// oblique axes, prismatic and continuous joints, random base, flange and tool) given random
// link mass properties, at random positions, velocities and accelerations, with a random
// payload and gravity along any direction. Agreement within 1e-9 relative to the torques'
// magnitude (both are exact to rounding).
#include <algorithm>
#include <random>

#include <gtest/gtest.h>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>

#include "core/robot/dynamics.hpp"
#include "core/robot/robot.hpp"
#include "kdl_chain.hpp"
#include "random_robot.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::JointVector;
using core::RobotModel;

constexpr double kTol = 1e-9;  // relative to max(1 N m, the largest torque)

core::DynamicsOptions random_options(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0), mass(0.0, 10.0);
  core::DynamicsOptions o;
  o.gravity = core::kStandardGravity * Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
  o.payload.mass = mass(rng);
  o.payload.center_of_mass = 0.2 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
  return o;
}

JointVector kdl_torques(const KDL::Chain& chain, const JointVector& q, const JointVector& q_dot,
                        const JointVector& q_ddot, const Eigen::Vector3d& gravity) {
  KDL::ChainIdSolver_RNE solver(chain, KDL::Vector(gravity.x(), gravity.y(), gravity.z()));
  KDL::JntArray tau(chain.getNrOfJoints());
  const KDL::Wrenches no_external(chain.getNrOfSegments(), KDL::Wrench::Zero());
  EXPECT_GE(solver.CartToJnt(to_kdl(q), to_kdl(q_dot), to_kdl(q_ddot), no_external, tau), 0);
  JointVector out(static_cast<Eigen::Index>(chain.getNrOfJoints()));
  for (unsigned i = 0; i < chain.getNrOfJoints(); ++i) out(i) = tau(i);
  return out;
}

// The model (its joints' inertials; a DH table dropped: the general chain set_dh wrote) at one
// random state against KDL built joint by joint; the largest torque compared.
double check_against_kdl(const RobotModel& m, std::mt19937_64& rng) {
  const JointVector q = random_joints(m, rng), q_dot = random_rates(m, rng), q_ddot = 2.0 * random_rates(m, rng);
  const core::DynamicsOptions o = random_options(rng);
  RobotModel general = m;
  general.dh.reset();
  SCOPED_TRACE(describe_robot(general, q, q_dot));
  JointVector tau;
  core::inverse_dynamics(m, q, q_dot, q_ddot, o, tau);
  const JointVector expected =
      kdl_torques(general_to_kdl_chain(general, core::Inertial{o.payload.mass, o.payload.center_of_mass, Eigen::Matrix3d::Zero()}), q, q_dot,
                  q_ddot, o.gravity);
  const double scale = std::max(1.0, expected.cwiseAbs().maxCoeff());
  EXPECT_LE((tau - expected).cwiseAbs().maxCoeff(), kTol * scale) << "ours:\n" << tau << "\nKDL:\n" << expected;
  return expected.cwiseAbs().maxCoeff();
}

TEST(KdlDynamics, BuiltinArmsWithRandomMassPropertiesAgree) {
  std::mt19937_64 rng(kPropertySeed + 40);
  for (const RobotModel& builtin : core::builtin_robots()) {
    SCOPED_TRACE(builtin.name);
    const RobotModel m = with_random_inertials(builtin, rng);
    ASSERT_TRUE(core::validate_robot(m).empty());
    double largest = 0.0;
    for (int k = 0; k < 100 && !HasFailure(); ++k) largest = std::max(largest, check_against_kdl(m, rng));
    EXPECT_GT(largest, 1.0) << "the states load the joints";
  }
}

TEST(KdlDynamics, RandomDhArmsAgree) {
  std::mt19937_64 rng(kPropertySeed + 41);
  for (int k = 0; k < property_case_count(300) && !HasFailure(); ++k)
    check_against_kdl(with_random_inertials(random_robot(rng), rng), rng);
}

TEST(KdlDynamics, RandomGeneralChainsAgree) {
  std::mt19937_64 rng(kPropertySeed + 42);
  int prismatic = 0;
  for (int k = 0; k < property_case_count(300) && !HasFailure(); ++k) {
    const RobotModel m = with_random_inertials(random_general_robot(rng), rng);
    for (const auto& j : m.joints) prismatic += j.type == core::JointType::kPrismatic;
    check_against_kdl(m, rng);
  }
  EXPECT_GT(prismatic, 0);
}

// Mass properties written on a standard DH table's rows (in frame i, as DH tables give them)
// reach the joints through set_dh: against KDL's own DH frames, whose segment tips are frame i.
TEST(KdlDynamics, StandardDhRowsCarryTheirMassPropertiesInFrameI) {
  std::mt19937_64 rng(kPropertySeed + 43);
  int checked = 0;
  for (int k = 0; k < property_case_count(300) && !HasFailure(); ++k) {
    RobotModel m = random_robot(rng);
    if (m.dh->convention != core::DhConvention::kStandard) continue;
    core::DhTable table = *m.dh;
    for (core::DhLink& l : table.links) l.inertial = random_inertial(rng);
    core::set_dh(m, table);
    ASSERT_TRUE(core::validate_robot(m).empty());
    const JointVector q = random_joints(m, rng), q_dot = random_rates(m, rng), q_ddot = random_rates(m, rng);
    core::DynamicsOptions o;
    o.gravity = core::kStandardGravity * Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
    JointVector tau;
    core::inverse_dynamics(m, q, q_dot, q_ddot, o, tau);
    const JointVector expected = kdl_torques(dh_to_kdl_chain(m), q, q_dot, q_ddot, o.gravity);
    SCOPED_TRACE(describe_robot(m, q, q_dot));
    EXPECT_LE((tau - expected).cwiseAbs().maxCoeff(), kTol * std::max(1.0, expected.cwiseAbs().maxCoeff()));
    ++checked;
  }
  EXPECT_GT(checked, 50);
}

}  // namespace
}  // namespace geotraj::test
