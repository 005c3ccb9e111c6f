// Forward kinematics and Jacobians of a DH chain (thesis 1.1.2-1.1.3). See kinematics.hpp.
#include "geotraj/core/kinematics.hpp"

#include <cmath>

namespace geotraj::core {
namespace {

// Rotation about x by alpha then translation along the new x by a: RotX(alpha) TransX(a).
// (RotX and TransX commute: both act along x.)
Eigen::Isometry3d rot_x_trans_x(double alpha, double a) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::AngleAxisd(alpha, Eigen::Vector3d::UnitX()).toRotationMatrix();
  X.translation() = Eigen::Vector3d(a, 0.0, 0.0);
  return X;
}

// RotZ(theta) TransZ(d) (they commute too).
Eigen::Isometry3d rot_z_trans_z(double theta, double d) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  X.translation() = Eigen::Vector3d(0.0, 0.0, d);
  return X;
}

// The joint axes of the chain at q: z_i (unit) and o_i (a point of the axis), in W, and
// the tool pose. Modified DH (1.3): joint i turns about the z axis of frame i, reached
// after RotX(alpha_i) TransX(a_i). Standard DH: about the z axis of frame i-1.
struct Axes {
  Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, static_cast<int>(kMaxJoints)> z, o;
  Eigen::Isometry3d X_WT;
};

void axes_at(const RobotModel& model, const JointVector& q, Axes& out) {
  const auto n = static_cast<Eigen::Index>(model.dof());
  GEOTRAJ_CHECK(q.size() == n);
  out.z.resize(3, n);
  out.o.resize(3, n);
  Eigen::Isometry3d X = model.base;
  for (Eigen::Index i = 0; i < n; ++i) {
    const DhLink& l = model.links[static_cast<std::size_t>(i)];
    const bool revolute = l.type == JointType::kRevolute;
    const double theta = l.theta + (revolute ? l.offset + q(i) : 0.0);
    const double d = l.d + (revolute ? 0.0 : l.offset + q(i));
    if (model.convention == DhConvention::kModified) {
      X = X * rot_x_trans_x(l.alpha, l.a);  // (1.3): RotX(alpha_{i-1}) TransX(a_{i-1})
      out.z.col(i) = X.linear().col(2);
      out.o.col(i) = X.translation();
      X = X * rot_z_trans_z(theta, d);  // (1.3): RotZ(theta_i) TransZ(d_i)
    } else {
      out.z.col(i) = X.linear().col(2);
      out.o.col(i) = X.translation();
      X = X * rot_z_trans_z(theta, d) * rot_x_trans_x(l.alpha, l.a);
    }
  }
  out.X_WT = X * model.tool;
}

}  // namespace

Eigen::Isometry3d forward_kinematics(const RobotModel& model, const JointVector& q) {
  Axes axes;
  axes_at(model, q, axes);
  return axes.X_WT;
}

void forward_kinematics(const RobotModel& model, const JointVector& q, Eigen::Isometry3d& X_WT, JointJacobian& J) {
  Axes axes;
  axes_at(model, q, axes);
  X_WT = axes.X_WT;
  const Eigen::Vector3d p_WT = X_WT.translation();
  const auto n = static_cast<Eigen::Index>(model.dof());
  J.resize(6, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d z = axes.z.col(i);
    if (model.links[static_cast<std::size_t>(i)].type == JointType::kRevolute) {
      J.block<3, 1>(0, i) = z.cross(p_WT - axes.o.col(i));  // (1.9), revolute column
      J.block<3, 1>(3, i) = z;
    } else {
      J.block<3, 1>(0, i) = z;  // (1.9), prismatic column
      J.block<3, 1>(3, i).setZero();
    }
  }
}

Vector6d jacobian_dot_qdot(const RobotModel& model, const JointVector& q, const JointVector& q_dot) {
  // d/dt of each column, summed with weights q_dot_i (1.10): the axes move with the joints
  // before them. omega is the angular velocity of the frame that carries axis i and v_o the
  // velocity of its point o_i, both accumulated joint by joint (O(n)).
  Axes axes;
  axes_at(model, q, axes);
  const auto n = static_cast<Eigen::Index>(model.dof());
  GEOTRAJ_CHECK(q_dot.size() == n);
  const Eigen::Vector3d p = axes.X_WT.translation();
  // Tool velocity v = J_v q_dot.
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_tool = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d z = axes.z.col(i);
    if (model.links[static_cast<std::size_t>(i)].type == JointType::kRevolute) {
      v_tool += z.cross(p - axes.o.col(i)) * q_dot(i);
    } else {
      v_tool += z * q_dot(i);
    }
  }
  Vector6d out = Vector6d::Zero();
  Eigen::Vector3d v_o = Eigen::Vector3d::Zero();  // velocity of the previous axis point
  Eigen::Vector3d o_prev = model.base.translation();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d z = axes.z.col(i);
    const Eigen::Vector3d o = axes.o.col(i);
    v_o += omega.cross(o - o_prev);  // the point o_i rides on the frame before joint i
    o_prev = o;
    const Eigen::Vector3d z_dot = omega.cross(z);
    if (model.links[static_cast<std::size_t>(i)].type == JointType::kRevolute) {
      out.head<3>() += (z_dot.cross(p - o) + z.cross(v_tool - v_o)) * q_dot(i);
      out.tail<3>() += z_dot * q_dot(i);
      omega += z * q_dot(i);
    } else {
      out.head<3>() += z_dot * q_dot(i);
      v_o += z * q_dot(i);
    }
  }
  return out;
}

std::vector<JointJacobian> influence_hessian(const RobotModel& model, const JointVector& q) {
  // H[j] = dJ/dq_j. Axis i moves with joint j only when j < i (j's motion carries i):
  //   revolute j: dz_i/dq_j = z_j x z_i, do_i/dq_j = z_j x (o_i - o_j);
  //   prismatic j: dz_i/dq_j = 0,        do_i/dq_j = z_j;
  // and the tool point moves with every joint: dp/dq_j = J_v column j.
  Axes axes;
  axes_at(model, q, axes);
  const auto n = static_cast<Eigen::Index>(model.dof());
  const Eigen::Vector3d p = axes.X_WT.translation();
  auto revolute = [&](Eigen::Index i) { return model.links[static_cast<std::size_t>(i)].type == JointType::kRevolute; };
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
