#include "server/wire/kinematics.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {
namespace {

void set_solution(const planner::IkSolution& s, v1::IkSolution& out) {
  for (Eigen::Index i = 0; i < s.joints.size(); ++i) out.add_joints(s.joints(i));
  to_proto(s.pose, *out.mutable_pose());
  out.set_position_error(s.position_error);
  out.set_orientation_error(s.orientation_error);
  out.set_distance_from_seed(s.distance_from_seed);
  out.set_manipulability(s.manipulability);
}

}  // namespace

planner::ForwardInput forward_input_from_proto(const v1::ForwardKinematicsRequest& request) {
  planner::ForwardInput in;
  if (request.has_robot()) in.robot = wire_detail::robot_spec_from_proto(request.robot(), in.violations);
  in.joints.assign(request.joints().begin(), request.joints().end());
  return in;
}

planner::InverseInput inverse_input_from_proto(const v1::InverseKinematicsRequest& request) {
  planner::InverseInput in;
  core::Violations& out = in.violations;
  if (request.has_robot()) in.robot = wire_detail::robot_spec_from_proto(request.robot(), out);
  if (request.has_target()) in.target = pose_from_proto(request.target(), "target", out);
  auto& search = in.search;
  const std::uint32_t restarts = request.has_restarts() ? request.restarts() : kDefaultIkRestarts;
  if (restarts > kMaxIkRestarts) {
    out.push_back({"restarts", "must be at most " + std::to_string(kMaxIkRestarts) + ", got " + std::to_string(restarts)});
  }
  search.max_attempts = static_cast<int>(std::min(restarts, kMaxIkRestarts)) + 1;
  search.all_solutions = request.all_solutions();
  const std::uint32_t solutions = request.has_max_solutions() ? request.max_solutions() : kDefaultIkSolutions;
  if (solutions < 1 || solutions > kMaxIkSolutions) {
    out.push_back({"maxSolutions", "must be between 1 and " + std::to_string(kMaxIkSolutions) + ", got " +
                                       std::to_string(solutions)});
  }
  search.max_solutions = solutions;
  if (request.has_position_tolerance()) {
    const double tol = request.position_tolerance();
    if (!(tol > 0.0 && tol <= 0.01)) {
      out.push_back({"positionTolerance", "must be above 0 and at most 0.01 [m], got " + core::number(tol)});
    }
    search.newton.position_tolerance = tol;
  }
  if (request.has_orientation_tolerance()) {
    const double tol = request.orientation_tolerance();
    if (!(tol > 0.0 && tol <= std::numbers::pi)) {
      out.push_back({"orientationTolerance", "must be above 0 and at most pi [rad], got " + core::number(tol)});
    }
    search.newton.orientation_tolerance = tol;
  }
  return in;
}

void to_proto(const planner::Forward& forward, v1::ForwardKinematicsResponse& out) {
  to_proto(forward.pose, *out.mutable_pose());
  for (Eigen::Index r = 0; r < forward.jacobian.rows(); ++r) {
    for (Eigen::Index c = 0; c < forward.jacobian.cols(); ++c) out.add_jacobian(forward.jacobian(r, c));
  }
  out.set_manipulability(forward.manipulability);
  out.set_min_singular_value(forward.min_singular_value);
  out.set_max_singular_value(forward.max_singular_value);
  for (const auto& axis : forward.axes) {
    auto* a = out.add_axes();
    to_proto(axis.origin, *a->mutable_origin());
    to_proto(axis.direction, *a->mutable_direction());
  }
  out.set_within_limits(forward.within_limits);
}

void to_proto(const planner::Inverse& inverse, v1::InverseKinematicsResponse& out) {
  out.set_reachable(inverse.reachable());
  for (const auto& s : inverse.solutions) set_solution(s, *out.add_solutions());
  if (inverse.closest) set_solution(*inverse.closest, *out.mutable_closest());
  out.set_attempts(static_cast<std::uint32_t>(inverse.attempts));
  out.set_iterations(static_cast<std::uint32_t>(inverse.iterations));
}

}  // namespace geotraj::server
