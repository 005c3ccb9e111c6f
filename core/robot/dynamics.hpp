// Inverse dynamics of a serial arm (robot.hpp's chain with every link's mass properties,
// Joint::inertial): the joint torques [N m] (forces [N] for prismatic joints) that move the
// arm along q(t) under gravity with a payload on its tool,
//   tau = M(q) q_ddot + C(q, q_dot) q_dot + g(q) + J_c(q)^T (load)        (thesis Eq. 1.15)
// (Eq. 1.12's inertia and power terms, Eq. 1.13's effective inertia, and Eq. 1.15's gravity
// loads on the links' centres of mass and on the end effector), computed by the recursive
// Newton-Euler algorithm (the thesis's motion planner's IDNewtonEuler, Appendix C) rather
// than by the influence-coefficient arrays: O(n) per call, no matrix of the arm formed.
//
// Frames and units: everything in the world frame W (the robot's base placed by
// RobotModel::base, gravity given in W: a ceiling- or wall-mounted arm needs nothing else).
// Link i is the body joint i moves, its frame the joint's frame after its motion; its centre
// of mass and inertia are given there (Inertial). The payload is a point mass at a point of
// the tool frame T, carried by the last link (through RobotModel::flange and ::tool).
//
// Forward pass (base to tip): each link's orientation R_i, origin p_i, angular velocity w_i,
// angular acceleration w_dot_i and the acceleration a_i of its origin, with the base
// accelerating at -gravity (so gravity needs no separate term):
//   revolute:  w_i = w_{i-1} + z_i q_dot_i,  w_dot_i = w_dot_{i-1} + z_i q_ddot_i + w_{i-1} x z_i q_dot_i
//   prismatic: w_i = w_{i-1}, w_dot_i = w_dot_{i-1}, and the slide's relative velocity
//              z_i q_dot_i adds 2 w_{i-1} x z_i q_dot_i + z_i q_ddot_i to a_i
//   a_i = a_{i-1} + w_dot_{i-1} x d + w_{i-1} x (w_{i-1} x d),  d = p_i - p_{i-1}.
// Backward pass (tip to base): the force F_i = m_i a_c,i and moment N_i = I_i w_dot_i +
// w_i x I_i w_i (Newton's and Euler's equations at the centre of mass, I_i in W) of each link,
// summed with its children's into the force f_i and moment n_i (about p_i) that joint i
// transmits; tau_i = z_i . n_i (revolute) or z_i . f_i (prismatic).
#pragma once

#include <cmath>
#include <limits>

#include <Eigen/Core>

#include "core/robot/robot.hpp"

namespace geotraj::core {

/// Standard gravity [m/s^2], along -z of W.
inline constexpr double kStandardGravity = 9.80665;

struct DynamicsOptions {
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -kStandardGravity);  ///< [m/s^2] in W
  Payload payload;
};

/// The model's own: standard gravity along -z of W and RobotModel::payload.
inline DynamicsOptions dynamics_options(const RobotModel& model) { return {Eigen::Vector3d(0.0, 0.0, -kStandardGravity), model.payload}; }

/// Whether every joint of the model gives the mass properties of the link it moves.
bool has_dynamics(const RobotModel& model);

/// Whether the model's joint torques are known (has_dynamics) and some joint limits its torque:
/// then the timings by the limits impose them (time_optimal.hpp, joint_path.hpp, moves.hpp).
bool torque_limited(const RobotModel& model);

/// How far the torque tau of a joint, whose gravity load is `gravity` (tau at rest in the same
/// pose), uses what its limit leaves the motion: the part beyond gravity's, d = tau - gravity,
/// over limit - gravity (d > 0) or limit + gravity (d < 0). Above 1 exactly where |tau| >
/// limit; a uniform time stretch by f divides d by f^2, so f = sqrt(usage) brings it to the
/// limit. +infinity where |gravity| > limit (no timing holds the pose). [N m or N]
inline double dynamic_torque_usage(double tau, double gravity, double limit) {
  const double d = tau - gravity;
  if (std::abs(gravity) > limit) return std::numeric_limits<double>::infinity();
  if (d == 0.0) return 0.0;
  const double room = d > 0.0 ? limit - gravity : limit + gravity;
  return room > 0.0 ? std::abs(d) / room : std::numeric_limits<double>::infinity();
}

/// The joint torques tau [N m or N] that give the motion (q, q_dot, q_ddot) [rad or m, /s,
/// /s^2] under options' gravity and payload (Eq. 1.15), by the recursive Newton-Euler
/// algorithm above. No heap allocation.
/// Preconditions (checked): has_dynamics(model); q, q_dot and q_ddot of model.dof() values.
void inverse_dynamics(const RobotModel& model, const JointVector& q, const JointVector& q_dot,
                      const JointVector& q_ddot, const DynamicsOptions& options, JointVector& tau);

/// The joint torques at rest at q under options' gravity and payload (g(q) of Eq. 1.15);
/// inverse_dynamics at zero velocity and acceleration.
void gravity_torques(const RobotModel& model, const JointVector& q, const DynamicsOptions& options, JointVector& tau);

/// The torques along a path q(s) [rad or m] through q with dq/ds = q_s, d2q/ds2 = q_ss, as
/// tau = a s_ddot + b s_dot^2 + c (time_optimal.hpp): a = M(q) q_s, b = M(q) q_ss + C(q, q_s) q_s,
/// c = g(q) (with the payload): inverse_dynamics at (q, 0, q_s) and (q, q_s, q_ss) without
/// gravity and at (q, 0, 0) with it, the links' poses computed once for the three. No heap
/// allocation.
void path_torque_terms(const RobotModel& model, const JointVector& q, const JointVector& q_s, const JointVector& q_ss,
                       const DynamicsOptions& options, JointVector& a, JointVector& b, JointVector& c);

}  // namespace geotraj::core
