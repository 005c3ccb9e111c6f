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

#include <Eigen/Core>

#include "core/robot/robot.hpp"

namespace geotraj::core {

/// Standard gravity [m/s^2], along -z of W.
inline constexpr double kStandardGravity = 9.80665;

/// A load on the tool (proto Payload): its mass [kg] at its centre of mass [m] in the tool
/// frame T, a point mass (its own rotational inertia neglected, as a robot's payload rating
/// gives it).
struct Payload {
  double mass = 0.0;
  Eigen::Vector3d center_of_mass = Eigen::Vector3d::Zero();
};

struct DynamicsOptions {
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -kStandardGravity);  ///< [m/s^2] in W
  Payload payload;
};

/// Whether every joint of the model gives the mass properties of the link it moves.
bool has_dynamics(const RobotModel& model);

/// The joint torques tau [N m or N] that give the motion (q, q_dot, q_ddot) [rad or m, /s,
/// /s^2] under options' gravity and payload (Eq. 1.15), by the recursive Newton-Euler
/// algorithm above. No heap allocation.
/// Preconditions (checked): has_dynamics(model); q, q_dot and q_ddot of model.dof() values.
void inverse_dynamics(const RobotModel& model, const JointVector& q, const JointVector& q_dot,
                      const JointVector& q_ddot, const DynamicsOptions& options, JointVector& tau);

}  // namespace geotraj::core
