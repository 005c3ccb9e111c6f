#include "planner/kinematics.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "core/format.hpp"

namespace geotraj::planner {
namespace {

IkSolution solution_of(const core::RobotModel& model, const core::IkResult& r, const core::JointVector& seed) {
  IkSolution s;
  s.joints = r.q;
  core::JointJacobian J;
  core::forward_kinematics(model, r.q, s.pose, J);
  s.position_error = r.position_error;
  s.orientation_error = r.orientation_error;
  s.distance_from_seed = (r.q - seed).norm();
  s.manipulability = core::manipulability(J);
  return s;
}

bool within_limits(const core::RobotModel& model, const core::JointVector& q) {
  for (std::size_t i = 0; i < model.dof(); ++i) {
    const double x = q(static_cast<Eigen::Index>(i));
    if (!core::within_position_limits(model.joints[i].type, model.limits[i], x)) return false;
  }
  return true;
}

// The request's robot, resolved, or its violations appended to `out`.
std::shared_ptr<const Robot> robot_of(const std::optional<RobotSpec>& spec, const RobotCatalog& catalog,
                                      const StopAt& stop_at, core::Violations& out) {
  if (!spec) {
    out.push_back({"robot", "is required: `name` of a built-in model (see ListRobots), an inline `model` or a `urdf` "
                            "document"});
    return nullptr;
  }
  auto robot = resolve_robot(*spec, catalog, /*motion=*/false, stop_at);
  if (!robot) {
    out.insert(out.end(), robot.error().begin(), robot.error().end());
    return nullptr;
  }
  return std::make_shared<const Robot>(std::move(*robot));
}

}  // namespace

core::Expected<ForwardRequest> admit(ForwardInput input, const RobotCatalog& catalog, const StopAt& stop_at) {
  core::Violations out = std::move(input.violations);
  ForwardRequest request;
  request.robot = robot_of(input.robot, catalog, stop_at, out);
  if (request.robot) {
    const std::size_t n = request.robot->model->dof();
    if (input.joints.size() != n) {
      out.push_back({"joints", "has " + std::to_string(input.joints.size()) + " values for a " + std::to_string(n) +
                                   "-joint robot: give one per joint, joint 0 first [rad or m]"});
    } else {
      request.joints.resize(static_cast<Eigen::Index>(n));
      for (std::size_t i = 0; i < n; ++i) {
        const double q = input.joints[i];
        if (!(std::isfinite(q) && std::abs(q) <= core::kMaxModelMagnitude)) {
          out.push_back({"joints[" + std::to_string(i) + "]", "must be finite with a magnitude of at most " +
                                                                  core::number(core::kMaxModelMagnitude) + ", got " +
                                                                  core::number(q)});
        }
        request.joints(static_cast<Eigen::Index>(i)) = q;
      }
    }
  }
  if (!out.empty()) return tl::unexpected(std::move(out));
  return request;
}

core::Expected<InverseRequest> admit(InverseInput input, const RobotCatalog& catalog, const StopAt& stop_at) {
  core::Violations out = std::move(input.violations);
  InverseRequest request;
  request.robot = robot_of(input.robot, catalog, stop_at, out);
  if (!input.target) {
    out.push_back({"target", "is required: the tool pose in W to reach (position [m], orientation)"});
  } else {
    request.target = *input.target;
    const Eigen::Vector3d p = request.target.translation();
    if (p.allFinite() && p.cwiseAbs().maxCoeff() > kMaxTargetCoordinate) {
      out.push_back({"target.position", "coordinates must lie within " + core::number(kMaxTargetCoordinate) +
                                            " m of the origin"});
    }
  }
  request.search = std::move(input.search);
  if (!out.empty()) return tl::unexpected(std::move(out));
  return request;
}

Forward forward_kinematics(const ForwardRequest& request) {
  const core::RobotModel& model = request.robot->model;
  Forward out;
  core::forward_kinematics(model, request.joints, out.pose, out.jacobian);
  out.manipulability = core::manipulability(out.jacobian);
  const Eigen::VectorXd sigma = core::singular_values(out.jacobian);
  out.max_singular_value = sigma.size() ? sigma(0) : 0.0;
  // A Jacobian with fewer than 6 columns has rank n at most: its smallest of 6 is 0.
  out.min_singular_value = out.jacobian.cols() >= 6 && sigma.size() ? sigma(sigma.size() - 1) : 0.0;
  out.axes = core::joint_axes(model, request.joints);
  out.within_limits = within_limits(model, request.joints);
  return out;
}

Expected<Inverse> inverse_kinematics(const InverseRequest& request, const Budget& budget) {
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  const core::RobotModel& model = request.robot->model;
  const core::JointVector& seed = request.robot->seed;
  core::IkSearchOptions options = request.search;
  options.stopped = [&budget] { return budget.stop_requested() || budget.expired(); };
  const core::IkSearchResult r = core::search_ik(model, request.target, seed, options);
  if (r.stopped) {
    if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  }
  Inverse out;
  out.attempts = r.attempts;
  out.iterations = r.iterations;
  for (const auto& s : r.solutions) out.solutions.push_back(solution_of(model, s, seed));
  if (out.solutions.empty()) out.closest = solution_of(model, r.closest, seed);
  return out;
}

}  // namespace geotraj::planner
