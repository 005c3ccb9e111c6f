// Sequences (PlanRequest.sequence) and the approach move: steps planned one after the other,
// each starting where the previous one ends, blended chains of lines, every violation named
// from the request's root. See planner.hpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "core/geometry/analysis.hpp"
#include "core/motion/orientation.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/plan_detail.hpp"
#include "planner/planner.hpp"

namespace geotraj::planner::detail {

namespace {

// ---------------------------------------------------------------------------------------
// Sequences


// Violations of step i named from the request's root: the step's own fields under
// `sequence[i].`, the request's motion (when the step has none of its own) and robot as
// they are, the step said in the message.
Error in_step(Error error, std::size_t i, const Step& step) {
  if (step.name) {  // a step the planner added: its own name, or the request's fields as they are
    if (!step.name->empty()) {
      for (auto& v : error.violations) {
        v.description = "the approach move: " + v.field + " " + v.description;
        v.field = *step.name;
      }
    }
    return error;
  }
  const std::string prefix = "sequence[" + std::to_string(i) + "].";
  for (auto& v : error.violations) {
    if (step_owns(v.field, step.own_motion ? &step.own_motion_fields : nullptr)) {
      v.field = prefix + v.field;
    } else {
      v.description += " (in " + prefix.substr(0, prefix.size() - 1) + ")";
    }
  }
  return error;
}

double rotation_angle(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return Eigen::AngleAxisd(a.toRotationMatrix() * b.toRotationMatrix().transpose()).angle();
}

std::string kind_of(const Geometry& g) {
  if (std::holds_alternative<core::PathSpec>(g)) return "path";
  if (std::holds_alternative<core::JointMoveSpec>(g) || std::holds_alternative<JointMoveToPose>(g)) return "jointMove";
  if (std::holds_alternative<core::JointPathSpec>(g)) return "jointPath";
  return "linearMove";
}

// Where the previous step ended: the tool pose and, with a robot, the joints.
struct StepEnd {
  core::ToolPose pose;
  core::JointVector q;
};

// Step i's geometry with its start at `end` (absent) or checked against it (given).
Expected<Geometry> started_at(const Step& step, std::size_t i, const StepEnd& end, const Robot* robot) {
  const std::string field = "sequence[" + std::to_string(i) + "].";
  Geometry g = step.geometry;
  const auto joint_start = [&](std::vector<double>& start) -> std::optional<Error> {
    if (!step.start_given) {
      start.assign(end.q.data(), end.q.data() + end.q.size());
      return std::nullopt;
    }
    if (start.size() != static_cast<std::size_t>(end.q.size())) return std::nullopt;  // plan_joint_move names it
    for (std::size_t j = 0; j < start.size(); ++j) {
      const double d = std::abs(start[j] - end.q(static_cast<Eigen::Index>(j)));
      if (d > kSequenceJointTolerance) {
        return invalid(core::Violations{
            {field + "jointMove.start[" + std::to_string(j) + "]",
             "is " + core::number(d, 6) + " from joint " + std::to_string(j) + "'s value where sequence[" +
                 std::to_string(i - 1) + "] ends (" + core::number(end.q(static_cast<Eigen::Index>(j))) +
                 "): a step starts where the previous one ends; leave `start` out to take that"}});
      }
    }
    return std::nullopt;
  };
  const auto pose_start = [&](core::ToolPose& start) -> std::optional<Error> {
    if (!step.start_given) {
      start = end.pose;
      return std::nullopt;
    }
    const double dp = (start.p_WT - end.pose.p_WT).norm();
    const double dr = start.q_WT.norm() > 0.0 ? rotation_angle(start.q_WT.normalized(), end.pose.q_WT) : 0.0;
    const double tp = robot ? robot->start_position_tolerance : kStartPositionTolerance;
    const double tr = robot ? robot->start_orientation_tolerance : kStartOrientationTolerance;
    if (dp <= tp && dr <= tr) {
      start = end.pose;  // exactly where the previous step ended
      return std::nullopt;
    }
    return invalid(core::Violations{{field + "linearMove.start",
                                     "is " + core::number(dp, 6) + " m and " + core::number(dr, 6) +
                                         " rad from where sequence[" + std::to_string(i - 1) + "] ends (tolerances " +
                                         core::number(tp) + " m, " + core::number(tr) +
                                         " rad): a step starts where the previous one ends; leave `start` out to "
                                         "take that"}});
  };
  // A joint path's first waypoint is its start: there (and then exactly there).
  const auto path_start = [&](core::JointPathSpec& path) -> std::optional<Error> {
    if (path.waypoints.empty() || path.waypoints.front().positions.size() != static_cast<std::size_t>(end.q.size()))
      return std::nullopt;  // build_joint_path names it
    auto& first = path.waypoints.front().positions;
    for (std::size_t j = 0; j < first.size(); ++j) {
      const double d = std::abs(first[j] - end.q(static_cast<Eigen::Index>(j)));
      if (!(d <= kSequenceJointTolerance)) {
        return invalid(core::Violations{
            {field + "jointPath.waypoints[0].positions[" + std::to_string(j) + "]",
             "is " + core::number(d, 6) + " from joint " + std::to_string(j) + "'s value where sequence[" +
                 std::to_string(i - 1) + "] ends (" + core::number(end.q(static_cast<Eigen::Index>(j))) +
                 "): a step starts where the previous one ends"}});
      }
    }
    first.assign(end.q.data(), end.q.data() + end.q.size());
    return std::nullopt;
  };
  std::optional<Error> error;
  if (auto* m = std::get_if<core::JointPathSpec>(&g)) error = path_start(*m);
  if (auto* m = std::get_if<core::JointMoveSpec>(&g)) error = joint_start(m->start);
  if (auto* m = std::get_if<JointMoveToPose>(&g)) error = joint_start(m->start);
  if (auto* m = std::get_if<core::LinearMoveSpec>(&g)) error = pose_start(m->start);
  if (auto* m = std::get_if<LinearMoveToJoints>(&g)) error = pose_start(m->start);
  if (error) return tl::unexpected(std::move(*error));
  return g;
}

// A path step must start where the previous step ended (its first sample, `first`).
std::optional<Error> path_starts_at(const core::TrajectorySample& first, const StepEnd& end, std::size_t i,
                                    const Robot* robot) {
  const double dp = (first.tool.X_WT.translation() - end.pose.p_WT).norm();
  const double dr = rotation_angle(first.q_WT, end.pose.q_WT);
  const double tp = robot ? robot->start_position_tolerance : kStartPositionTolerance;
  const double tr = robot ? robot->start_orientation_tolerance : kStartOrientationTolerance;
  if (dp <= tp && dr <= tr) return std::nullopt;
  return invalid(core::Violations{core::unattainable(
      "sequence[" + std::to_string(i) + "].path",
      "starts " + core::number(dp, 6) + " m and " + core::number(dr, 6) + " rad from where sequence[" +
          std::to_string(i - 1) + "] ends (tolerances " + core::number(tp) + " m, " + core::number(tr) +
          " rad): its first key frame must be there, with the tool's orientation (a frame normal, or a "
          "straight start that keeps the orientation)")});
}

double arc_length_of(const core::StepMotion& m) {
  if (const auto* path = std::get_if<core::PathMotion>(&m)) return path->path.length();
  if (const auto* line = std::get_if<core::LinearMovePlan>(&m)) return line->length;
  return 0.0;
}

core::StepMotion as_step(core::Trajectory&& t) {
  if (auto* m = std::get_if<core::PathMotion>(&t)) return core::StepMotion(std::move(*m));
  if (auto* m = std::get_if<core::JointMovePlan>(&t)) return core::StepMotion(std::move(*m));
  if (auto* m = std::get_if<core::JointPathPlan>(&t)) return core::StepMotion(std::move(*m));
  return core::StepMotion(std::move(std::get<core::LinearMovePlan>(t)));
}

// The steps first..last (joined by blended corners) as one path: each line's start where
// the previous piece ends (or checked there), a path's first frame checked there, the chain
// blended by core::blend_chain. `end` is where the step before `first` ended.
Expected<core::BlendedChain> blended_chain(const Request& request, std::size_t first, std::size_t last,
                                           const StepEnd& end, const Robot* robot,
                                           std::optional<Eigen::Quaterniond>& start_orientation) {
  std::vector<core::BlendPiece> pieces;
  std::vector<double> tolerances;
  std::vector<std::string> names;
  StepEnd at = end;  // where the previous piece ends
  const auto named = [](std::size_t i) { return "sequence[" + std::to_string(i) + "]"; };
  for (std::size_t k = first; k <= last; ++k) {
    const Step& step = request.sequence[k];
    names.push_back(named(k));
    if (k < last) tolerances.push_back(step.blend_tolerance);
    if (k > first && step.own_motion) {
      return tl::unexpected(invalid(core::Violations{
          {named(k) + ".motion", "a step blended into the previous one moves on the same timing, " + named(first) +
                                     "'s: give the motion on " + named(first) + " only"}}));
    }
    Geometry g = step.geometry;
    if (std::holds_alternative<core::JointMoveSpec>(g) || std::holds_alternative<JointMoveToPose>(g) ||
        std::holds_alternative<core::JointPathSpec>(g)) {
      const bool waypoints = std::holds_alternative<core::JointPathSpec>(g);
      return tl::unexpected(invalid(core::Violations{
          {named(k > first ? k - 1 : k) + ".blendTolerance",
           std::string(waypoints ? "a joint path's ends are" : "a joint move's corners are") +
               " not blended with a Cartesian step (its tool does not follow a path): rest before and after it "
               "(blendTolerance 0)"}}));
    }
    if (k > first || first > 0) {
      auto started = started_at(step, k, at, robot);
      if (!started) return tl::unexpected(std::move(started.error()));
      g = std::move(*started);
    }
    if (auto* move = std::get_if<LinearMoveToJoints>(&g)) {
      auto spec = resolve(*move, *robot);
      if (!spec) return tl::unexpected(in_step(std::move(spec.error()), k, step));
      g = std::move(*spec);
    }
    if (const auto* line = std::get_if<core::LinearMoveSpec>(&g)) {
      if (auto bad = pose_errors(*line, step.motion)) return tl::unexpected(in_step(std::move(*bad), k, step));
      core::BlendLine piece{line->start.p_WT, line->goal.p_WT, line->start.q_WT.normalized(), line->goal.q_WT.normalized()};
      if (k == first) start_orientation = piece.q0;
      pieces.emplace_back(piece);
      at.pose = line->goal;
      at.pose.q_WT.normalize();
      continue;
    }
    const auto& path = std::get<core::PathSpec>(g);
    if (k > first && !path.frames.empty()) {
      const double dp = (path.frames.front().p_W - at.pose.p_WT).norm();
      const double tp = robot ? robot->start_position_tolerance : kStartPositionTolerance;
      if (!(dp <= tp)) {
        return tl::unexpected(invalid(core::Violations{
            {named(k) + ".path.frames[0].position", "is " + core::number(dp, 6) + " m from where " + named(k - 1) +
                                                        " ends (tolerance " + core::number(tp) +
                                                        " m): a step starts where the previous one ends"}}));
      }
    }
    // Where the path ends, its orientation included: a line after it starts there.
    auto built = build(path);
    if (!built) return tl::unexpected(in_step(std::move(built.error()), k, step));
    auto orientation = core::plan_orientation(*built, at.pose.q_WT);
    if (!orientation) {
      return tl::unexpected(in_step(invalid(core::prefixed(std::move(orientation.error()), "path.")), k, step));
    }
    at.pose.p_WT = path.frames.back().p_W;
    at.pose.q_WT = orientation->segments.back().q_end;
    pieces.emplace_back(path);
  }
  auto chain = core::blend_chain(pieces, tolerances, names);
  if (!chain) return tl::unexpected(invalid(std::move(chain.error())));
  return std::move(*chain);
}

}  // namespace

Expected<Plan> plan_sequence(const Request& request, const Budget& budget, const Limits& limits, Use use) {
  const auto deadline = optimizer_deadline(request, budget);
  const Robot* robot = request.robot.get();
  Plan result;
  result.robot = request.robot;
  std::vector<core::StepMotion> steps;
  std::vector<std::size_t> step_index;
  std::vector<std::vector<std::size_t>> segment_steps;
  std::optional<core::JointReportBuilder> builder;
  if (robot) builder.emplace(robot->model, robot->branch_tolerance);
  core::ToolBindingBuilder tool_binding;  // without a robot
  ToolPeaks peaks;
  StepEnd end;
  if (robot) {
    end.q = robot->seed;
    const Eigen::Isometry3d X = core::forward_kinematics(robot->model, robot->seed);
    end.pose.p_WT = X.translation();
    end.pose.q_WT = Eigen::Quaterniond(X.linear());
  }
  const double rate = request.sequence.front().motion.cycle_rate_hz;
  std::size_t first = 0;  // global index of the unit's first sample
  for (std::size_t i = 0; i < request.sequence.size();) {
    // A unit: step i alone, or the steps i..last joined by blended corners.
    std::size_t last = i;
    while (last + 1 < request.sequence.size() && request.sequence[last].blend_tolerance > 0.0) ++last;
    const Step& step = request.sequence[i];
    if (step.motion.cycle_rate_hz != rate) {
      return tl::unexpected(invalid(core::Violations{
          {"sequence[" + std::to_string(i) + "].motion.cycleRateHz",
           "is " + core::number(step.motion.cycle_rate_hz) + " Hz; every step of a sequence streams at one rate, " +
               core::number(rate) + " Hz (sequence[0]'s)"}}));
    }
    Request sub;
    StepReport report;
    report.index = i;
    report.last_index = last;
    report.kind = last > i ? "blended" : kind_of(step.geometry);
    std::vector<std::size_t> segments_of_steps;
    if (last > i) {
      auto chain = blended_chain(request, i, last, end, robot, sub.start_orientation);
      if (!chain) return tl::unexpected(std::move(chain.error()));
      sub.geometry = std::move(chain->spec);
      report.corners = std::move(chain->corners);
      std::erase_if(report.corners, [](const core::CornerBlend& c) {
        return c.corner <= core::kSmoothJunction && c.deviation <= 1e-9;  // collinear: no corner
      });
      for (std::size_t piece : chain->segment_piece) segments_of_steps.push_back(i + piece);
      if (!sub.start_orientation && i > 0) sub.start_orientation = end.pose.q_WT;
      if (request.optimize) {  // the timing only: the optimisers of a path's shape would move the blends
        Optimize timing_only;
        timing_only.time_optimal = request.optimize->time_optimal;
        timing_only.jerk_limited = request.optimize->jerk_limited;
        timing_only.budget_s = request.optimize->budget_s;
        sub.optimize = timing_only;
      }
    } else if (i == 0) {
      sub.geometry = step.geometry;
    } else {
      auto started = started_at(step, i, end, robot);
      if (!started) return tl::unexpected(std::move(started.error()));
      sub.geometry = std::move(*started);
      sub.start_orientation = end.pose.q_WT;
    }
    sub.motion = step.motion;
    if (robot) {
      auto at_end = std::make_shared<Robot>(*robot);
      at_end->seed = end.q;
      sub.robot = std::move(at_end);
    }
    if (const auto* move = std::get_if<JointMoveToPose>(&sub.geometry); move && robot) {
      auto chosen = resolve(*move, *robot, budget);
      if (!chosen) return tl::unexpected(in_step(std::move(chosen.error()), i, step));
      report.goal_choice = std::move(chosen->choice);
      sub.geometry = std::move(chosen->spec);
    }
    const bool path = std::holds_alternative<core::PathSpec>(sub.geometry);
    if ((path || std::holds_alternative<core::LinearMoveSpec>(sub.geometry) ||
         std::holds_alternative<LinearMoveToJoints>(sub.geometry) ||
         std::holds_alternative<core::JointPathSpec>(sub.geometry)) &&
        last == i) {
      sub.optimize = request.optimize;  // a line takes its timing flags only
    }
    auto trajectory = plan_trajectory(sub, budget, deadline, report.optimizers, result.default_jerk);
    if (!trajectory) return tl::unexpected(in_step(std::move(trajectory.error()), i, step));
    if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
    if (i == 0 && robot) {
      if (auto refused = starts_at_robot(*trajectory, *robot)) return tl::unexpected(std::move(*refused));
    }
    // A path or a line has its joints chosen for the whole step, as a request of its own
    // (plan_request): asked (optimize.redundancy), with the tool's roll free, or a straight
    // line to goal joints on a redundant arm, which ends at them only so. Each step starts
    // where the one before ended (its seed, and its orientation: a roll chosen there is kept).
    const auto* to_joints = std::get_if<LinearMoveToJoints>(&sub.geometry);
    const bool along_tool = path || to_joints != nullptr || std::holds_alternative<core::LinearMoveSpec>(sub.geometry);
    const bool asked = request.optimize && request.optimize->redundancy;
    const bool held = to_joints != nullptr && robot && (robot->model->dof() > 6 || robot->tool_axis_free);
    if (along_tool && robot && (asked || held || robot->tool_axis_free)) {
      optim::RedundancyWeights weights;
      weights.acceleration = 1.0;
      if (asked) weights = *request.optimize->redundancy;
      if (auto refused = choose_joints(*trajectory, sub, weights, held ? &to_joints->goal : nullptr, budget, deadline,
                                       report.optimizers))
        return tl::unexpected(in_step(std::move(*refused), i, step));
      if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
    }
    core::StepMotion motion = as_step(std::move(*trajectory));
    const std::size_t n = core::sample_count(motion);
    const bool last_unit = last + 1 == request.sequence.size();
    report.start_time_s = static_cast<double>(first) / rate;
    report.duration_s = core::duration(motion);
    report.first_sample = first;
    report.sample_count = last_unit ? n : n - 1;
    report.arc_length = arc_length_of(motion);
    report.peak_tangential_acceleration = tangential_peak(motion);
    if (path && use == Use::kPlan) report.path = report_of(std::get<core::PathMotion>(motion).path);
    if (first + report.sample_count > limits.max_samples) {
      return tl::unexpected(invalid(core::Violations{
          {"sequence", "the sequence has more than " + std::to_string(limits.max_samples) +
                           " samples by sequence[" + std::to_string(i) + "] (" +
                           core::number(report.start_time_s + report.duration_s, 6) +
                           " s at the cycle rate); this server streams and checks at most " +
                           std::to_string(limits.max_samples) + " per call" +
                           (limits.max_samples_name.empty() ? "" : " (" + limits.max_samples_name + ")") +
                           ": shorten it or lower cycleRateHz"}}));
    }
    // The unit's samples, as the sequence streams them: the joint report and the tool's
    // peaks over the whole sequence, and where the unit ends.
    const auto ref = std::visit([](const auto& m) { return core::StepRef(&m); }, motion);
    core::StepSampler sampler(ref, robot ? &robot->model.model() : nullptr, end.q, {});
    const core::CartesianLimits cartesian = cartesian_limits(*sub.motion, !joint_geometry(sub.geometry));
    if (builder) builder->set_cartesian_limits(cartesian);
    tool_binding.set_cartesian_limits(cartesian);
    core::TrajectorySample sample;
    while (sampler.next(sample)) {
      const std::size_t j = sampler.index() - 1;
      if (j == 0 && i > 0 && path) {
        if (auto refused = path_starts_at(sample, end, i, robot)) return tl::unexpected(std::move(*refused));
      }
      if (last_unit || j + 1 < n) {
        const double t = report.start_time_s + sample.t;
        if (builder) builder->add(first + j, t, sample.s, sample.joints, &sample.tool);
        else if (use == Use::kPlan) tool_binding.add(first + j, t, sample.s, sample.tool);
        add(peaks, sample);
      }
      add(report.tool, sample);  // the step's own, its last rest included
      if (j % (robot ? kSamplesPerCheck : kToolSamplesPerCheck) == 0) {
        if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
      }
    }
    end.pose.p_WT = sample.tool.X_WT.translation();
    end.pose.q_WT = sample.q_WT;
    if (robot) {
      end.q = sample.joints.q;
      const Geometry& goal = last > i ? request.sequence[last].geometry : sub.geometry;
      if (auto refused = ends_at_goal(goal, end.q)) {
        return tl::unexpected(in_step(std::move(*refused), last, request.sequence[last]));
      }
    }
    first += report.sample_count;
    result.steps.push_back(std::move(report));
    steps.push_back(std::move(motion));
    step_index.push_back(i);
    segment_steps.push_back(std::move(segments_of_steps));
    i = last + 1;
  }
  core::SequenceMotion sequence = core::make_sequence(std::move(steps), rate);
  sequence.step_index = std::move(step_index);
  sequence.segment_steps = std::move(segment_steps);
  result.trajectory = std::move(sequence);
  if (builder) {
    core::JointMotionReport joints = builder->report();
    const bool only_limits = std::all_of(joints.violations.begin(), joints.violations.end(), [](const auto& e) {
      return e.kind != core::LimitKind::kIk && e.kind != core::LimitKind::kBranch;
    });
    const bool allowed = robot->report_only && (use == Use::kPlan || only_limits);
    if (!joints.feasible() && !allowed) {
      return tl::unexpected(
          Error{ErrorKind::kRobotCannotFollow, {}, joints.violations, robot->model->name, robot->report_only});
    }
    result.joints = std::move(joints);
  }
  // A jerk-limited step's binding: the stretches measured on the sequence's samples that
  // overlap the step.
  const auto& measured = result.joints ? result.joints->binding : tool_binding.binding();
  for (StepReport& r : result.steps) {
    std::vector<core::BindingStretch> own;
    for (const auto& stretch : measured) {
      if (stretch.t_end > r.start_time_s && stretch.t_start < r.start_time_s + r.duration_s) own.push_back(stretch);
    }
    measured_binding(r.optimizers, own);
  }
  if (use == Use::kPlan) {
    double tangential = 0.0;
    for (const StepReport& r : result.steps) tangential = std::max(tangential, r.peak_tangential_acceleration);
    result.summary = MotionSummary{core::duration(*result.trajectory), core::sample_count(*result.trajectory), peaks,
                                   tangential, robot ? std::vector<core::BindingStretch>{} : tool_binding.binding()};
  }
  if (auto stop = check(budget)) return tl::unexpected(std::move(*stop));
  return result;
}

std::optional<Expected<Request>> with_approach(const Request& request) {
  const Robot* robot = request.robot.get();
  const auto* path = std::get_if<core::PathSpec>(&request.geometry);
  if (robot == nullptr || path == nullptr || !request.motion || robot->approach == Approach::kNone) return std::nullopt;
  auto built = build(*path);
  if (!built) return tl::unexpected(std::move(built.error()));
  const Eigen::Isometry3d X = core::forward_kinematics(robot->model, robot->seed);
  auto orientation = core::plan_orientation(*built, Eigen::Quaterniond(X.linear()));
  if (!orientation) return tl::unexpected(invalid(core::prefixed(std::move(orientation.error()), "path.")));
  core::ToolPose start;
  start.p_WT = path->frames.front().p_W;
  start.q_WT = orientation->segments.front().q_start;
  const double dp = (start.p_WT - X.translation()).norm();
  const double dr = rotation_angle(start.q_WT, Eigen::Quaterniond(X.linear()));
  if (dp <= robot->start_position_tolerance && dr <= robot->start_orientation_tolerance) return std::nullopt;
  Request out = request;
  Step approach;
  approach.name = "robot.approach";
  approach.motion = *request.motion;
  approach.motion.duration_s = 0.0;  // as fast as the joint limits (and a line's Cartesian ones) allow
  // The room for live speed changes (reserve_room), unless the request's motion has it already.
  if (!request.motion_reserved) approach.motion.acceleration_scale *= 1.0 - request.reserve;
  out.reserve_applied = out.reserve_applied || request.reserve > 0.0;
  const std::vector<double> q(robot->seed.data(), robot->seed.data() + robot->seed.size());
  if (robot->approach == Approach::kJoint) {
    approach.geometry = JointMoveToPose{q, Eigen::Translation3d(start.p_WT) * start.q_WT, GoalChoice::kLargestMargin};
  } else {
    core::ToolPose from;
    from.p_WT = X.translation();
    from.q_WT = Eigen::Quaterniond(X.linear());
    approach.geometry = core::LinearMoveSpec{from, start};
  }
  Step follow;
  follow.name = "";
  follow.geometry = request.geometry;
  follow.motion = *request.motion;
  out.sequence = {std::move(approach), std::move(follow)};
  return out;
}


}  // namespace geotraj::planner::detail
