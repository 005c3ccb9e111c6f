// Inverse dynamics (core/robot/dynamics.hpp), one thread, per call, every built-in arm
// (PA-10, UR5, Panda, iiwa 14, UR5e) at 64 random states (positions within the limits,
// velocities and accelerations in [-2, 2] and [-4, 4] per second), cycled, with a 2 kg
// payload: our recursive Newton-Euler beside forward kinematics with the Jacobian (the
// target: within 3x of it) and beside Orocos KDL's ChainIdSolver_RNE on the same arms and
// states (checked equal to ours first, 1e-9). The arms' mass properties are random (fixed
// seed): the cost does not depend on their values.
// Run: build/bench/bench_dynamics --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <algorithm>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>
#if GEOTRAJ_BENCH_KDL
#include <kdl/chain.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>

#include "kdl_chain.hpp"
#endif

#include "core/robot/dynamics.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/robots.hpp"
#include "random_robot.hpp"

namespace {

using namespace geotraj;
using core::JointVector;

// 0 PA-10, 1 UR5 (DH tables); 2 Panda, 3 iiwa 14, 4 UR5e (URDF: general chains).
core::RobotModel arm(int which) {
  static const char* const names[] = {"pa10", "ur5", "panda", "iiwa14", "ur5e"};
  std::mt19937_64 rng(20261207);
  core::RobotModel m = *planner::find_builtin_robot(names[which]);
  for (core::Joint& j : m.joints)
    if (!j.inertial) j.inertial = test::random_inertial(rng);
  return m;
}

struct State {
  JointVector q, q_dot, q_ddot;
};

std::vector<State> random_states(const core::RobotModel& m) {
  std::mt19937_64 rng(20240611);
  std::vector<State> out;
  for (int k = 0; k < 64; ++k)
    out.push_back({test::random_joints(m, rng), test::random_rates(m, rng), 2.0 * test::random_rates(m, rng)});
  return out;
}

core::DynamicsOptions with_payload() {
  core::DynamicsOptions o;
  o.payload.mass = 2.0;
  o.payload.center_of_mass = Eigen::Vector3d(0.0, 0.0, 0.05);
  return o;
}

void BM_InverseDynamics(benchmark::State& state) {
  const core::RobotModel m = arm(static_cast<int>(state.range(0)));
  const auto states = random_states(m);
  const core::DynamicsOptions o = with_payload();
  JointVector tau(static_cast<Eigen::Index>(m.dof()));
  std::size_t k = 0;
  for (auto _ : state) {
    const State& s = states[k++ % states.size()];
    core::inverse_dynamics(m, s.q, s.q_dot, s.q_ddot, o, tau);
    benchmark::DoNotOptimize(tau.data());
  }
  state.SetLabel(m.name);
}
BENCHMARK(BM_InverseDynamics)->DenseRange(0, 4);

// The reference of the target: one FK with the Jacobian per state.
void BM_ForwardKinematicsJacobian(benchmark::State& state) {
  const core::RobotModel m = arm(static_cast<int>(state.range(0)));
  const auto states = random_states(m);
  Eigen::Isometry3d X;
  core::JointJacobian J;
  std::size_t k = 0;
  for (auto _ : state) {
    core::forward_kinematics(m, states[k++ % states.size()].q, X, J);
    benchmark::DoNotOptimize(X);
    benchmark::DoNotOptimize(J);
  }
  state.SetLabel(m.name);
}
BENCHMARK(BM_ForwardKinematicsJacobian)->DenseRange(0, 4);

#if GEOTRAJ_BENCH_KDL
// KDL's chain the way it runs fastest: one segment per joint (its motion, then the next
// joint's origin; the last ends in flange * tool), the link's inertia moved into that
// segment's tip frame (KDL holds it there), the payload on the last segment.
KDL::Chain kdl_chain(const core::RobotModel& m, const core::Payload& payload) {
  KDL::Chain chain;
  chain.addSegment(KDL::Segment(KDL::Joint(KDL::Joint::Fixed), test::to_kdl(m.base * m.joints.front().origin)));
  for (std::size_t i = 0; i < m.dof(); ++i) {
    const core::Joint& j = m.joints[i];
    const Eigen::Isometry3d tip = i + 1 < m.dof() ? m.joints[i + 1].origin : m.flange * m.tool;
    const Eigen::Isometry3d to_tip = tip.inverse();
    const Eigen::Matrix3d R = to_tip.linear();
    core::Inertial in{j.inertial->mass, to_tip * j.inertial->center_of_mass, R * j.inertial->inertia * R.transpose()};
    KDL::RigidBodyInertia I = test::to_kdl(in);
    if (i + 1 == m.dof()) I = I + KDL::RigidBodyInertia(payload.mass, KDL::Vector(payload.center_of_mass.x(),
                                                                                   payload.center_of_mass.y(),
                                                                                   payload.center_of_mass.z()));
    const KDL::Joint joint("", KDL::Vector::Zero(), KDL::Vector(j.axis.x(), j.axis.y(), j.axis.z()),
                           core::turns(j.type) ? KDL::Joint::RotAxis : KDL::Joint::TransAxis);
    chain.addSegment(KDL::Segment(joint, test::to_kdl(tip), I));
  }
  return chain;
}

void BM_KdlInverseDynamics(benchmark::State& state) {
  core::RobotModel m = arm(static_cast<int>(state.range(0)));
  m.dh.reset();  // the general chain set_dh wrote
  const core::DynamicsOptions o = with_payload();
  const KDL::Chain chain = kdl_chain(m, o.payload);
  KDL::ChainIdSolver_RNE solver(chain, KDL::Vector(o.gravity.x(), o.gravity.y(), o.gravity.z()));
  const KDL::Wrenches none(chain.getNrOfSegments(), KDL::Wrench::Zero());
  struct KdlState {
    KDL::JntArray q, q_dot, q_ddot;
  };
  std::vector<KdlState> states;
  KDL::JntArray tau(chain.getNrOfJoints());
  double error = 0.0;
  for (const State& s : random_states(m)) {
    states.push_back({test::to_kdl(s.q), test::to_kdl(s.q_dot), test::to_kdl(s.q_ddot)});
    solver.CartToJnt(states.back().q, states.back().q_dot, states.back().q_ddot, none, tau);
    JointVector ours;
    core::inverse_dynamics(m, s.q, s.q_dot, s.q_ddot, o, ours);
    error = std::max(error, (tau.data - ours).cwiseAbs().maxCoeff() / std::max(1.0, ours.cwiseAbs().maxCoeff()));
  }
  if (!(error <= 1e-9)) state.SkipWithError("KDL's chain does not match the model");
  std::size_t k = 0;
  for (auto _ : state) {
    const KdlState& s = states[k++ % states.size()];
    solver.CartToJnt(s.q, s.q_dot, s.q_ddot, none, tau);
    benchmark::DoNotOptimize(tau.data.data());
  }
  state.counters["max_difference"] = error;
  state.SetLabel(m.name + ", KDL ChainIdSolver_RNE");
}
BENCHMARK(BM_KdlInverseDynamics)->DenseRange(0, 4);
#endif

}  // namespace

BENCHMARK_MAIN();
