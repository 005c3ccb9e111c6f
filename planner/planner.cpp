// One request planned (planner.hpp): its path's optimisers, the trajectory and its timing,
// the passes over its samples (the robot's joints, the tool's peaks), and the analysis.
#include "planner/planner.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>
#include <utility>

#include "core/format.hpp"
#include "core/geometry/analysis.hpp"
#include "core/motion/orientation.hpp"
#include "core/robot/kinematics.hpp"
#include "optim/timing/joint_path_jerk.hpp"
#include "optim/timing/time_optimal_jerk.hpp"
#include "planner/plan_detail.hpp"

namespace geotraj::planner {
namespace detail {


double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

Error invalid(core::Violations violations) {
  const ErrorKind kind = core::all_unattainable(violations) ? ErrorKind::kUnattainable : ErrorKind::kInvalidArgument;
  return Error{kind, std::move(violations), {}, {}};
}

void observe(const Budget& budget, std::string_view optimizer, Clock::time_point started) {
  if (budget.on_optimizer) budget.on_optimizer(optimizer, seconds_since(started));
}

// How far [rad or m] the last joints of a straight line to joint values may end from them:
// the tracking's IK converges to 1e-9 on the goal's pose, so any larger gap is a branch.
constexpr double kGoalJointTolerance = 1e-6;


// The deadline every optimiser of the request shares: the earlier of the budget's and
// optimize.timeBudgetS from the start of the plan.
Clock::time_point optimizer_deadline(const Request& request, const Budget& budget) {
  if (!request.optimize) return budget.deadline;
  const auto budget_s = std::chrono::duration<double>(std::min(request.optimize->budget_s, 1e9));
  return std::min(budget.deadline, Clock::now() + std::chrono::duration_cast<Clock::duration>(budget_s));
}

// One path optimiser under the plan's budget and deadline: `path` becomes its result's path
// and `report` its result. Its errors name absolute field paths already.
template <class Options, class Optimize, class Result>
std::optional<Error> run_path_optimizer(std::optional<Options> options, Optimize optimize, std::string_view name,
                                        const Budget& budget, Clock::time_point deadline, core::PathSpec& path,
                                        std::optional<Result>& report) {
  if (!options) return std::nullopt;
  options->deadline = deadline;
  options->stop = budget.stop;
  const auto started = Clock::now();
  auto result = optimize(path, *options);
  observe(budget, name, started);
  if (!result) return invalid(std::move(result.error()));
  path = result->spec;
  report = std::move(*result);
  return std::nullopt;
}

// The request's path after the optimisers it asks for (tangent scales, then breakpoints),
// their reports in `reports`.
Expected<core::PathSpec> optimized_path(const Request& request, const Budget& budget, Clock::time_point deadline,
                                        OptimizerReports& reports) {
  core::PathSpec path = std::get<core::PathSpec>(request.geometry);
  if (!request.optimize) return path;
  if (auto error = run_path_optimizer(request.optimize->tangent_scales, optim::optimize_tangent_scales,
                                      "tangent_scales", budget, deadline, path, reports.tangent_scales)) {
    return tl::unexpected(std::move(*error));
  }
  if (auto error = run_path_optimizer(request.optimize->breakpoints, optim::optimize_breakpoints, "breakpoints",
                                      budget, deadline, path, reports.breakpoints)) {
    return tl::unexpected(std::move(*error));
  }
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  return path;
}

Expected<core::Path> build(const core::PathSpec& spec) {
  auto path = core::build_path(spec);
  if (!path) return tl::unexpected(invalid(core::prefixed(std::move(path.error()), "path.")));
  return std::move(*path);
}

// The fastest timing along the path within the joint limits (with a robot) and the
// Cartesian ones given (thesis 6.4, TOPP in b = s_dot^2: core/planning/time_optimal.hpp), with jerk
// limits by the NLP warm-started from it (optim/timing/time_optimal_jerk.hpp), within the
// optimisers' shared deadline. `joints`: a redundant arm's joints chosen along the path (in
// arc length), which the timing's tracker follows (null: the sample-by-sample self-motion).
Expected<core::MotionPlan> time_optimal_timing(const core::Path& path, const core::OrientationPlan& orientation,
                                               const core::MotionSpec& motion, const Robot* robot, bool jerk_limited,
                                               const Budget& budget, Clock::time_point deadline,
                                               OptimizerReports& reports,
                                               std::shared_ptr<const core::JointReference> joints = nullptr) {
  if (robot == nullptr && !motion.max_acceleration) {
    return tl::unexpected(invalid(core::Violations{
        {"motion.maxAcceleration", "is needed for a time-optimal motion without a robot (and maxSpeed, optional)"}}));
  }
  const auto started = Clock::now();
  const core::RobotModel* model = robot ? &robot->model.model() : nullptr;
  const core::JointVector seed = robot ? robot->seed : core::JointVector();
  core::MotionPlan plan;
  TimingReport timing;
  if (jerk_limited) {
    optim::JerkTimingOptions options;
    options.time_budget_s = std::max(0.0, std::chrono::duration<double>(deadline - started).count());
    options.stop = budget.stop;
    core::TimeOptimalOptions exact = optim::jerk_exact_options();
    exact.joints = joints;
    auto result = optim::plan_time_optimal_jerk(path, orientation, motion, model, seed, exact, options);
    if (!result) {
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
      return tl::unexpected(invalid(std::move(result.error())));
    }
    plan = std::move(result->motion);
    // Its binding stretches are measured on its samples after the plan's pass (measured_binding):
    // the exact sweep's (its warm start) describe another, faster motion (the PA-10's path C:
    // stretches to 5.67 s of a 5.98 s plan).
    timing.jerk_limited = true;
    timing.report = result->report;
    timing.check_rate_hz = result->check_rate_hz;
    timing.worst_limit_usage = result->worst_sample_usage;
    timing.refinements = result->refinements;
    timing.duration_grid_error_s = result->duration_grid_error;
  } else {
    core::TimeOptimalOptions exact;
    exact.stop = budget.stop;
    exact.joints = std::move(joints);
    auto result = core::plan_time_optimal(path, orientation, motion, model, seed, exact);
    if (!result) {
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
      return tl::unexpected(invalid(std::move(result.error())));
    }
    plan = std::move(result->motion);
    timing.binding = std::move(result->binding);
    timing.report.status = optim::OptimizerStatus::kConverged;
    timing.report.iterations = result->refinements + 1;
    timing.check_rate_hz = result->check_rate_hz;
    timing.worst_limit_usage = result->worst_sample_usage;
    timing.refinements = result->refinements;
    timing.duration_grid_error_s = result->duration_grid_error;
  }
  observe(budget, jerk_limited ? "time_optimal_jerk" : "time_optimal", started);
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  timing.report.seconds = seconds_since(started);
  // Before: the move time the request would have had without the optimiser.
  double before = motion.duration_s;
  if (before == 0.0) {
    if (auto conservative = core::plan_motion(path, motion)) before = conservative->duration_s;
  }
  timing.report.objective_before = before;
  timing.report.objective_after = plan.duration_s;
  reports.timing = std::move(timing);
  return plan;
}

// The timing of a joint path through waypoints (core/planning/joint_path.hpp) for `robot`
// (its model's jerk limits defaulted by the caller where the limits time the motion): the
// time-optimal sweep where optimize.timing.timeOptimal asks for it alone, else the
// jerk-limited NLP warm-started from it (optim/timing/joint_path_jerk.hpp); a durationS
// stretches either. The timing report where the limits time it (durationS 0).
Expected<core::Trajectory> joint_path_trajectory(const core::JointPathSpec& spec, const core::MotionSpec& motion,
                                                 const Robot& robot, bool jerk_limited, const Budget& budget,
                                                 Clock::time_point deadline, OptimizerReports& reports) {
  auto path = core::build_joint_path(robot.model, spec);
  if (!path) return tl::unexpected(invalid(core::prefixed(std::move(path.error()), "jointPath.")));
  const auto started = Clock::now();
  TimingReport timing;
  std::optional<core::JointPathPlan> plan;
  if (jerk_limited) {
    optim::JerkTimingOptions options;
    options.time_budget_s = std::max(0.0, std::chrono::duration<double>(deadline - started).count());
    options.stop = budget.stop;
    core::JointPathOptions exact = optim::joint_path_jerk_exact_options();
    exact.stop = budget.stop;
    auto result = optim::plan_joint_path_jerk(robot.model, std::move(*path), motion, exact, options);
    if (!result) {
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
      return tl::unexpected(invalid(std::move(result.error())));
    }
    timing.jerk_limited = true;
    timing.report = result->rounds.report;
    timing.check_rate_hz = result->plan.check_rate_hz;
    timing.worst_limit_usage = result->rounds.worst_sample_usage;
    timing.refinements = result->rounds.refinements;
    timing.duration_grid_error_s = result->rounds.duration_grid_error;
    timing.report.objective_before = result->exact_duration_s;  // the sweep it started from
    plan = std::move(result->plan);
  } else {
    core::JointPathOptions exact;
    exact.stop = budget.stop;
    auto result = core::plan_joint_path(robot.model, std::move(*path), motion, exact);
    if (!result) {
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
      return tl::unexpected(invalid(std::move(result.error())));
    }
    timing.binding = result->binding;
    timing.report.status = optim::OptimizerStatus::kConverged;
    timing.report.iterations = result->refinements + 1;
    timing.check_rate_hz = result->check_rate_hz;
    timing.worst_limit_usage = std::max(result->velocity_usage, result->acceleration_usage);
    timing.refinements = result->refinements;
    timing.duration_grid_error_s = result->duration_grid_error;
    timing.report.objective_before = result->duration_s;
    plan = std::move(*result);
  }
  observe(budget, jerk_limited ? "joint_path_jerk" : "joint_path", started);
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  if (motion.duration_s == 0.0) {
    timing.report.seconds = seconds_since(started);
    timing.report.objective_after = plan->duration_s;
    reports.timing = std::move(timing);
  }
  return core::Trajectory(std::in_place_type<core::JointPathPlan>, std::move(*plan));
}

// The jerk bounds of `model`'s joints without max_jerk under core::jerk_bound's default.
DefaultJerk default_jerk_of(const core::RobotModel& model) {
  DefaultJerk used;
  for (std::size_t i = 0; i < model.limits.size(); ++i) {
    if (model.limits[i].max_jerk) continue;
    used.joints.push_back(i);
    used.max_jerk.push_back(core::jerk_bound(model.limits[i], used.ramp_s));
  }
  const auto [low, high] = std::minmax_element(used.max_jerk.begin(), used.max_jerk.end());
  std::string names;
  bool revolute = false, prismatic = false;
  for (std::size_t k = 0; k < used.joints.size(); ++k) {
    const std::size_t i = used.joints[k];
    names += (k == 0 ? "" : ", ") + std::to_string(i) +
             (model.joints[i].name.empty() ? "" : " (" + model.joints[i].name + ")");
    (model.joints[i].type == core::JointType::kPrismatic ? prismatic : revolute) = true;
  }
  const std::string unit = revolute && prismatic ? " rad/s^3 or m/s^3" : prismatic ? " m/s^3" : " rad/s^3";
  used.message = "the " + model.name + " model gives no maxJerk for joint" + (used.joints.size() > 1 ? "s " : " ") +
                 names + ": the motion, timed by the limits, keeps their jerk within maxAcceleration / " +
                 core::number(used.ramp_s) + " s (" + core::number(*low, 4) +
                 (*high > *low ? " to " + core::number(*high, 4) : std::string()) + unit +
                 ") so that it starts and ends without an acceleration step; give the joints a maxJerk (or the "
                 "motion a durationS) to choose otherwise";
  return used;
}

// Whether the limits time the request's motion on a robot (no durationS, timeOptimal or
// jerkLimited): the timings a free choice can serve.
bool timed_by_limits(const Request& request) {
  return request.motion && time_optimally_timed(*request.motion, true, request.optimize && request.optimize->time_optimal,
                                                request.optimize && request.optimize->jerk_limited);
}

// How the limits time a motion of `request` (a joint move or path: `joint`): the robot whose
// limits time it when the model's missing jerk limits are defaulted (`defaulted`, with
// `default_jerk`), and whether a path or a line is timed jerk-limited. Shared by
// plan_trajectory and the timings made again along a choice (retime_along_choices).
struct LimitsTiming {
  std::optional<Robot> defaulted;
  std::optional<DefaultJerk> default_jerk;
  bool jerk_limited = false;
  bool jerk_from_model = false;  // the model's (or the defaulted) jerk limits time it
};
LimitsTiming limits_timing(const Request& request, bool joint) {
  LimitsTiming out;
  const core::MotionSpec& motion = *request.motion;
  const Robot* robot = request.robot.get();
  const bool time_optimal = request.optimize && request.optimize->time_optimal;
  const bool asked_jerk = request.optimize && request.optimize->jerk_limited;
  // No acceleration step by default: where the request leaves the timing to the limits (no
  // durationS and no optimize.timing.timeOptimal) or asks for jerkLimited, a joint without
  // max_jerk is bounded by core::jerk_bound's default, and the plan says so. Not where the
  // tool's angular limits are asked of a path or a line (the jerk-limited NLP has no angular
  // rows: the time-optimal sweep imposes them) nor under an explicit timeOptimal (the sweep
  // the request asks for, thesis 6.4).
  const bool by_limits = robot != nullptr && timed_by_limits(request);
  const bool angular = motion.max_angular_speed || motion.max_angular_acceleration;
  if (by_limits && !core::jerk_limited(robot->model) && !(angular && !joint) && (!time_optimal || asked_jerk)) {
    out.default_jerk = default_jerk_of(robot->model);
    out.defaulted.emplace(*robot);
    out.defaulted->model = core::with_default_jerk(robot->model, out.default_jerk->ramp_s);
    robot = &*out.defaulted;
  }
  out.jerk_from_model = by_limits && !asked_jerk && robot != nullptr &&
                        std::any_of(robot->model->limits.begin(), robot->model->limits.end(),
                                    [](const core::JointLimits& l) { return l.max_jerk.has_value(); });
  out.jerk_limited = asked_jerk || (out.jerk_from_model && !joint);
  return out;
}

// The rate [Hz] at which a joint move's torques are measured for its stretch (at least the
// cycle rate): the time-optimal checks' (core::TimeOptimalOptions::check_rate_hz).
constexpr double kTorqueCheckRateHz = 2'000.0;

// The trajectory of a request with a motion. `default_jerk`: set when the model's missing
// jerk limits were defaulted.
Expected<core::Trajectory> plan_trajectory(const Request& request, const Budget& budget, Clock::time_point deadline,
                                           OptimizerReports& reports, std::optional<DefaultJerk>& default_jerk) {
  core::MotionSpec motion = *request.motion;
  const Robot* robot = request.robot.get();
  const bool time_optimal = request.optimize && request.optimize->time_optimal;
  const bool joint = std::holds_alternative<core::JointMoveSpec>(request.geometry) ||
                     std::holds_alternative<JointMoveToPose>(request.geometry) ||
                     std::holds_alternative<core::JointPathSpec>(request.geometry);
  // Within every limit the model gives: where the limits time the motion and the model has
  // jerk limits, a path or a line is timed jerk-limited and a joint move is a double S, for
  // PlanTrajectory, StreamSamples and Execute alike (live execution keeps the model's jerk
  // limits and refuses a plan that breaks them). See limits_timing.
  LimitsTiming timed = limits_timing(request, joint);
  const bool angular = motion.max_angular_speed || motion.max_angular_acceleration;
  if (timed.defaulted) {
    default_jerk = timed.default_jerk;
    robot = &*timed.defaulted;
  }
  const bool jerk_from_model = timed.jerk_from_model;
  const bool jerk_limited = timed.jerk_limited;
  if (jerk_from_model && joint) motion.profile = core::ProfileShape::kSCurve;
  const auto joint_move = [&](const core::JointMoveSpec& move) -> Expected<core::Trajectory> {
    auto plan = core::plan_joint_move(robot->model, move, motion);
    if (!plan) return tl::unexpected(invalid(std::move(plan.error())));
    // Timed by the limits on an arm with torque limits: stretched as a whole until every
    // torque holds (a uniform time scaling, the speed scale's: exact; checked at the check
    // rate, then by the joint report at the cycle rate). Gravity beyond a limit: the report
    // names it.
    if (motion.duration_s == 0.0) {
      const double f = core::torque_stretch(*plan, std::max(motion.cycle_rate_hz, kTorqueCheckRateHz));
      if (f > 1.0 && std::isfinite(f)) {
        core::MotionSpec stretched = motion;
        stretched.speed_scale /= f * (1.0 + 1e-6);
        plan = core::plan_joint_move(robot->model, move, stretched);
        if (!plan) return tl::unexpected(invalid(std::move(plan.error())));
      }
    }
    return core::Trajectory(std::in_place_type<core::JointMovePlan>, std::move(*plan));
  };
  // The tool's angular limits are imposed where the motion is as fast as its limits allow:
  // the time-optimal sweep, a line's minimum time. Elsewhere they would be ignored: refused.
  const std::string angular_field = motion.max_angular_speed ? "motion.maxAngularSpeed" : "motion.maxAngularAcceleration";
  const bool path_or_line = !joint;
  if (const auto* waypoints = std::get_if<core::JointPathSpec>(&request.geometry)) {
    // Jerk-limited unless the sweep alone is asked for (optimize.timing.timeOptimal).
    return joint_path_trajectory(*waypoints, motion, *robot, !time_optimal || jerk_limited, budget, deadline, reports);
  }
  if (angular && path_or_line) {
    const bool line = !std::holds_alternative<core::PathSpec>(request.geometry);
    std::string why;
    if (jerk_from_model && !joint) {
      why = "is not imposed on the fastest motion of a robot with jerk limits (" + robot->model->name +
            "'s), which is timed jerk-limited (its NLP has no angular rows): drop it, or give a durationS";
    } else if (jerk_limited) {
      why = "is not imposed by optimize.timing.jerkLimited (its NLP has no angular rows): use timeOptimal, or drop it";
    } else if (!time_optimally_timed(motion, robot != nullptr, time_optimal, false) &&
               !(line && motion.duration_s == 0.0)) {
      why = "is imposed where the motion is as fast as its limits allow (durationS 0: the time-optimal timing, a "
            "line's minimum time); this motion is timed by its " +
            std::string(motion.duration_s > 0.0 ? "duration" : "S-curve without a robot") + ", which it would not bound";
    }
    if (!why.empty()) return tl::unexpected(invalid(core::Violations{{angular_field, why}}));
  }
  const auto linear_move = [&](const core::LinearMoveSpec& move) -> Expected<core::Trajectory> {
    // With a robot and no duration (or optimize.timing): the fastest line within the joint
    // limits and the Cartesian ones given, on the time-optimal sweep of the straight path.
    if (robot != nullptr && time_optimally_timed(motion, true, time_optimal, jerk_limited) &&
        (move.goal.p_WT - move.start.p_WT).norm() > 0.0) {
      if (auto bad = pose_errors(move, motion)) return tl::unexpected(std::move(*bad));
      auto line = straight_path(move);
      if (!line) return tl::unexpected(std::move(line.error()));
      auto timing = time_optimal_timing(line->path, line->orientation, motion, robot, jerk_limited, budget, deadline,
                                        reports);
      if (!timing) return tl::unexpected(std::move(timing.error()));
      return core::Trajectory(std::in_place_type<core::PathMotion>,
                              core::PathMotion{std::move(line->path), std::move(*timing), std::move(line->orientation)});
    }
    auto plan = core::plan_linear_move(move, motion);
    if (!plan) return tl::unexpected(invalid(std::move(plan.error())));
    return core::Trajectory(std::in_place_type<core::LinearMovePlan>, std::move(*plan));
  };
  if (const auto* move = std::get_if<core::JointMoveSpec>(&request.geometry)) return joint_move(*move);
  if (const auto* move = std::get_if<core::LinearMoveSpec>(&request.geometry)) return linear_move(*move);
  if (const auto* move = std::get_if<JointMoveToPose>(&request.geometry)) {
    auto chosen = resolve(*move, *robot, budget);
    if (!chosen) return tl::unexpected(std::move(chosen.error()));
    return joint_move(chosen->spec);
  }
  if (const auto* move = std::get_if<LinearMoveToJoints>(&request.geometry)) {
    auto spec = resolve(*move, *robot);
    if (!spec) return tl::unexpected(std::move(spec.error()));
    return linear_move(*spec);
  }
  auto spec = optimized_path(request, budget, deadline, reports);
  if (!spec) return tl::unexpected(std::move(spec.error()));
  auto path = build(*spec);
  if (!path) return tl::unexpected(std::move(path.error()));
  // A straight start keeps the tool as the robot holds it at its initial joints (or the
  // world axes without a robot): see plan_orientation.
  const Eigen::Quaterniond start_W =
      request.start_orientation ? *request.start_orientation
      : robot                   ? Eigen::Quaterniond(core::forward_kinematics(robot->model, robot->seed).rotation())
                                : Eigen::Quaterniond::Identity();
  auto orientation = core::plan_orientation(*path, start_W);
  if (!orientation) return tl::unexpected(invalid(core::prefixed(std::move(orientation.error()), "path.")));
  // As fast as the limits allow: the time-optimal timing, with a robot (joint limits) or
  // without (Cartesian limits; the S-curve keeps its minimum-time double S, whose jerk bound
  // the sweep does not model, unless jerkLimited asks for the NLP).
  if (time_optimally_timed(motion, robot != nullptr, time_optimal, jerk_limited)) {
    auto timing = time_optimal_timing(*path, *orientation, motion, robot, jerk_limited, budget, deadline, reports);
    if (!timing) return tl::unexpected(std::move(timing.error()));
    return core::Trajectory(std::in_place_type<core::PathMotion>,
                            core::PathMotion{std::move(*path), std::move(*timing), std::move(*orientation)});
  }
  auto timing = core::plan_motion(*path, motion);
  if (!timing) return tl::unexpected(invalid(std::move(timing.error())));
  return core::Trajectory(std::in_place_type<core::PathMotion>,
                          core::PathMotion{std::move(*path), std::move(*timing), std::move(*orientation)});
}

void add(ToolPeaks& peaks, const core::TrajectorySample& sample) {
  peaks.speed = std::max(peaks.speed, sample.speed);
  peaks.acceleration = std::max(peaks.acceleration, sample.tool.a_WT.norm());
  peaks.angular_speed = std::max(peaks.angular_speed, sample.tool.omega_WT.norm());
}

// The joint-space pass over every sample (IK at each): the joint report and the tool's peaks.
struct RobotPass {
  core::JointMotionReport joints;
  ToolPeaks peaks;
  core::JointVector last;  ///< the joints of the last sample
};

// A path is followed from where the robot is: its first tool pose must be the pose of the
// robot's initial joints (within the robot's start tolerances), else kUnattainable on
// `robot.initialJoints` with the distance.
std::optional<Error> starts_at_robot(const core::Trajectory& trajectory, const Robot& robot) {
  if (!std::holds_alternative<core::PathMotion>(trajectory)) return std::nullopt;
  core::TrajectorySampler sampler(trajectory, nullptr, {});
  core::TrajectorySample first;
  if (!sampler.next(first)) return std::nullopt;
  const Eigen::Isometry3d X = core::forward_kinematics(robot.model, robot.seed);
  const double dp = (first.tool.X_WT.translation() - X.translation()).norm();
  const double dr = Eigen::AngleAxisd(first.tool.X_WT.linear() * X.linear().transpose()).angle();
  if (dp <= robot.start_position_tolerance && dr <= robot.start_orientation_tolerance) return std::nullopt;
  return invalid(core::Violations{core::unattainable(
      "robot.initialJoints",
      "the path starts " + core::number(dp, 6) + " m and " + core::number(dr, 6) +
          " rad from the tool pose of the robot's initial joints (tolerances " +
          core::number(robot.start_position_tolerance) + " m, " + core::number(robot.start_orientation_tolerance) +
          " rad: robot.startPositionTolerance, robot.startOrientationTolerance): move the robot to the path's "
          "start first (a jointMove with goalPose), or give initialJoints there")});
}

// The Cartesian limits that `motion`'s samples are measured against in the binding report:
// a path's or a line's, as given (none for a joint move, whose tool follows no path).
core::CartesianLimits cartesian_limits(const core::MotionSpec& motion, bool tool_path) {
  if (!tool_path) return {};
  return {motion.max_speed.value_or(0.0), motion.max_acceleration.value_or(0.0), motion.max_angular_speed.value_or(0.0),
          motion.max_angular_acceleration.value_or(0.0)};
}

bool joint_geometry(const Geometry& geometry) {
  return std::holds_alternative<core::JointMoveSpec>(geometry) || std::holds_alternative<JointMoveToPose>(geometry) ||
         std::holds_alternative<core::JointPathSpec>(geometry);
}

Expected<RobotPass> robot_pass(const core::Trajectory& trajectory, const Robot& robot,
                               const core::CartesianLimits& cartesian, const Budget& budget) {
  core::TrajectorySampler sampler(trajectory, &robot.model.model(), robot.seed);
  core::JointReportBuilder builder(robot.model, robot.branch_tolerance);
  builder.set_cartesian_limits(cartesian);
  core::TrajectorySample sample;
  ToolPeaks peaks;
  while (sampler.next(sample)) {
    const std::size_t k = sampler.index() - 1;
    builder.add(k, sample.t, sample.s, sample.joints, &sample.tool);
    add(peaks, sample);
    if (k % kSamplesPerCheck == 0) {
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
    }
  }
  return RobotPass{builder.report(), peaks, sample.joints.q};
}

// A straight line to joint values must end at them, not on another branch of their pose.
std::optional<Error> ends_at_goal(const Geometry& geometry, const core::JointVector& last) {
  const auto* move = std::get_if<LinearMoveToJoints>(&geometry);
  if (move == nullptr || last.size() != static_cast<Eigen::Index>(move->goal.size())) return std::nullopt;
  double worst = 0.0;
  std::size_t joint = 0;
  for (std::size_t i = 0; i < move->goal.size(); ++i) {
    const double d = std::abs(last(static_cast<Eigen::Index>(i)) - move->goal[i]);
    if (d > worst) worst = d, joint = i;
  }
  if (worst <= kGoalJointTolerance) return std::nullopt;
  return invalid(core::Violations{core::unattainable(
      "linearMove.goalJoints", "the straight line brings the robot to the goal's pose on another branch: joint " +
                                   std::to_string(joint) + " ends " + core::number(worst, 6) +
                                   " from its goal value; reach these joints with a jointMove")});
}

// The largest step of the joints the redundancy optimiser chooses [s]: 100 Hz, the thesis's
// rate, whatever the cycle rate (between them the samples follow the reference's spline,
// JointTracker::set_reference), and at most kMaxRedundancySteps steps (a longer motion gets
// longer steps: the problem's size, some 4 residual blocks a step, stays bounded).
constexpr double kRedundancyStepS = 0.01;
constexpr std::size_t kMaxRedundancySteps = 20'000;

// How a choice serves a timing made again along it (optimize_joints, retime_along_choices).
enum class Serve {
  kNo,            // the limits as constraints on the motion's timing (a fixed duration, a line)
  kPeaks,         // the limits' rounds, with the room of a path 1 / kServedLimitScale faster
  kLeastSquares,  // the criteria alone
};
constexpr double kServedLimitScale = 0.95;

// Coordinates chosen at uniform times (a JointReference in time), with the path's arc length
// at those times `arc` (non-decreasing, from 0), as functions of the arc length: their values
// at as many points uniform in s over [0, length], each at the time the motion passes there
// (linear in s between the times sampled).
std::vector<core::JointVector> along_path(const core::JointReference& chosen, const std::vector<double>& arc,
                                          double length) {
  const std::size_t M = arc.size() - 1;
  std::vector<core::JointVector> values(M + 1);
  core::JointVector rate, acceleration;
  std::size_t k = 0;
  for (std::size_t m = 0; m <= M; ++m) {
    const double s = length * static_cast<double>(m) / static_cast<double>(M);
    while (k + 1 < M && arc[k + 1] < s) ++k;
    const double ds = arc[k + 1] - arc[k];
    const double f = ds > 0.0 ? std::clamp((s - arc[k]) / ds, 0.0, 1.0) : 0.0;
    chosen.at((static_cast<double>(k) + f) * chosen.dt(), values[m], rate, acceleration);
  }
  return values;
}

// The roll chosen at uniform times (one coordinate) as a function of the path's arc length,
// added to the roll the path had (`before`, or none: the poses the roll was chosen on were
// turned by it).
std::shared_ptr<const core::RollProfile> roll_along_path(const core::JointReference& roll, const std::vector<double>& arc,
                                                       double length, const core::RollProfile* before) {
  const std::vector<core::JointVector> values = along_path(roll, arc, length);
  std::vector<double> phi(values.size());
  double had = 0.0, had_s = 0.0, had_ss = 0.0;
  for (std::size_t m = 0; m < values.size(); ++m) {
    if (before != nullptr)
      before->at(length * static_cast<double>(m) / static_cast<double>(values.size() - 1), had, had_s, had_ss);
    phi[m] = had + values[m](0);
  }
  return std::make_shared<const core::RollProfile>(std::move(phi), length);
}

// optimize.redundancy on a path motion or a straight line with a redundant arm, and every
// straight line to goal joints on one: the tool's poses and the tracker's joints at uniform
// times (the sample-by-sample choice, the start), the joints chosen by the optimiser for the
// whole motion (a line to goal joints ends at them exactly: `goal`, held), attached to the
// motion as the reference its samples follow. With robot.toolAxisFree the optimiser works on
// the arm with the tool's roll as one more joint (core::with_tool_roll; from 0, the planned
// orientation, and back to 0 at a held goal), and the roll it chooses is attached too: a
// path's as a function of its arc length in its orientation plan (roll_along_path), a line's
// in time (core::apply_roll); every sample's tool is turned by it and the real joints follow.
// A report whatever happens; the motion is left as it was when the optimiser finds nothing
// better or fails. `serve` (a path timed by the limits, to be timed again along the choice:
// retime_along_choices): the optimum taken whatever its peaks on this timing (the next timing
// is made along it), chosen by the limits' rounds with room to speed up or by the criteria
// alone, and a redundant arm's joints attached as a function of the arc length, as the roll.
std::optional<Error> optimize_joints(core::Trajectory& trajectory, const Robot& robot,
                                     const optim::RedundancyWeights& weights, const std::vector<double>* goal,
                                     const Budget& budget, Clock::time_point deadline, OptimizerReports& reports,
                                     Serve serve) {
  std::shared_ptr<const core::JointReference>* slot = nullptr;
  std::shared_ptr<const core::JointReference>* line_roll = nullptr;
  core::PathMotion* path_motion = nullptr;
  if (auto* motion = std::get_if<core::PathMotion>(&trajectory)) slot = &motion->joints, path_motion = motion;
  if (auto* line = std::get_if<core::LinearMovePlan>(&trajectory)) slot = &line->joints, line_roll = &line->roll;
  if (slot == nullptr) return std::nullopt;
  const bool roll = robot.tool_axis_free;
  const auto n = static_cast<Eigen::Index>(robot.model->dof());
  // The joints with the roll after them (0: the orientation as planned).
  const auto with_roll = [&](const core::JointVector& q) {
    if (!roll) return q;
    core::JointVector out(n + 1);
    out << q, 0.0;
    return out;
  };
  const double duration = core::duration(trajectory);
  const std::size_t steps = std::clamp<std::size_t>(
      static_cast<std::size_t>(std::ceil(duration / kRedundancyStepS - 1e-9)), 1, kMaxRedundancySteps);
  const double dt = duration / static_cast<double>(steps);
  std::vector<Eigen::Isometry3d> poses;
  std::vector<core::JointVector> joints;
  std::vector<double> arc;  // s at each step [m]
  poses.reserve(steps + 1);
  joints.reserve(steps + 1);
  arc.reserve(steps + 1);
  {
    core::TrajectorySampler sampler(trajectory, &robot.model.model(), robot.seed);
    core::TrajectorySample sample;
    for (std::size_t k = 0; k <= steps; ++k) {
      sampler.at(static_cast<double>(k) * dt, sample);
      if (!sample.joints.converged) {
        optim::OptimizerReport report;
        report.status = optim::OptimizerStatus::kFailed;
        report.message = "the arm does not follow the path at t = " + core::number(sample.t, 6) +
                         " s: there is no motion to improve";
        reports.redundancy = report;
        return std::nullopt;
      }
      poses.push_back(sample.tool.X_WT);
      joints.push_back(with_roll(sample.joints.q));
      arc.push_back(sample.s);
    }
  }
  optim::RedundancyOptions options;
  options.weights = weights;
  if (goal != nullptr) {
    options.goal = with_roll(Eigen::Map<const Eigen::VectorXd>(goal->data(), static_cast<Eigen::Index>(goal->size())));
    options.hold_goal = true;
  }
  const bool serve_timing = serve != Serve::kNo && path_motion != nullptr;
  if (serve_timing) {
    options.take_optimum = true;
    options.limit_scale = serve == Serve::kPeaks ? kServedLimitScale : 1.0;
    options.within_limits = serve == Serve::kPeaks;
  }
  options.time_budget_s = std::max(1e-3, std::chrono::duration<double>(deadline - Clock::now()).count());
  options.stopped = [&] { return budget.stop_requested() || Clock::now() >= deadline; };
  const auto started = Clock::now();
  auto result = optim::optimize_redundancy(roll ? core::with_tool_roll(robot.model) : robot.model, poses, dt, joints,
                                           options);
  observe(budget, "redundancy", started);
  if (!result) return invalid(core::prefixed(std::move(result.error()), "optimize.redundancy."));
  reports.redundancy = result->report;
  const optim::OptimizerStatus status = result->report.status;
  if (status == optim::OptimizerStatus::kFailed || status == optim::OptimizerStatus::kNoImprovement) return std::nullopt;
  if (roll) {
    std::vector<core::JointVector> angles(result->q.size(), core::JointVector(1));
    for (std::size_t k = 0; k < angles.size(); ++k) {
      angles[k](0) = -result->q[k](n);  // X_WT(q) RotZ(phi) holds the pose: the real tool is turned by -phi
      result->q[k].conservativeResize(n);
    }
    if (line_roll != nullptr) {
      *line_roll = std::make_shared<const core::JointReference>(std::move(angles), dt);
    } else {
      path_motion->orientation.roll = roll_along_path(core::JointReference(std::move(angles), dt), arc,
                                                      path_motion->path.length(), path_motion->orientation.roll.get());
    }
    if (n <= 6) return std::nullopt;  // the tracker follows the rolled pose: no self-motion left
  }
  if (serve_timing) {
    const double length = path_motion->path.length();
    *slot = std::make_shared<const core::JointReference>(
        along_path(core::JointReference(std::move(result->q), dt), arc, length),
        length / static_cast<double>(arc.size() - 1), core::ReferenceParameter::kArcLength);
    return std::nullopt;
  }
  *slot = std::make_shared<const core::JointReference>(std::move(result->q), dt);
  return std::nullopt;
}

MotionSummary summary_of(const core::Trajectory& trajectory, const ToolPeaks& peaks) {
  return {core::duration(trajectory), core::sample_count(trajectory), peaks, tangential_peak(trajectory), {}};
}

// The tool's pass without a robot (the samples without IK): its peaks and which of its
// Cartesian limits binds.
struct ToolPass {
  ToolPeaks peaks;
  std::vector<core::BindingStretch> binding;
};
Expected<ToolPass> tool_pass(const core::Trajectory& trajectory, const core::CartesianLimits& cartesian,
                             const Budget& budget) {
  core::TrajectorySampler sampler(trajectory, nullptr, {});
  core::ToolBindingBuilder binding;
  binding.set_cartesian_limits(cartesian);
  core::TrajectorySample sample;
  ToolPeaks peaks;
  while (sampler.next(sample)) {
    add(peaks, sample);
    binding.add(sampler.index() - 1, sample.t, sample.s, sample.tool);
    if (sampler.index() % kToolSamplesPerCheck == 0) {
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
    }
  }
  return ToolPass{peaks, binding.binding()};
}

// A motion with more samples than the server allows: it is streamed, followed by a robot
// (the IK runs at every sample) or summarised from its samples.
std::optional<Error> sample_limit(const core::Trajectory& trajectory, const Limits& limits) {
  const auto count = core::sample_count(trajectory);
  if (count <= limits.max_samples) return std::nullopt;
  return invalid(core::Violations{
      {"motion.durationS", "the motion has " + std::to_string(count) + " samples (" +
                               core::number(core::duration(trajectory), 6) +
                               " s at the cycle rate); this server streams and checks at most " +
                               std::to_string(limits.max_samples) + " per call" +
                               (limits.max_samples_name.empty() ? "" : " (" + limits.max_samples_name + ")") +
                               ": shorten it or lower cycleRateHz"}});
}

PathReport report_of(const core::Path& path) {
  PathReport report;
  report.achieved = core::achieved_geometry(path);
  report.closed_loop = core::closed_loop_error(path, report.achieved);
  report.geometry = core::geometry_report(path);
  return report;
}
}  // namespace detail

using namespace detail;

bool time_optimally_timed(const core::MotionSpec& motion, bool robot, bool time_optimal, bool jerk_limited) {
  const bool minimum_time = motion.duration_s == 0.0 && (robot || motion.profile == core::ProfileShape::kTrapezoidal);
  return time_optimal || jerk_limited || minimum_time;
}

void reserve_room(Request& request, double reserve) {
  const double factor = 1.0 - std::clamp(reserve, 0.0, 0.99);  // of every acceleration and jerk limit
  request.reserve = reserve;
  const bool robot = request.robot != nullptr;
  const bool time_optimal = request.optimize && request.optimize->time_optimal;
  const bool jerk_limited = request.optimize && request.optimize->jerk_limited;
  if (request.motion && time_optimally_timed(*request.motion, robot, time_optimal, jerk_limited)) {
    request.motion->acceleration_scale *= factor;
    request.motion_reserved = true;
    request.reserve_applied = reserve > 0.0;
  }
  for (Step& step : request.sequence) {
    const bool path = std::holds_alternative<core::PathSpec>(step.geometry);
    if (time_optimally_timed(step.motion, robot, path && time_optimal, path && jerk_limited)) {
      step.motion.acceleration_scale *= factor;
      request.reserve_applied = request.reserve_applied || reserve > 0.0;
    }
  }
}

std::optional<Error> check(const Budget& budget) {
  // A passed deadline first: an RPC is also cancelled then, and the kind should say why.
  if (budget.expired()) return Error{ErrorKind::kDeadlineExceeded, {}, {}, {}};
  if (budget.stop_requested()) return Error{ErrorKind::kStopped, {}, {}, {}};
  return std::nullopt;
}

const core::Path* Plan::followed_path() const {
  if (path) return &*path;
  if (trajectory) {
    if (const auto* motion = std::get_if<core::PathMotion>(&*trajectory)) return &motion->path;
  }
  return nullptr;
}

namespace {

// What Execute's reserve (reserve_room) changed in `result`, in words.
Expected<Plan> with_reserve_noted(Expected<Plan> result, const Request& request) {
  if (!result || !request.reserve_applied) return result;
  const std::string percent = core::number(100.0 * request.reserve, 4) + " %";
  const std::string scale = core::number(1.0 - request.reserve, 4);
  result->reserve = request.reserve;
  result->reserve_note =
      "the motions the limits time (no durationS: fastest paths and moves, robot.approach) keep " + percent +
      " of every acceleration and jerk limit free for speed changes (ExecuteOptions.accelerationReserve " +
      core::number(request.reserve, 4) + "): their speed-ups and slow-downs take longer than PlanTrajectory's and " +
      "StreamSamples' (theirs with motion.accelerationScale x " + scale +
      " are this plan); speed limits and motions with a durationS are kept";
  return result;
}

// How many times a motion timed by the limits is re-timed, slower, when the joints the
// redundancy optimiser chose break a limit its timing (made on the sample-by-sample joints)
// did not foresee (plan_request).
constexpr int kRetimes = 3;

// The factor f > 1 that stretches a motion's time so that the limit events fit: a velocity
// scales as 1/f, an acceleration as 1/f^2, a jerk as 1/f^3; 0 when an event is no such limit.
double stretch_for(const std::vector<core::LimitEvent>& violations) {
  double f = 1.0;
  for (const core::LimitEvent& e : violations) {
    if (!(e.limit > 0.0) || !std::isfinite(e.value)) return 0.0;
    const double ratio = std::abs(e.value) / e.limit;
    switch (e.kind) {
      case core::LimitKind::kVelocity: f = std::max(f, ratio); break;
      case core::LimitKind::kAcceleration: f = std::max(f, std::sqrt(ratio)); break;
      case core::LimitKind::kJerk: f = std::max(f, std::cbrt(ratio)); break;
      default: return 0.0;
    }
  }
  return f;
}

// How many times a redundant arm's joints are chosen again on the timing made along the last
// choice (retime_along_choices), and the least gain [relative] that asks for another round.
constexpr int kTimingRounds = 4;
constexpr double kTimingGain = 5e-3;

// A path timed by the limits whose free choices were just made (optimize_joints): the tool's
// roll (robot.toolAxisFree), a redundant arm's joints along the path (`serve`). Timed again
// along them (the seam of docs/kinematics.md: 1.53 s as planned), kept when faster; a
// redundant arm's joints are then chosen again on the new timing and the path timed again
// along them, while it gets faster by kTimingGain (at most kTimingRounds rounds). Where no
// timing is faster, joints chosen to serve the timing (taken whatever their peaks on the first
// timing) are dropped for the sample-by-sample ones the first timing was made for
// (`as_timed`, given with them); a roll alone stays (chosen within the limits).
std::optional<Error> retime_along_choices(core::Trajectory& trajectory, const Request& request,
                                          const optim::RedundancyWeights& weights, Serve serve,
                                          const core::Trajectory* as_timed, const Budget& budget,
                                          Clock::time_point deadline, OptimizerReports& reports) {
  auto* motion = std::get_if<core::PathMotion>(&trajectory);
  if (motion == nullptr || !reports.redundancy || !timed_by_limits(request)) return std::nullopt;
  // Timed as the first timing was: jerk-limited where the model's (or the defaulted) jerk
  // limits time it.
  const LimitsTiming timed = limits_timing(request, false);
  const bool jerk_limited = timed.jerk_limited;
  const Robot* robot = timed.defaulted ? &*timed.defaulted : request.robot.get();
  const auto chosen_joints = [&] {
    return motion->joints && motion->joints->over() == core::ReferenceParameter::kArcLength ? motion->joints : nullptr;
  };
  if (!motion->orientation.roll && !chosen_joints()) return std::nullopt;
  const double first = motion->timing.duration_s;
  // The last choice with the timing made along it, and the optimiser's report of that choice.
  std::optional<core::Trajectory> kept;
  std::optional<optim::OptimizerReport> kept_report;
  int timings = 0;
  for (int round = 0; round < kTimingRounds; ++round) {
    const double before = motion->timing.duration_s;
    OptimizerReports retimed = reports;
    auto timing = time_optimal_timing(motion->path, motion->orientation, *request.motion, robot, jerk_limited, budget,
                                      deadline, retimed, chosen_joints());
    if (!timing) {
      if (auto stop = check(budget)) return stop;
      break;  // the timing before stands
    }
    if (!(timing->duration_s < before)) break;
    motion->timing = std::move(*timing);
    reports.timing = std::move(retimed.timing);
    kept = trajectory;
    kept_report = reports.redundancy;
    ++timings;
    motion = std::get_if<core::PathMotion>(&trajectory);
    if (serve == Serve::kNo || !(motion->timing.duration_s < before * (1.0 - kTimingGain))) break;
    // Choose again on the new timing (from the joints that follow the last choice).
    if (auto refused = optimize_joints(trajectory, *request.robot, weights, nullptr, budget, deadline, reports, serve))
      return refused;
    if (auto stop = check(budget)) return stop;
    motion = std::get_if<core::PathMotion>(&trajectory);
    const auto status = reports.redundancy->status;
    if (status == optim::OptimizerStatus::kFailed || status == optim::OptimizerStatus::kNoImprovement) break;
  }
  // (The self-motion serves the timing only with the roll fixed: choose_joints.)
  const std::string what = serve == Serve::kNo ? "the roll" : "the joints";
  const std::string how = serve == Serve::kPeaks          ? " (the peaks weighed)"
                          : serve == Serve::kLeastSquares ? " (the criteria alone)"
                                                          : "";
  if (!kept) {
    if (as_timed != nullptr) trajectory = *as_timed;  // choose_joints says so
    return std::nullopt;
  }
  trajectory = std::move(*kept);
  reports.redundancy = std::move(kept_report);
  reports.redundancy->message += "; timed again along " + what + " chosen" + how + ": " + core::number(first, 4) +
                                 " s -> " + core::number(core::duration(trajectory), 4) + " s" +
                                 (timings > 1 ? " (chosen " + std::to_string(timings) + " times)" : "");
  return std::nullopt;
}

}  // namespace

// optimize_joints, and for a path timed by the limits the timing made again along the choices
// (retime_along_choices). A redundant arm's joints serve the timing as the tool's roll does,
// chosen two ways (the limits' rounds, the criteria alone: neither is the fastest on every
// path; on the thesis's paths each wins one) and the faster kept.
std::optional<Error> detail::choose_joints(core::Trajectory& trajectory, const Request& request,
                                           const optim::RedundancyWeights& weights,
                                           const std::vector<double>* goal, const Budget& budget,
                                           Clock::time_point deadline, OptimizerReports& reports) {
  // (A line to goal joints keeps the joints that end at them, chosen on its first timing; with
  // the tool's roll free too, the roll alone is timed again: the self-motion chosen with it
  // took the Panda's seam from 1.5 s to 4.6 s.)
  const bool serve_timing = std::holds_alternative<core::PathMotion>(trajectory) &&
                            request.robot->model->dof() > 6 && goal == nullptr && !request.robot->tool_axis_free &&
                            timed_by_limits(request);
  if (!serve_timing) {
    if (auto refused = optimize_joints(trajectory, *request.robot, weights, goal, budget, deadline, reports, Serve::kNo))
      return refused;
    if (auto stop = check(budget)) return stop;
    if (!request.robot->tool_axis_free) return std::nullopt;
    return retime_along_choices(trajectory, request, weights, Serve::kNo, nullptr, budget, deadline, reports);
  }
  const core::Trajectory as_timed = trajectory;
  std::optional<core::Trajectory> best;
  OptimizerReports best_reports;
  for (const Serve serve : {Serve::kPeaks, Serve::kLeastSquares}) {
    core::Trajectory candidate = as_timed;
    OptimizerReports candidate_reports = reports;
    if (auto refused =
            optimize_joints(candidate, *request.robot, weights, goal, budget, deadline, candidate_reports, serve))
      return refused;
    if (auto stop = check(budget)) return stop;
    if (auto refused = retime_along_choices(candidate, request, weights, serve, &as_timed, budget, deadline,
                                            candidate_reports))
      return refused;
    if (!best || core::duration(candidate) < core::duration(*best)) {
      best = std::move(candidate);
      best_reports = std::move(candidate_reports);
    }
  }
  if (!(core::duration(*best) < core::duration(as_timed)) && best_reports.redundancy)
    best_reports.redundancy->message +=
        "; the joints chosen (the peaks weighed, and the criteria alone) do not make the motion faster: the "
        "sample-by-sample joints are kept";
  trajectory = std::move(*best);
  reports = std::move(best_reports);
  return std::nullopt;
}

namespace {

Expected<Plan> plan_request(const Request& request, const Budget& budget, const Limits& limits, Use use,
                            int retimes_left = kRetimes) {
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  if (!request.sequence.empty()) return plan_sequence(request, budget, limits, use);
  if (auto approached = with_approach(request)) {
    if (!*approached) return tl::unexpected(std::move(approached->error()));
    return with_reserve_noted(plan_sequence(**approached, budget, limits, use), **approached);
  }
  const auto deadline = optimizer_deadline(request, budget);
  Plan result;
  result.robot = request.robot;
  if (!request.motion) {  // the path's geometry only
    auto spec = optimized_path(request, budget, deadline, result.optimizers);
    if (!spec) return tl::unexpected(std::move(spec.error()));
    auto path = build(*spec);
    if (!path) return tl::unexpected(std::move(path.error()));
    if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
    if (use == Use::kPlan) result.path_report = report_of(*path);
    result.path = std::move(*path);
    return result;
  }
  auto trajectory = plan_trajectory(request, budget, deadline, result.optimizers, result.default_jerk);
  if (!trajectory) return tl::unexpected(std::move(trajectory.error()));
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  result.trajectory = std::move(*trajectory);
  if (use == Use::kPlan) {
    if (const core::Path* path = result.followed_path()) result.path_report = report_of(*path);
  }
  if (auto refused = sample_limit(*result.trajectory, limits)) return tl::unexpected(std::move(*refused));
  if (request.robot) {
    if (auto refused = starts_at_robot(*result.trajectory, *request.robot)) return tl::unexpected(std::move(*refused));
    // A straight line to goal joints on a redundant arm ends at them only if its self-motion
    // is chosen for the whole line: by the user's criteria, or the joints' acceleration.
    // With the tool's roll free, the roll is chosen the same way (and a line to goal joints
    // ends at them: its roll back to 0).
    const auto* to_joints = std::get_if<LinearMoveToJoints>(&request.geometry);
    const bool free_roll = request.robot->tool_axis_free;
    const bool redundant_line = to_joints != nullptr && (request.robot->model->dof() > 6 || free_roll);
    if ((request.optimize && request.optimize->redundancy) || redundant_line || free_roll) {
      optim::RedundancyWeights weights;
      weights.acceleration = 1.0;
      if (request.optimize && request.optimize->redundancy) weights = *request.optimize->redundancy;
      if (auto refused = choose_joints(*result.trajectory, request, weights, redundant_line ? &to_joints->goal : nullptr,
                                       budget, deadline, result.optimizers))
        return tl::unexpected(std::move(*refused));
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
    }
    auto pass = robot_pass(*result.trajectory, *request.robot,
                           cartesian_limits(*request.motion, !joint_geometry(request.geometry)), budget);
    if (!pass) return tl::unexpected(std::move(pass.error()));
    auto& [joints, peaks, last] = *pass;
    // Timed by the limits on the sample-by-sample joints, then given others: where these break
    // a velocity, acceleration or jerk limit, the motion is timed again, slower by what the
    // worst of them needs (and the joints chosen again on the new timing).
    const bool chosen = (request.optimize && request.optimize->redundancy) || redundant_line || free_roll;
    if (chosen && timed_by_limits(request) && !joints.feasible() && retimes_left > 0 && result.optimizers.redundancy &&
        (result.optimizers.redundancy->status == optim::OptimizerStatus::kConverged ||
         result.optimizers.redundancy->status == optim::OptimizerStatus::kIterationLimit)) {
      if (const double f = stretch_for(joints.violations); f > 1.0) {
        Request slower = request;
        slower.motion->speed_scale /= 1.01 * f;
        auto again = plan_request(slower, budget, limits, use, retimes_left - 1);
        // Said once, by the call whose re-timing the plan kept (the deepest).
        constexpr std::string_view kSaid = "; timed again at motion.speedScale ";
        if (again && again->optimizers.redundancy && again->optimizers.redundancy->message.find(kSaid) == std::string::npos)
          again->optimizers.redundancy->message += std::string(kSaid) + core::number(slower.motion->speed_scale, 4) +
                                                   " so that the joints chosen keep their limits";
        if (again || retimes_left > 1) return again;
      }
    }
    // reportOnly streams a motion that breaks joint limits (for simulation and analysis),
    // never one whose IK failed or jumped branches: those joints would be meaningless.
    const bool only_limits = std::all_of(joints.violations.begin(), joints.violations.end(), [](const auto& e) {
      return e.kind != core::LimitKind::kIk && e.kind != core::LimitKind::kBranch;
    });
    const bool allowed = request.robot->report_only && (use == Use::kPlan || only_limits);
    if (!joints.feasible() && !allowed) {
      return tl::unexpected(Error{ErrorKind::kRobotCannotFollow, {}, joints.violations, request.robot->model->name,
                                  request.robot->report_only});
    }
    if (joints.feasible()) {
      if (auto refused = ends_at_goal(request.geometry, last)) return tl::unexpected(std::move(*refused));
    }
    if (use == Use::kPlan) result.summary = summary_of(*result.trajectory, peaks);
    measured_binding(result.optimizers, joints.binding);
    result.joints = std::move(joints);
  } else if (use == Use::kPlan) {
    auto pass = tool_pass(*result.trajectory,
                          cartesian_limits(*request.motion, !joint_geometry(request.geometry)), budget);
    if (!pass) return tl::unexpected(std::move(pass.error()));
    result.summary = summary_of(*result.trajectory, pass->peaks);
    result.summary->binding = pass->binding;
    measured_binding(result.optimizers, pass->binding);
  }
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  return result;
}

}  // namespace

Expected<Plan> plan(const Request& request, const Budget& budget, const Limits& limits, Use use) {
  return with_reserve_noted(plan_request(request, budget, limits, use), request);
}

Expected<std::vector<core::FrameConstraints>> convert(const core::PathSpec& path) {
  auto frames = core::convert_path(path);
  if (!frames) return tl::unexpected(invalid(core::prefixed(std::move(frames.error()), "path.")));
  return std::move(*frames);
}

Expected<Analysis> analyze(const Request& request, std::size_t points, const Budget& budget) {
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  OptimizerReports reports;
  auto spec = optimized_path(request, budget, optimizer_deadline(request, budget), reports);
  if (!spec) return tl::unexpected(std::move(spec.error()));
  auto path = build(*spec);
  if (!path) return tl::unexpected(std::move(path.error()));
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  Analysis analysis{std::move(*path), {}};
  auto profile = core::analyze(analysis.path, points, [&budget] { return budget.stop_requested() || budget.expired(); });
  if (!profile) return tl::unexpected(std::move(*check(budget)));
  analysis.points = std::move(*profile);
  return analysis;
}

}  // namespace geotraj::planner

