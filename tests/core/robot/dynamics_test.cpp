// Inverse dynamics (core/robot/dynamics.hpp) against physics computed here from the links'
// poses alone: the energy balance (the work of the torques along a motion equals the change
// of kinetic plus potential energy), the gravity torques by virtual work, a payload as the
// point mass it is, a symmetric positive definite mass matrix; no heap allocation; mass
// properties refused by field.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "core/robot/dynamics.hpp"
#include "core/robot/robot.hpp"
#include "random_robot.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::JointVector;
using core::RobotModel;
using Eigen::Isometry3d;
using Eigen::Matrix3d;
using Eigen::Vector3d;

// Every link's frame in W at q (robot.hpp's chain, composed here: base * O_1 M_1 ... O_i M_i).
std::vector<Isometry3d> link_frames(const RobotModel& m, const JointVector& q) {
  std::vector<Isometry3d> out;
  Isometry3d X = m.base;
  for (std::size_t i = 0; i < m.dof(); ++i) {
    const core::Joint& j = m.joints[i];
    const double v = q(static_cast<Eigen::Index>(i));
    X = X * j.origin;
    if (core::turns(j.type))
      X = X * Eigen::AngleAxisd(v, j.axis);
    else
      X = X * Eigen::Translation3d(v * j.axis);
    out.push_back(X);
  }
  return out;
}

// A smooth motion: q_i(t) = c_i + A_i sin(w_i t + phi_i).
struct Motion {
  JointVector centre, amplitude, rate, phase;
  JointVector q(double t) const {
    return centre + amplitude.cwiseProduct((rate * t + phase).array().sin().matrix());
  }
  JointVector q_dot(double t) const {
    return amplitude.cwiseProduct(rate).cwiseProduct((rate * t + phase).array().cos().matrix());
  }
  JointVector q_ddot(double t) const {
    return -amplitude.cwiseProduct(rate).cwiseProduct(rate).cwiseProduct((rate * t + phase).array().sin().matrix());
  }
};

Motion random_motion(const RobotModel& m, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> amplitude(0.2, 0.8), rate(1.0, 4.0), phase(-3.0, 3.0);
  const auto n = static_cast<Eigen::Index>(m.dof());
  Motion out{random_joints(m, rng), JointVector(n), JointVector(n), JointVector(n)};
  for (Eigen::Index i = 0; i < n; ++i) {
    out.amplitude(i) = amplitude(rng) * (m.joints[static_cast<std::size_t>(i)].type == core::JointType::kPrismatic ? 0.3 : 1.0);
    out.rate(i) = rate(rng);
    out.phase(i) = phase(rng);
  }
  return out;
}

// Kinetic plus potential energy [J] of the links and the payload at time t, their velocities
// by central differences of the poses (h = 1e-5 s: error ~1e-10 of the energy).
double energy(const RobotModel& m, const Motion& motion, double t, const core::DynamicsOptions& o) {
  constexpr double h = 1e-5;
  const auto before = link_frames(m, motion.q(t - h)), now = link_frames(m, motion.q(t)),
             after = link_frames(m, motion.q(t + h));
  double E = 0.0;
  const auto point = [&](const Isometry3d& X, const Vector3d& local) { return Vector3d(X * local); };
  const auto add_body = [&](std::size_t i, double mass, const Vector3d& local, const Matrix3d& inertia) {
    const Vector3d v = (point(after[i], local) - point(before[i], local)) / (2.0 * h);
    const Eigen::AngleAxisd turn(after[i].linear() * before[i].linear().transpose());
    const Vector3d w = turn.angle() * turn.axis() / (2.0 * h);
    const Matrix3d I = now[i].linear() * inertia * now[i].linear().transpose();
    E += 0.5 * mass * v.squaredNorm() + 0.5 * w.dot(I * w) - mass * o.gravity.dot(point(now[i], local));
  };
  for (std::size_t i = 0; i < m.dof(); ++i) {
    const core::Inertial& b = *m.joints[i].inertial;
    add_body(i, b.mass, b.center_of_mass, b.inertia);
  }
  add_body(m.dof() - 1, o.payload.mass, m.flange * m.tool * o.payload.center_of_mass, Matrix3d::Zero());
  return E;
}

// Along random motions of random arms, the work of the torques (Simpson's rule, 2,000 steps
// of 0.5 ms) equals the change of energy to 1e-7 of the work done in absolute value.
TEST(Dynamics, TheTorquesWorkIsTheChangeOfEnergy) {
  std::mt19937_64 rng(kPropertySeed + 50);
  for (int k = 0; k < property_case_count(40) && !HasFailure(); ++k) {
    const RobotModel m = with_random_inertials(k % 2 ? random_general_robot(rng) : random_robot(rng), rng);
    const Motion motion = random_motion(m, rng);
    core::DynamicsOptions o;
    o.payload.mass = 3.0;
    o.payload.center_of_mass = Vector3d(0.01, -0.02, 0.05);
    constexpr int kSteps = 2000;
    constexpr double T = 1.0, dt = T / kSteps;
    double work = 0.0, absolute = 0.0;
    JointVector tau;
    for (int s = 0; s <= kSteps; ++s) {
      const double t = s * dt;
      core::inverse_dynamics(m, motion.q(t), motion.q_dot(t), motion.q_ddot(t), o, tau);
      const double power = tau.dot(motion.q_dot(t));
      const double weight = (s == 0 || s == kSteps) ? 1.0 : (s % 2 ? 4.0 : 2.0);
      work += weight * power * dt / 3.0;
      absolute += weight * std::abs(power) * dt / 3.0;
    }
    const double change = energy(m, motion, T, o) - energy(m, motion, 0.0, o);
    SCOPED_TRACE(describe_robot(m, motion.q(0.0), motion.q_dot(0.0)));
    EXPECT_NEAR(work, change, 1e-7 * std::max(1.0, absolute)) << "work " << work << " J, energy change " << change << " J";
  }
}

// At rest the torques hold the weights: tau_i = -sum_k m_k g . dc_k/dq_i (virtual work), the
// centres of mass c_k moved by central differences of the joints.
TEST(Dynamics, AtRestTheTorquesHoldTheWeightsByVirtualWork) {
  std::mt19937_64 rng(kPropertySeed + 51);
  for (const RobotModel& builtin : core::builtin_robots()) {
    SCOPED_TRACE(builtin.name);
    const RobotModel m = with_random_inertials(builtin, rng);
    const JointVector q = random_joints(m, rng), zero = JointVector::Zero(q.size());
    core::DynamicsOptions o;
    o.payload.mass = 2.5;
    o.payload.center_of_mass = Vector3d(0.0, 0.03, 0.08);
    JointVector tau;
    core::inverse_dynamics(m, q, zero, zero, o, tau);
    const auto potential = [&](const JointVector& x) {
      const auto frames = link_frames(m, x);
      double V = 0.0;
      for (std::size_t i = 0; i < m.dof(); ++i)
        V -= m.joints[i].inertial->mass * o.gravity.dot(frames[i] * m.joints[i].inertial->center_of_mass);
      V -= o.payload.mass * o.gravity.dot(frames.back() * (m.flange * m.tool * o.payload.center_of_mass));
      return V;
    };
    for (Eigen::Index i = 0; i < q.size(); ++i) {
      constexpr double h = 1e-6;
      JointVector up = q, down = q;
      up(i) += h;
      down(i) -= h;
      EXPECT_NEAR(tau(i), (potential(up) - potential(down)) / (2.0 * h), 1e-6 * std::max(1.0, tau.cwiseAbs().maxCoeff()))
          << "joint " << i;
    }
  }
}

// A payload is a point mass on the last link: the same torques as that link with the mass
// added to its own (centre of mass and inertia by the parallel-axis theorem).
TEST(Dynamics, APayloadIsAPointMassOnTheLastLink) {
  std::mt19937_64 rng(kPropertySeed + 52);
  for (const RobotModel& builtin : core::builtin_robots()) {
    SCOPED_TRACE(builtin.name);
    RobotModel m = with_random_inertials(builtin, rng);
    m.tool = Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.12));
    const JointVector q = random_joints(m, rng), q_dot = random_rates(m, rng), q_ddot = random_rates(m, rng);
    core::DynamicsOptions o;
    o.payload.mass = 4.0;
    o.payload.center_of_mass = Vector3d(0.02, 0.0, 0.05);
    JointVector with_payload, merged;
    core::inverse_dynamics(m, q, q_dot, q_ddot, o, with_payload);
    core::Inertial& last = *m.joints.back().inertial;
    const Vector3d p = m.flange * m.tool * o.payload.center_of_mass;
    const double total = last.mass + o.payload.mass;
    const Vector3d c = (last.mass * last.center_of_mass + o.payload.mass * p) / total;
    const auto parallel = [](double mass, const Vector3d& r) {
      return Matrix3d(mass * (r.squaredNorm() * Matrix3d::Identity() - r * r.transpose()));
    };
    last.inertia = last.inertia + parallel(last.mass, last.center_of_mass - c) + parallel(o.payload.mass, p - c);
    last.mass = total;
    last.center_of_mass = c;
    o.payload = {};
    core::inverse_dynamics(m, q, q_dot, q_ddot, o, merged);
    EXPECT_LE((with_payload - merged).cwiseAbs().maxCoeff(), 1e-10 * std::max(1.0, merged.cwiseAbs().maxCoeff()));
  }
}

// The mass matrix, column j the torques of q_ddot = e_j without gravity or velocity, is
// symmetric and positive definite.
TEST(Dynamics, TheMassMatrixIsSymmetricPositiveDefinite) {
  std::mt19937_64 rng(kPropertySeed + 53);
  for (int k = 0; k < property_case_count(100); ++k) {
    const RobotModel m = with_random_inertials(random_general_robot(rng), rng);
    const JointVector q = random_joints(m, rng), zero = JointVector::Zero(q.size());
    core::DynamicsOptions o;
    o.gravity.setZero();
    Eigen::MatrixXd M(q.size(), q.size());
    JointVector tau;
    for (Eigen::Index j = 0; j < q.size(); ++j) {
      core::inverse_dynamics(m, q, zero, JointVector::Unit(q.size(), j), o, tau);
      M.col(j) = tau;
    }
    EXPECT_LE((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, M.cwiseAbs().maxCoeff()));
    EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(M).info(), Eigen::Success) << M;
  }
}

TEST(Dynamics, NoHeapAllocationPerCall) {
  std::mt19937_64 rng(kPropertySeed + 54);
  const RobotModel m = with_random_inertials(core::builtin_robots().front(), rng);
  const JointVector q = random_joints(m, rng), q_dot = random_rates(m, rng), q_ddot = random_rates(m, rng);
  const core::DynamicsOptions o;
  JointVector tau(q.size());
  const long before = geotraj::testing::allocation_count();
  for (int k = 0; k < 100; ++k) core::inverse_dynamics(m, q, q_dot, q_ddot, o, tau);
  EXPECT_EQ(geotraj::testing::allocation_count(), before);
}

TEST(Dynamics, MassPropertiesNoBodyHasAreRefusedByField) {
  RobotModel m = core::builtin_robots().front();
  m.dh.reset();
  const auto violation = [&](std::size_t joint, const core::Inertial& in) {
    RobotModel bad = m;
    bad.joints[joint].inertial = in;
    const core::Violations v = core::validate_robot(bad);
    return v.empty() ? std::string() : v.front().field + ": " + v.front().description;
  };
  core::Inertial ok{1.0, Vector3d(0.0, 0.0, 0.1), Matrix3d(Vector3d(0.01, 0.02, 0.025).asDiagonal())};
  EXPECT_EQ(violation(2, ok), "");
  core::Inertial negative = ok;
  negative.mass = -1.0;
  EXPECT_EQ(violation(2, negative).rfind("joints[2].inertial.mass: must be in [0, ", 0), 0u) << violation(2, negative);
  core::Inertial nan = ok;
  nan.center_of_mass.x() = std::nan("");
  EXPECT_EQ(violation(1, nan).rfind("joints[1].inertial.centerOfMass", 0), 0u);
  core::Inertial asymmetric = ok;
  asymmetric.inertia(0, 1) = 0.001;
  EXPECT_EQ(violation(0, asymmetric), "joints[0].inertial.inertia: must be symmetric");
  core::Inertial indefinite = ok;
  indefinite.inertia(0, 0) = -0.01;
  EXPECT_NE(violation(0, indefinite).find("positive semi-definite"), std::string::npos);
  core::Inertial rod = ok;
  rod.inertia = Matrix3d(Vector3d(0.001, 0.001, 0.05).asDiagonal());
  EXPECT_NE(violation(3, rod).find("triangle inequality"), std::string::npos) << violation(3, rod);
  // A DH row's, named by its row.
  RobotModel dh = core::builtin_robots().front();
  ASSERT_TRUE(dh.dh.has_value());
  core::DhTable table = *dh.dh;
  table.links[4].inertial = negative;
  core::set_dh(dh, table);
  const core::Violations v = core::validate_robot(dh);
  ASSERT_FALSE(v.empty());
  EXPECT_EQ(v.front().field, "links[4].inertial.mass");
}

}  // namespace
}  // namespace geotraj::test
