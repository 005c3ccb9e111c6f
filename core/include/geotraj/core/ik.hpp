// Inverse kinematics of a serial arm (thesis 6.4: every Cartesian sample goes through the
// arm's IK) and the joint-space motion that follows a Cartesian one, sample by sample.
//
// Method (documented in docs/kinematics.md): Newton-Raphson on the 6-D pose error with the
// geometric Jacobian (kinematics.hpp), warm-started from the previous sample, minimum-norm
// steps (J^+ = J^T (J J^T + lambda^2 I)^-1 with lambda = 0 away from singularities and a
// small damping only where J J^T is near singular), to |position error| <= 1e-9 m and
// |orientation error| <= 1e-9 rad. For a redundant arm (n > 6) the self-motion is chosen by
// the null-space projector N = I - J^+ J applied to the gradient of a documented cost that
// keeps joints away from their limits (and, weighted, the arm away from singularities).
#pragma once

#include <cstddef>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geotraj/core/robot.hpp"

namespace geotraj::core {

/// Tolerances and budgets of the IK (Ceres-style options value).
struct IkOptions {
  double position_tolerance = 1e-9;     ///< [m]
  double orientation_tolerance = 1e-9;  ///< [rad]
  int max_iterations = 100;             ///< Newton iterations per solve
  /// Restarts from random configurations within the limits when a cold solve (solve_ik)
  /// fails from the seed; 0 = none. Deterministic (fixed seed).
  int restarts = 0;
};

/// The outcome of one IK solve (a report, not an exception).
struct IkResult {
  JointVector q;                  ///< the joint values [rad or m]
  bool converged = false;         ///< both tolerances met
  int iterations = 0;
  double position_error = 0.0;     ///< |p_WT(q) - p_target| [m]
  double orientation_error = 0.0;  ///< angle of R_WT(q)^T R_target [rad]
  bool within_limits = false;      ///< every joint within its position limits
};

/// Solves X_WT(q) = X_WT_target from `seed` (position and orientation; n >= 6 joints).
/// Joints stay within their position limits where a solution within them exists near the
/// seed. Precondition (checked): seed.size() == model.dof(), the model is valid.
IkResult solve_ik(const RobotModel& model, const Eigen::Isometry3d& X_WT_target, const JointVector& seed,
                  const IkOptions& options = {});

}  // namespace geotraj::core
