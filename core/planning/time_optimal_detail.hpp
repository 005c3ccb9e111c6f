// What the time-optimal sweep (time_optimal_sweep.cpp) and the plan around it
// (time_optimal.cpp: the grids, the sample checks, the refinements) share. Private to
// geotraj_core; the interface is time_optimal.hpp.
#pragma once

#include <cmath>
#include <limits>
#include <vector>

#include "core/error.hpp"
#include "core/planning/time_optimal.hpp"
#include "core/robot/dynamics.hpp"

namespace geotraj::core::time_optimal_detail {

/// solve_time_optimal with per-point limit scales `sigma` (null: all 1; indexed as `grid`):
/// the plan's refinements and its grid-error estimate (time_optimal.cpp). `points` (null:
/// every point) sweeps the grid's points of those indices, increasing, without copying them
/// (every_second_point: the grid-error estimate); their intervals ignore GridPoint's middles.
Expected<TimeOptimalSolution> sweep(const std::vector<GridPoint>& grid, const TimeOptimalLimits& lim,
                                    const std::vector<double>* sigma, const std::vector<std::size_t>* points = nullptr);

/// Scratch of check_torques (no allocation per sample).
struct TorqueScratch {
  JointVector tau, gravity;
};

/// The torques of one sample of a sample check (q, q_dot, q_ddot; s_ddot and b = s_dot^2 of
/// the path), between grid points g0 and g1 at `within` in [0, 1]: screened by the grid's
/// terms (torques_near_limits), computed exactly near a limit, the gravity load exactly only
/// where a torque passes its limit (where the ratio tightens the grid; elsewhere the grid's
/// estimate, whose ratio cannot pass 1). Calls note(|tau|, limit, joint, dynamic usage) for
/// each joint worth noting. False, with `joint` and its load in `load`, where gravity alone
/// passes a joint's limit.
template <class Note>
bool check_torques(const RobotModel& model, const JointVector& q, const JointVector& q_dot, const JointVector& q_ddot,
                   const GridPoint& g0, const GridPoint& g1, double within, double s_ddot, double b,
                   const TimeOptimalLimits& limits, TorqueScratch& x, Note note, Eigen::Index& joint, double& load) {
  TorqueEstimate estimate;
  if (!torques_near_limits(g0, g1, within, s_ddot, b, limits, estimate)) {
    if (estimate.joint >= 0) note(estimate.value, estimate.limit, estimate.joint, estimate.usage);
    return true;
  }
  inverse_dynamics(model, q, q_dot, q_ddot, dynamics_options(model), x.tau);
  bool over = false;
  for (Eigen::Index j = 0; j < x.tau.size(); ++j) over = over || std::abs(x.tau(j)) > limits.joint_torque(j);
  if (over) {
    gravity_torques(model, q, dynamics_options(model), x.gravity);
  } else {
    x.gravity = g0.tau_c + within * (g1.tau_c - g0.tau_c);
  }
  for (Eigen::Index j = 0; j < x.tau.size(); ++j) {
    const double T = limits.joint_torque(j);
    if (!(T < std::numeric_limits<double>::infinity())) continue;
    if (std::abs(x.gravity(j)) > T) {
      joint = j, load = x.gravity(j);
      return false;
    }
    note(std::abs(x.tau(j)), T, j, dynamic_torque_usage(x.tau(j), x.gravity(j), T));
  }
  return true;
}

}  // namespace geotraj::core::time_optimal_detail
