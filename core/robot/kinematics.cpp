// Forward kinematics and Jacobians of a serial chain (thesis 1.1.2-1.1.3). See kinematics.hpp.
#include "core/robot/kinematics.hpp"

#include <cmath>

#include <Eigen/SVD>

#include "core/robot/serial_chain.hpp"

namespace geotraj::core {
namespace {

// The tool pose and joint axes at q, by the precomputed chain (serial_chain.hpp, shared with
// the IK, kept per thread: cached_chain): z_i unit axis of joint i, o_i the origin of its
// frame, in W (robot.hpp: the frame O_i ends in; modified DH (1.3): frame i, reached after
// RotX(alpha_i) TransX(a_i); standard DH: frame i-1).
struct Axes {
  Eigen::Matrix3d R_WT;
  Eigen::Vector3d p_WT;
  detail::JointAxes z, o;
  JointJacobian J;
};

Axes axes_at(const RobotModel& model, const JointVector& q) {
  GEOTRAJ_CHECK(q.size() == static_cast<Eigen::Index>(model.dof()));
  Axes a;
  detail::cached_chain(model).jacobian(q, a.R_WT, a.p_WT, a.z, a.o, a.J);
  return a;
}

Eigen::Isometry3d isometry(const Eigen::Matrix3d& R, const Eigen::Vector3d& p) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = R;
  X.translation() = p;
  return X;
}

}  // namespace

Eigen::Isometry3d forward_kinematics(const RobotModel& model, const JointVector& q) {
  GEOTRAJ_CHECK(q.size() == static_cast<Eigen::Index>(model.dof()));
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  detail::cached_chain(model).pose(q, R, p);
  return isometry(R, p);
}

void forward_kinematics(const RobotModel& model, const JointVector& q, Eigen::Isometry3d& X_WT, JointJacobian& J) {
  Axes a = axes_at(model, q);  // (1.9): revolute [z_i x (p - o_i); z_i], prismatic [z_i; 0]
  X_WT = isometry(a.R_WT, a.p_WT);
  J = a.J;
}

std::vector<JointAxis> joint_axes(const RobotModel& model, const JointVector& q) {
  const Axes a = axes_at(model, q);
  std::vector<JointAxis> out(model.dof());
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = {a.o.col(static_cast<Eigen::Index>(i)), a.z.col(static_cast<Eigen::Index>(i))};
  }
  return out;
}

Eigen::VectorXd singular_values(const JointJacobian& J) {
  return Eigen::JacobiSVD<Eigen::MatrixXd>(Eigen::MatrixXd(J)).singularValues();
}

Vector6d jacobian_dot_qdot(const RobotModel& model, const JointVector& q, const JointVector& q_dot) {
  GEOTRAJ_CHECK(q_dot.size() == static_cast<Eigen::Index>(model.dof()));
  const detail::SerialChain& chain = detail::cached_chain(model);
  Axes a;
  chain.jacobian(q, a.R_WT, a.p_WT, a.z, a.o, a.J);
  JointJacobian J_dot;
  chain.jacobian_dot(a.p_WT, a.z, a.o, a.J, q_dot, J_dot);  // (1.10, 1.11)
  return J_dot * q_dot;
}

std::vector<JointJacobian> influence_hessian(const RobotModel& model, const JointVector& q) {
  // H[j] = dJ/dq_j. Axis i moves with joint j only when j < i (j's motion carries i):
  //   revolute j: dz_i/dq_j = z_j x z_i, do_i/dq_j = z_j x (o_i - o_j);
  //   prismatic j: dz_i/dq_j = 0,        do_i/dq_j = z_j;
  // and the tool point moves with every joint: dp/dq_j = J_v column j.
  const Axes axes = axes_at(model, q);
  const auto n = static_cast<Eigen::Index>(model.dof());
  const Eigen::Vector3d p = axes.p_WT;
  auto revolute = [&](Eigen::Index i) { return turns(model.joints[static_cast<std::size_t>(i)].type); };
  std::vector<JointJacobian> H(static_cast<std::size_t>(n), JointJacobian::Zero(6, n));
  for (Eigen::Index j = 0; j < n; ++j) {
    const Eigen::Vector3d zj = axes.z.col(j);
    const Eigen::Vector3d dp = revolute(j) ? Eigen::Vector3d(zj.cross(p - axes.o.col(j))) : zj;
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector3d zi = axes.z.col(i);
      Eigen::Vector3d dz = Eigen::Vector3d::Zero();
      Eigen::Vector3d d_o = Eigen::Vector3d::Zero();
      if (j < i) {
        if (revolute(j)) {
          dz = zj.cross(zi);
          d_o = zj.cross(axes.o.col(i) - axes.o.col(j));
        } else {
          d_o = zj;
        }
      }
      auto& Hj = H[static_cast<std::size_t>(j)];
      if (revolute(i)) {
        Hj.block<3, 1>(0, i) = dz.cross(p - axes.o.col(i)) + zi.cross(dp - d_o);  // (1.11)
        Hj.block<3, 1>(3, i) = dz;
      } else {
        Hj.block<3, 1>(0, i) = dz;
      }
    }
  }
  return H;
}

double manipulability(const JointJacobian& J) {
  const Eigen::Matrix<double, 6, 6> JJt = J * J.transpose();
  const double det = JJt.determinant();
  return det > 0.0 ? std::sqrt(det) : 0.0;
}

}  // namespace geotraj::core
