#include "server/wire/kinematics.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <string>
#include <utility>

#include "core/format.hpp"

namespace geotraj::server {
namespace {

// The request's robot, resolved, or its violations appended to `out`.
std::shared_ptr<const planner::Robot> robot_of(bool has_robot, const v1::RobotSpec& spec, const RobotCatalog& catalog,
                                               const planner::StopAt& stop_at, core::Violations& out) {
  if (!has_robot) {
    out.push_back({"robot", "is required: `name` of a built-in model (see ListRobots), an inline `model` or a `urdf` "
                            "document"});
    return nullptr;
  }
  auto robot = robot_from_request(spec, catalog, /*motion=*/false, stop_at);
  if (!robot) {
    out.insert(out.end(), robot.error().begin(), robot.error().end());
    return nullptr;
  }
  return std::make_shared<const planner::Robot>(std::move(*robot));
}

void set_solution(const planner::IkSolution& s, v1::IkSolution& out) {
  for (Eigen::Index i = 0; i < s.joints.size(); ++i) out.add_joints(s.joints(i));
  to_proto(s.pose, *out.mutable_pose());
  out.set_position_error(s.position_error);
  out.set_orientation_error(s.orientation_error);
  out.set_distance_from_seed(s.distance_from_seed);
  out.set_manipulability(s.manipulability);
}

}  // namespace

core::Expected<planner::ForwardRequest> forward_request_from_proto(const v1::ForwardKinematicsRequest& request,
                                                                   const RobotCatalog& catalog,
                                                                   const planner::StopAt& stop_at) {
  core::Violations out;
  planner::ForwardRequest converted;
  converted.robot = robot_of(request.has_robot(), request.robot(), catalog, stop_at, out);
  if (converted.robot) {
    const std::size_t n = converted.robot->model.dof();
    if (static_cast<std::size_t>(request.joints_size()) != n) {
      out.push_back({"joints", "has " + std::to_string(request.joints_size()) + " values for a " + std::to_string(n) +
                                   "-joint robot: give one per joint, joint 0 first [rad or m]"});
    } else {
      converted.joints.resize(static_cast<Eigen::Index>(n));
      for (std::size_t i = 0; i < n; ++i) {
        const double q = request.joints(static_cast<int>(i));
        if (!(std::isfinite(q) && std::abs(q) <= core::kMaxModelMagnitude)) {
          out.push_back({"joints[" + std::to_string(i) + "]", "must be finite with a magnitude of at most " +
                                                                  core::number(core::kMaxModelMagnitude) + ", got " +
                                                                  core::number(q)});
        }
        converted.joints(static_cast<Eigen::Index>(i)) = q;
      }
    }
  }
  if (!out.empty()) return tl::unexpected(std::move(out));
  return converted;
}

core::Expected<planner::InverseRequest> inverse_request_from_proto(const v1::InverseKinematicsRequest& request,
                                                                   const RobotCatalog& catalog,
                                                                   const planner::StopAt& stop_at) {
  core::Violations out;
  planner::InverseRequest converted;
  converted.robot = robot_of(request.has_robot(), request.robot(), catalog, stop_at, out);
  if (!request.has_target()) {
    out.push_back({"target", "is required: the tool pose in W to reach (position [m], orientation)"});
  } else {
    converted.target = pose_from_proto(request.target(), "target", out);
    if (converted.target.translation().allFinite() &&
        converted.target.translation().cwiseAbs().maxCoeff() > kMaxTargetCoordinate) {
      out.push_back({"target.position", "coordinates must lie within " + core::number(kMaxTargetCoordinate) +
                                            " m of the origin"});
    }
  }
  auto& search = converted.search;
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
  if (!out.empty()) return tl::unexpected(std::move(out));
  return converted;
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
