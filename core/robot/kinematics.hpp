// Forward kinematics, the Jacobian (first-order influence coefficients, thesis Eqs. 1.8-1.9)
// and the second-order term (Eqs. 1.10-1.11) of a serial arm (robot.hpp). Free functions
// over the immutable RobotModel; no heap allocation.
//
// Output convention: the thesis's output vector P = {x, y, z, psi_x, psi_y, psi_z} (1.8) is
// taken with its angular part as the angular velocity of the tool (the geometric Jacobian),
// so that, in the world frame W,
//   [v_WT; omega_WT]   = J(q) q_dot                                   (1.8)
//   [a_WT; alpha_WT]   = J(q) q_ddot + q_dot^T H(q) q_dot             (1.10, 1.11)
// with v_WT, a_WT the velocity [m/s] and acceleration [m/s^2] of the tool origin and
// omega_WT, alpha_WT the tool's angular velocity [rad/s] and acceleration [rad/s^2].
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The tool pose X_WT at joint values q (robot.hpp's chain: base * A_1 ... A_n * tool).
/// Precondition (checked): q.size() == model.dof().
Eigen::Isometry3d forward_kinematics(const RobotModel& model, const JointVector& q);

/// The tool pose X_WT and the geometric Jacobian J (6 x n, rows v then omega, in W) at q
/// (Eqs. 1.8-1.9). Column i, with z_i the unit axis of joint i and o_i a point on it (W):
///   revolute:  [z_i x (p_WT - o_i); z_i],   prismatic: [z_i; 0].
void forward_kinematics(const RobotModel& model, const JointVector& q, Eigen::Isometry3d& X_WT,
                        JointJacobian& J);

/// The velocity-product term q_dot^T H q_dot = J_dot(q, q_dot) q_dot of Eq. (1.11)
/// [m/s^2; rad/s^2] in W: the tool acceleration when q_ddot = 0.
Vector6d jacobian_dot_qdot(const RobotModel& model, const JointVector& q, const JointVector& q_dot);

/// The second-order influence coefficients (Eq. 1.11): H[j] = dJ/dq_j, one 6 x n matrix per
/// joint j, so that q_dot^T H q_dot = sum_j q_dot_j H[j] q_dot. (For tests and analysis;
/// the sampling loop uses jacobian_dot_qdot.)
std::vector<JointJacobian> influence_hessian(const RobotModel& model, const JointVector& q);

/// A joint's axis in W: a point on it (the origin of the joint's frame, after its origin
/// transform: for a DH chain the frame the joint turns about or slides along) [m] and its
/// unit direction.
struct JointAxis {
  Eigen::Vector3d origin;
  Eigen::Vector3d direction;
};

/// Every joint's axis at q, joint 0 first: the o_i and z_i of Eq. (1.9).
/// Precondition (checked): q.size() == model.dof().
std::vector<JointAxis> joint_axes(const RobotModel& model, const JointVector& q);

/// The singular values of J, largest first (min(6, n) of them).
Eigen::VectorXd singular_values(const JointJacobian& J);

/// Yoshikawa's manipulability sqrt(det(J J^T)) of the 6 x n Jacobian (0 at a singularity).
double manipulability(const JointJacobian& J);

}  // namespace geotraj::core
