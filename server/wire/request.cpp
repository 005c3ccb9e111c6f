// A PlanRequest as the planner's request (convert.hpp): one path, move or line;
// sequences in sequence.cpp.
#include <memory>
#include <utility>

#include "planner/robot_spec.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

namespace {

// The path of a request and its optimisers (optimize.*), every violation of both together.
core::Expected<planner::Request> path_request(const v1::PlanRequest& request, const ServiceLimits& limits,
                                              planner::Request out) {
  auto spec = path_from_request(request, limits);
  core::Violations violations = spec ? core::Violations{} : spec.error();
  if (request.has_optimize()) {
    planner::Optimize optimize;
    const auto& o = request.optimize();
    if (auto budget = optimize_budget(request, limits.max_optimize_seconds)) {
      optimize.budget_s = *budget;
    } else {
      violations = joined(std::move(violations), budget.error());
    }
    if (o.has_tangent_scales()) {
      auto options = tangent_scale_options(request);
      if (options) {
        optimize.tangent_scales = std::move(*options);
      } else {
        violations = joined(std::move(violations), options.error());
      }
    }
    if (o.has_breakpoints()) {
      auto options = breakpoint_options(request);
      if (options) {
        optimize.breakpoints = std::move(*options);
      } else {
        violations = joined(std::move(violations), options.error());
      }
    }
    optimize.time_optimal = o.timing().time_optimal();
    optimize.jerk_limited = o.timing().jerk_limited();
    out.optimize = std::move(optimize);
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  out.geometry = std::move(*spec);
  return out;
}

}  // namespace

core::Expected<planner::Request> wire_detail::single_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                   const ServiceLimits& limits, RequestUse use,
                                                   const planner::StopAt& stop_at,
                                                   std::shared_ptr<const planner::Robot> robot) {
  planner::Request out;
  const bool moves = request.has_joint_move() || request.has_linear_move();
  if (!request.has_motion()) {
    if (use == RequestUse::kStream) {
      return tl::unexpected(core::Violations{
          {"motion", "is required to stream samples: give durationS (s), or the limits for a minimum-time motion"}});
    }
    if (use == RequestUse::kPlan && (request.has_robot() || moves)) {
      return tl::unexpected(core::Violations{
          {"motion", "is required with a robot or a move: give durationS (s), or the limits for a minimum-time move"}});
    }
  }
  // Without a motion (PlanTrajectory) or for an analysis, only the path and its optimisers.
  if (use == RequestUse::kAnalyze || !request.has_motion()) return path_request(request, limits, std::move(out));
  core::Violations violations;
  if (use == RequestUse::kStream && !v1::StreamPacing_IsValid(request.pacing())) {
    violations.push_back({"pacing", "unknown value " + std::to_string(request.pacing()) +
                                        "; use STREAM_PACING_AS_FAST_AS_POSSIBLE or STREAM_PACING_REAL_TIME"});
  }
  const int kinds = int(request.has_path()) + int(request.has_joint_move()) + int(request.has_linear_move());
  if (kinds != 1) {
    violations.push_back({"path", kinds == 0
                                      ? "is required: give the key frames of a `path`, or a `jointMove` or a `linearMove`"
                                      : "give exactly one of `path`, `jointMove` and `linearMove`"});
    return tl::unexpected(std::move(violations));
  }
  if (request.has_optimize() && request.has_joint_move()) {
    violations.push_back({"optimize", "applies to a `path` or a linearMove's timing: a jointMove is timed by its "
                                      "slowest joint already"});
  }
  if (request.has_optimize() && request.has_linear_move()) {
    const auto& o = request.optimize();
    if (o.has_tangent_scales() || o.has_breakpoints()) {
      violations.push_back({o.has_tangent_scales() ? "optimize.tangentScales" : "optimize.breakpoints",
                            "shapes a path: a linearMove is straight (optimize.timing applies to it)"});
    }
    planner::Optimize optimize;
    if (auto budget = optimize_budget(request, limits.max_optimize_seconds)) {
      optimize.budget_s = *budget;
    } else {
      violations = joined(std::move(violations), budget.error());
    }
    optimize.time_optimal = o.timing().time_optimal();
    optimize.jerk_limited = o.timing().jerk_limited();
    out.optimize = optimize;
  }
  if (auto motion = motion_from_request(request)) {
    out.motion = std::move(*motion);
  } else {
    violations = joined(std::move(violations), motion.error());
  }
  if (robot) {
    out.robot = std::move(robot);
  } else if (request.has_robot()) {
    if (auto resolved = robot_from_request(request.robot(), catalog, true, stop_at)) {
      out.robot = std::make_shared<const planner::Robot>(std::move(*resolved));
    } else {
      violations = joined(std::move(violations), resolved.error());
    }
  }
  if (request.has_joint_move()) {
    if (!request.has_robot()) {
      violations.push_back({"robot", "is required by a jointMove: the joints belong to a robot model"});
    }
    if (!violations.empty()) return tl::unexpected(std::move(violations));
    auto move = joint_move_from_request(request, out.robot->seed);
    if (!move) return tl::unexpected(std::move(move.error()));
    out.geometry = std::move(*move);
    return out;
  }
  // Following a Cartesian pose (a path or a straight line) takes six joints at least.
  if (out.robot && out.robot->model.dof() < 6) {
    const auto& spec = request.robot();
    violations.push_back({spec.model_source_case() == v1::RobotSpec::kUrdf ? "robot.urdf"
                          : !spec.has_model()                            ? "robot"
                          : spec.model().joints_size() > 0               ? "robot.model.joints"
                                                                         : "robot.model.links",
                          "the robot has " + std::to_string(out.robot->model.dof()) +
                              " joints; following a tool pose (position and orientation) needs at least 6"});
  }
  if (request.has_linear_move()) {
    if (!violations.empty()) return tl::unexpected(std::move(violations));
    auto move = linear_move_from_request(request, out.robot.get());
    if (!move) return tl::unexpected(std::move(move.error()));
    out.geometry = std::move(*move);
    return out;
  }
  // The path's and the optimisers' own violations with these, so that one answer lists all.
  auto converted = path_request(request, limits, std::move(out));
  if (violations.empty()) return converted;
  return tl::unexpected(converted ? std::move(violations) : joined(std::move(converted.error()), violations));
}

core::Expected<planner::Request> request_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                     const ServiceLimits& limits, RequestUse use,
                                                     const planner::StopAt& stop_at) {
  if (request.sequence_size() > 0) return sequence_from_proto(request, catalog, limits, use, stop_at);
  return single_from_proto(request, catalog, limits, use, stop_at, nullptr);
}

}  // namespace geotraj::server
