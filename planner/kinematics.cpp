#include "planner/kinematics.hpp"

#include <utility>

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

}  // namespace

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
