// A request as given, admitted into the planner's Request (request_input.hpp): what each call
// needs of it, the motion's values, the robot resolved once, the moves completed from the
// robot, and a sequence's steps each with the request's motion under its own.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "core/geometry/validate.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/plan_detail.hpp"
#include "planner/request_input.hpp"

namespace geotraj::planner {

namespace {

// Calls f(API name, member pointer) for every field of a MotionInput.
template <class F>
void for_each_motion_field(F&& f) {
  f("durationS", &MotionInput::duration_s);
  f("profile", &MotionInput::profile);
  f("rampFraction", &MotionInput::ramp_fraction);
  f("rampTimeS", &MotionInput::ramp_time_s);
  f("cycleRateHz", &MotionInput::cycle_rate_hz);
  f("timeParameterization", &MotionInput::time_parameterization);
  f("speedScale", &MotionInput::speed_scale);
  f("accelerationScale", &MotionInput::acceleration_scale);
  f("maxSpeed", &MotionInput::max_speed);
  f("maxAcceleration", &MotionInput::max_acceleration);
  f("maxJerk", &MotionInput::max_jerk);
  f("maxAngularSpeed", &MotionInput::max_angular_speed);
  f("maxAngularAcceleration", &MotionInput::max_angular_acceleration);
}

}  // namespace

std::vector<std::string> given_fields(const MotionInput& m) {
  std::vector<std::string> out;
  for_each_motion_field([&](const char* name, auto field) {
    if (m.*field) out.emplace_back(name);
  });
  return out;
}

MotionInput merged(MotionInput base, const MotionInput& over) {
  for_each_motion_field([&](const char*, auto field) {
    if (over.*field) base.*field = over.*field;
  });
  return base;
}

core::MotionSpec motion_spec(const MotionInput& m) {
  core::MotionSpec spec;
  spec.duration_s = m.duration_s.value_or(0.0);
  spec.profile = m.profile.value_or(core::ProfileShape::kTrapezoidal);
  if (m.ramp_fraction) spec.ramp_fraction = *m.ramp_fraction;
  spec.ramp_fraction_given = m.ramp_fraction.has_value();
  spec.ramp_time_s = m.ramp_time_s;
  if (m.cycle_rate_hz) spec.cycle_rate_hz = *m.cycle_rate_hz;
  spec.time_parameterization = m.time_parameterization.value_or(core::TimeParameterization::kArcLength);
  if (m.speed_scale) spec.speed_scale = *m.speed_scale;
  if (m.acceleration_scale) spec.acceleration_scale = *m.acceleration_scale;
  spec.max_speed = m.max_speed;
  spec.max_acceleration = m.max_acceleration;
  spec.max_jerk = m.max_jerk;
  spec.max_angular_speed = m.max_angular_speed;
  spec.max_angular_acceleration = m.max_angular_acceleration;
  return spec;
}

bool detail::step_owns(std::string_view field, const std::vector<std::string>* own_motion_fields) {
  const auto under = [field](std::string_view root) {
    return field.starts_with(root) &&
           (field.size() == root.size() || field[root.size()] == '.' || field[root.size()] == '[');
  };
  if (under("path") || under("jointMove") || under("linearMove")) return true;
  if (own_motion_fields == nullptr || !under("motion")) return false;
  if (field == "motion") return true;
  field.remove_prefix(std::string_view("motion.").size());
  const std::string_view name = field.substr(0, field.find_first_of(".["));
  return std::find(own_motion_fields->begin(), own_motion_fields->end(), name) != own_motion_fields->end();
}

namespace {

using core::Violations;

void append(Violations& to, Violations from) {
  to.insert(to.end(), std::make_move_iterator(from.begin()), std::make_move_iterator(from.end()));
}

// N for a field that starts with `root` ("frames[" or "sequence["), -1 for any other.
long index_under(const std::string& field, std::string_view root) {
  if (!field.starts_with(root)) return -1;
  return std::strtol(field.c_str() + root.size(), nullptr, 10);
}

// The field that wrote the robot's joints: where a rule about how many it has points.
std::string chain_field(const RobotSpec& spec) {
  if (std::holds_alternative<UrdfRobot>(spec.source)) return "robot.urdf";
  if (const auto* model = std::get_if<InlineRobot>(&spec.source)) return model->chain_field;
  return "robot";
}

// The motion's own rules for the geometry it times: accelerationScale scales only a timing
// by the limits; its values are core::validate_motion's, timed as time_optimally_timed says
// (a joint move's are core::plan_joint_move's checks).
Violations check_motion(const core::MotionSpec& spec, const MotionInput& given, const GeometryInput& geometry,
                        const RobotSpec* robot, const Optimize* optimize) {
  if (given.acceleration_scale && spec.duration_s > 0.0) {
    // With a durationS it scales nothing, unless a robot.approach (timed by the limits)
    // comes first.
    const bool approach = geometry.path && robot != nullptr && robot->approach != Approach::kNone;
    if (!approach) {
      return {{"motion.accelerationScale", "scales the limits of a timing by the limits (durationS 0, or a "
                                           "robot.approach): a motion with a durationS is timed by it instead"}};
    }
  }
  if (geometry.joint_move || geometry.joint_path) return {};  // core checks their motion
  // A minimum time that the time-optimal timing sets: the limits given, and the joint ones
  // with a robot, make it, so the Cartesian ones that the profiles need are optional here
  // (the planner asks for maxAcceleration without a robot).
  const bool by_limits =
      spec.duration_s == 0.0 && time_optimally_timed(spec, robot != nullptr, optimize && optimize->time_optimal,
                                                     optimize && optimize->jerk_limited);
  return core::validate_motion(spec, by_limits ? core::MotionTiming::kLimits : core::MotionTiming::kProfile);
}

core::Expected<Geometry> joint_move_geometry(const JointMoveInput& move, const Robot& robot) {
  std::vector<double> start = move.start;
  if (start.empty()) start.assign(robot.seed.data(), robot.seed.data() + robot.seed.size());
  const bool joints = !move.goal.empty();
  if (joints == move.goal_pose.has_value()) {
    return tl::unexpected(Violations{
        {"jointMove.goal", joints ? "give `goal` (joint values) or `goalPose` (a tool pose), not both"
                                  : "is required: the joint values at the goal, one per joint (or `goalPose`)"}});
  }
  if (joints) return Geometry(core::JointMoveSpec{std::move(start), move.goal});
  const Eigen::Vector3d p = move.goal_pose->translation();
  if (p.allFinite() && p.cwiseAbs().maxCoeff() > core::PathLimits{}.max_coordinate) {
    return tl::unexpected(Violations{{"jointMove.goalPose.position", "coordinates must lie within " +
                                                                         core::number(core::PathLimits{}.max_coordinate) +
                                                                         " m of the origin"}});
  }
  return Geometry(JointMoveToPose{std::move(start), *move.goal_pose});
}

// `placeholder_start`: a sequence step after the first without a start, which starts where
// the previous step ends (the planner sets it there).
core::Expected<Geometry> linear_move_geometry(const LinearMoveInput& move, const Robot* robot, bool placeholder_start) {
  Violations out;
  core::LinearMoveSpec spec;
  if (move.start) {
    spec.start = *move.start;
  } else if (placeholder_start) {
    spec.start = core::ToolPose{};
  } else if (robot != nullptr) {
    const Eigen::Isometry3d X = core::forward_kinematics(robot->model, robot->seed);
    spec.start.p_WT = X.translation();
    spec.start.q_WT = Eigen::Quaterniond(X.linear());
  } else {
    out.push_back({"linearMove.start", "is required without a robot (with one, the pose of its initialJoints)"});
  }
  const bool joints = !move.goal_joints.empty();
  if (joints && move.goal) {
    out.push_back({"linearMove.goal", "give `goal` (a tool pose) or `goalJoints` (joint values), not both"});
  } else if (joints) {
    if (robot == nullptr) out.push_back({"linearMove.goalJoints", "needs `robot`: the joints belong to a robot model"});
    for (std::size_t i = 0; i < move.goal_joints.size(); ++i) {
      if (!std::isfinite(move.goal_joints[i])) {
        out.push_back({"linearMove.goalJoints[" + std::to_string(i) + "]",
                       "must be finite, got " + core::number(move.goal_joints[i])});
      }
    }
  } else if (move.goal) {
    spec.goal = *move.goal;
  } else {
    out.push_back({"linearMove.goal", "is required: the tool pose at the end of the move (or `goalJoints`)"});
  }
  if (!out.empty()) return tl::unexpected(std::move(out));
  if (joints) return Geometry(LinearMoveToJoints{spec.start, move.goal_joints});
  return Geometry(spec);
}

core::Expected<std::shared_ptr<const Robot>> resolved(const RobotSpec& spec, const RobotCatalog& catalog,
                                                      const StopAt& stop_at) {
  auto robot = resolve_robot(spec, catalog, /*motion=*/true, stop_at);
  if (!robot) return tl::unexpected(std::move(robot.error()));
  return std::make_shared<const Robot>(std::move(*robot));
}

// optimize.redundancy: weights each finite and >= 0, one at least > 0, on a path or a
// straight line (a joint path gives every joint) followed by a robot with more than 6 joints.
Violations redundancy_violations(const optim::RedundancyWeights& w, const GeometryInput& geometry, const Robot* robot) {
  Violations v;
  const std::pair<const char*, double> weights[] = {{"jointRangeWeight", w.joint_range},
                                                    {"velocityWeight", w.velocity},
                                                    {"accelerationWeight", w.acceleration},
                                                    {"jerkWeight", w.jerk},
                                                    {"manipulabilityWeight", w.manipulability}};
  bool any = false;
  for (const auto& [name, value] : weights) {
    if (!std::isfinite(value) || value < 0.0 || value > optim::kMaxRedundancyWeight)
      v.push_back({std::string("optimize.redundancy.") + name, "must be a weight in [0, " +
                                                               core::number(optim::kMaxRedundancyWeight) + "], got " +
                                                               core::number(value)});
    any = any || value > 0.0;
  }
  if (v.empty() && !any)
    v.push_back({"optimize.redundancy", "weighs nothing: give at least one weight > 0 (accelerationWeight, velocityWeight, "
                                        "jerkWeight, jointRangeWeight, manipulabilityWeight)"});
  if (geometry.joint_path)
    v.push_back({"optimize.redundancy", "chooses a redundant arm's joints along a Cartesian path; a jointPath gives every joint"});
  if (robot == nullptr) {
    v.push_back({"optimize.redundancy", "needs a robot: it chooses the joints of a redundant arm"});
  } else if (robot->model->dof() <= 6 && !robot->tool_axis_free) {
    v.push_back({"optimize.redundancy", "needs a robot with more than 6 joints, or robot.toolAxisFree: " +
                                            robot->model->name + " has " + std::to_string(robot->model->dof()) +
                                            ", so a tool pose leaves it no self-motion to choose"});
  }
  if (robot != nullptr && w.jerk > 0.0 &&
      std::none_of(robot->model->limits.begin(), robot->model->limits.end(),
                   [](const core::JointLimits& l) { return l.max_jerk.has_value(); }))
    v.push_back({"optimize.redundancy.jerkWeight", "weighs the joints' jerk per their maxJerk, and the " + robot->model->name +
                                                       " model gives no joint a maxJerk: give the joints one, or weigh "
                                                       "accelerationWeight instead"});
  return v;
}

// What one path, move or line needs, given with a motion (the request's, or a step's over
// the request's). `robot`: resolved already (a sequence resolves it once for its steps).
core::Expected<Request> admit_motion(const GeometryInput& geometry, const MotionInput& motion,
                                     const RobotSpec* robot_spec, std::shared_ptr<const Robot> robot,
                                     const std::optional<OptimizeInput>& optimize, bool placeholder_start,
                                     bool first = true) {
  Request out;
  Violations violations;
  const int kinds = geometry.kinds();
  if (kinds != 1) {
    return tl::unexpected(Violations{
        {"path", kinds == 0 ? "is required: give the key frames of a `path`, or a `jointMove`, a `linearMove` or a "
                              "`jointPath`"
                            : "give exactly one of `path`, `jointMove`, `linearMove` and `jointPath`"}});
  }
  if (optimize && geometry.joint_move) {
    violations.push_back({"optimize", "applies to a `path` or a linearMove's timing: a jointMove is timed by its "
                                      "slowest joint already"});
  }
  // A line and a joint path take optimize.timing only; the shape optimisers are refused.
  const auto timing_only = [&](const char* why) {
    if (optimize->tangent_scales || optimize->breakpoints)
      violations.push_back({optimize->tangent_scales ? "optimize.tangentScales" : "optimize.breakpoints", why});
    Optimize timing;
    timing.budget_s = optimize->values.budget_s;
    timing.time_optimal = optimize->values.time_optimal;
    timing.jerk_limited = optimize->values.jerk_limited;
    timing.redundancy = optimize->values.redundancy;  // a line's self-motion (a joint path's refused below)
    out.optimize = timing;
  };
  if (optimize && geometry.linear_move) timing_only("shapes a path: a linearMove is straight (optimize.timing applies to it)");
  if (optimize && geometry.path && (geometry.path->spec.start || !geometry.path->spec.pieces.empty()) &&
      (optimize->tangent_scales || optimize->breakpoints)) {
    violations.push_back({optimize->tangent_scales ? "optimize.tangentScales" : "optimize.breakpoints",
                          "shapes the blends between key frames; a path of pieces has exact shapes (optimize.timing "
                          "applies to it)"});
  }
  if (optimize && geometry.path) out.optimize = optimize->values;
  if (optimize && optimize->values.redundancy) append(violations, redundancy_violations(*optimize->values.redundancy, geometry, robot.get()));
  if (optimize && geometry.joint_path) {
    timing_only("shapes a Cartesian path: a jointPath's blends are set by its blendTolerance (optimize.timing "
                "applies to it)");
  }
  const core::MotionSpec spec = motion_spec(motion);
  append(violations, check_motion(spec, motion, geometry, robot_spec, out.optimize ? &*out.optimize : nullptr));
  out.motion = spec;
  out.robot = std::move(robot);
  // A joint move or path needs a robot: said here when none was given; one given and refused
  // was named where it was resolved.
  if (geometry.joint_move) {
    if (!out.robot && robot_spec == nullptr) {
      violations.push_back({"robot", "is required by a jointMove: the joints belong to a robot model"});
    }
    if (!out.robot || !violations.empty()) return tl::unexpected(std::move(violations));
    auto move = joint_move_geometry(*geometry.joint_move, *out.robot);
    if (!move) return tl::unexpected(std::move(move.error()));
    out.geometry = std::move(*move);
    return out;
  }
  if (geometry.joint_path) {
    if (!out.robot && robot_spec == nullptr) {
      violations.push_back({"robot", "is required by a jointPath: the joints belong to a robot model"});
    }
    // A joint path is timed by its joints' limits; its tool goes where they take it.
    const auto cartesian = [&](const char* name, bool given) {
      if (given) {
        violations.push_back({std::string("motion.") + name,
                              "is a Cartesian limit; a jointPath is timed by its joints' limits (its tool goes "
                              "where the joints take it): drop it"});
      }
    };
    cartesian("maxSpeed", spec.max_speed.has_value());
    cartesian("maxAcceleration", spec.max_acceleration.has_value());
    cartesian("maxJerk", spec.max_jerk.has_value());
    cartesian("maxAngularSpeed", spec.max_angular_speed.has_value());
    cartesian("maxAngularAcceleration", spec.max_angular_acceleration.has_value());
    // Its first waypoint is the start: where the robot is, when the request says where.
    const auto& waypoints = geometry.joint_path->waypoints;
    if (out.robot && robot_spec && !robot_spec->initial_joints.empty() && !waypoints.empty() &&
        waypoints.front().positions.size() == robot_spec->initial_joints.size() && first) {
      for (std::size_t j = 0; j < waypoints.front().positions.size(); ++j) {
        const double d = std::abs(waypoints.front().positions[j] - robot_spec->initial_joints[j]);
        if (!(d <= kSequenceJointTolerance)) {
          violations.push_back(
              {"jointPath.waypoints[0].positions[" + std::to_string(j) + "]",
               "is " + core::number(d, 6) + " from robot.initialJoints[" + std::to_string(j) + "] (" +
                   core::number(robot_spec->initial_joints[j]) + "): a jointPath starts where the robot is (within " +
                   core::number(kSequenceJointTolerance) + "); leave initialJoints out, or start there"});
        }
      }
    }
    if (!violations.empty()) return tl::unexpected(std::move(violations));
    out.geometry = *geometry.joint_path;
    return out;
  }
  // Following a Cartesian pose (a path or a straight line) takes six joints at least.
  if (out.robot && out.robot->model->dof() < 6) {
    violations.push_back({chain_field(*robot_spec), "the robot has " + std::to_string(out.robot->model->dof()) +
                                                        " joints; following a tool pose (position and orientation) "
                                                        "needs at least 6"});
  }
  if (geometry.linear_move) {
    if (!violations.empty()) return tl::unexpected(std::move(violations));
    auto move = linear_move_geometry(*geometry.linear_move, out.robot.get(), placeholder_start);
    if (!move) return tl::unexpected(std::move(move.error()));
    out.geometry = std::move(*move);
    return out;
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  if (!geometry.path->usable()) return tl::unexpected(Violations{});  // admit lists why
  out.geometry = geometry.path->spec;
  return out;
}

core::Expected<Request> admit_single(const RequestInput& input, const RobotCatalog& catalog, Use use,
                                     const StopAt& stop_at) {
  const bool moves = input.geometry.joint_move || input.geometry.linear_move || input.geometry.joint_path;
  if (!input.motion) {
    if (use == Use::kStream) {
      return tl::unexpected(Violations{
          {"motion", "is required to stream samples: give durationS (s), or the limits for a minimum-time motion"}});
    }
    if (use == Use::kPlan && (input.robot || moves)) {
      return tl::unexpected(Violations{
          {"motion", "is required with a robot or a move: give durationS (s), or the limits for a minimum-time move"}});
    }
  }
  // Without a motion (PlanTrajectory) or for an analysis, only the path and its optimisers.
  if (use == Use::kAnalyze || !input.motion) {
    auto path = admit_path(input.geometry.path);
    if (!path) return tl::unexpected(std::move(path.error()));
    Request out;
    out.geometry = std::move(*path);
    if (input.optimize) out.optimize = input.optimize->values;
    return out;
  }
  Violations violations;
  std::shared_ptr<const Robot> robot;
  if (input.robot && input.geometry.kinds() == 1) {
    if (auto r = resolved(*input.robot, catalog, stop_at)) {
      robot = std::move(*r);
    } else {
      violations = std::move(r.error());  // named there; admit_motion says no more of it
    }
  }
  if (robot && robot->tool_axis_free && (input.geometry.joint_move || input.geometry.joint_path)) {
    violations.push_back({"robot.toolAxisFree", std::string("frees the tool's roll along a Cartesian path or line; a ") +
                                                    (input.geometry.joint_move ? "jointMove" : "jointPath") +
                                                    " gives the joints, and the tool turns as they take it: drop it"});
  }
  auto out = admit_motion(input.geometry, *input.motion, input.robot ? &*input.robot : nullptr, std::move(robot),
                          input.optimize, false);
  if (!out) append(violations, std::move(out.error()));
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return out;
}

// The rate a step streams at and the field that set it: the step's motion, else the
// request's, else core::MotionSpec's default.
std::pair<double, std::string> step_rate(const RequestInput& input, std::size_t i) {
  const auto& step = input.sequence[i];
  if (step.motion && step.motion->cycle_rate_hz) {
    return {*step.motion->cycle_rate_hz, "sequence[" + std::to_string(i) + "].motion.cycleRateHz"};
  }
  if (input.motion && input.motion->cycle_rate_hz) return {*input.motion->cycle_rate_hz, "motion.cycleRateHz"};
  return {core::MotionSpec{}.cycle_rate_hz, "the default"};
}

// Step i's blend tolerance, or its violation.
void check_blend(const StepInput& step, std::size_t i, std::size_t steps, Violations& violations) {
  if (!step.blend_tolerance) return;
  const double blend = *step.blend_tolerance;
  const std::string field = "sequence[" + std::to_string(i) + "].blendTolerance";
  if (!(std::isfinite(blend) && blend >= 0.0 && blend <= 1e3)) {
    violations.push_back({field, "must be a distance in [0, 1000] m, got " + core::number(blend)});
  } else if (blend > 0.0 && i + 1 == steps) {
    violations.push_back({field, "the last step has no corner after it to blend"});
  }
}

// Every step streams at one rate: a step's other rate is named on the field the user gave
// (the step's, else once the first step's).
void check_rate(const RequestInput& input, std::size_t i, bool& first_rate_named, Violations& violations) {
  const auto [rate, source] = step_rate(input, i);
  const auto [first_rate, first_source] = step_rate(input, 0);
  if (i == 0 || rate == first_rate) return;
  const bool own = source.starts_with("sequence[");
  if (!own && first_rate_named) return;
  violations.push_back({own ? source : first_source,
                        "is " + core::number(own ? rate : first_rate) +
                            " Hz; every step of a sequence streams at one rate, " +
                            core::number(own ? first_rate : rate) + " Hz (" + (own ? first_source : source) + ")"});
  first_rate_named = first_rate_named || !own;
}

// PlanRequest.sequence: each step admitted as a request of its own (the request's robot,
// its motion under the step's, optimize for paths and lines), every violation named from the
// root.
core::Expected<Request> admit_sequence(const RequestInput& input, const RobotCatalog& catalog, Use use,
                                       const StopAt& stop_at) {
  if (use == Use::kAnalyze) {
    return tl::unexpected(Violations{
        {"sequence", "AnalyzePath analyses one `path`: send each path of the sequence on its own"}});
  }
  Violations violations;
  if (input.geometry.kinds() > 0) {
    violations.push_back({"sequence", "give a sequence, or one `path`, `jointMove` or `linearMove`, not both"});
  }
  if (input.sequence_given > std::size_t(kMaxSequenceSteps)) {
    violations.push_back({"sequence", "has " + std::to_string(input.sequence_given) + " steps; at most " +
                                          std::to_string(kMaxSequenceSteps) + " are planned in one request"});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  // The robot, once for every step (a URDF is read once, not once a step); the steps of a
  // sequence whose robot does not resolve are not checked.
  std::shared_ptr<const Robot> robot;
  if (input.robot) {
    auto r = resolved(*input.robot, catalog, stop_at);
    if (!r) return tl::unexpected(std::move(r.error()));
    robot = std::move(*r);
  }
  Request out;
  bool any_path = false, any_line = false, any_joint_path = false, first_rate_named = false;
  for (std::size_t i = 0; i < input.sequence.size(); ++i) {
    const StepInput& step = input.sequence[i];
    const std::string field = "sequence[" + std::to_string(i) + "]";
    if (!step.motion && !input.motion) {
      violations.push_back({field + ".motion", "is required: a sequence step's timing, or the request's `motion`"});
      continue;
    }
    // The step's motion over the request's. The request's accelerationScale scales the steps
    // the limits time; a step timed by its own durationS takes none (unless it gives one,
    // which is then refused as at the top).
    MotionInput motion = merged(input.motion.value_or(MotionInput{}), step.motion.value_or(MotionInput{}));
    if (step.motion && step.motion->duration_s.value_or(0.0) > 0.0 && !step.motion->acceleration_scale) {
      motion.acceleration_scale.reset();
    }
    any_path = any_path || step.geometry.path.has_value();
    any_line = any_line || step.geometry.linear_move.has_value();
    any_joint_path = any_joint_path || step.geometry.joint_path.has_value();
    check_blend(step, i, input.sequence.size(), violations);
    check_rate(input, i, first_rate_named, violations);
    const int kinds = step.geometry.kinds();
    if (kinds != 1) {
      violations.push_back({field, kinds == 0 ? "is empty: give a `path`, a `jointMove`, a `linearMove` or a `jointPath`"
                                              : "give exactly one of `path`, `jointMove`, `linearMove` and `jointPath`"});
      continue;
    }
    const bool start_given = (step.geometry.joint_move && !step.geometry.joint_move->start.empty()) ||
                             (step.geometry.linear_move && step.geometry.linear_move->start) ||
                             step.geometry.joint_path.has_value();  // its first waypoint
    // optimize applies to the paths; its timing to the lines (the shape optimisers are
    // checked for the whole sequence below).
    std::optional<OptimizeInput> optimize = step.geometry.joint_move ? std::nullopt : input.optimize;
    if (optimize && (step.geometry.linear_move || step.geometry.joint_path))
      optimize->tangent_scales = optimize->breakpoints = false;
    if (optimize) optimize->values.redundancy.reset();  // refused for the whole sequence below
    auto admitted = admit_motion(step.geometry, motion, input.robot ? &*input.robot : nullptr, robot, optimize,
                                 /*placeholder_start=*/i > 0 && !start_given, /*first=*/i == 0);
    const std::vector<std::string> own_fields = step.motion ? given_fields(*step.motion) : std::vector<std::string>{};
    if (!admitted) {
      for (auto& v : admitted.error()) {
        if (detail::step_owns(v.field, step.motion ? &own_fields : nullptr)) v.field = field + "." + v.field;
        const bool seen = std::any_of(violations.begin(), violations.end(), [&v](const core::FieldViolation& w) {
          return w.field == v.field && w.description == v.description;
        });
        if (!seen) violations.push_back(std::move(v));
      }
      continue;
    }
    if (!out.robot) out.robot = admitted->robot;
    if (!out.optimize) out.optimize = admitted->optimize;
    if (!out.motion) out.motion = admitted->motion;
    out.sequence.push_back(Step{std::move(admitted->geometry), *admitted->motion, step.motion.has_value(), own_fields,
                                start_given, step.blend_tolerance.value_or(0.0), {}});
  }
  // optimize.redundancy and robot.toolAxisFree choose the joints along each path and line of
  // the sequence (its joint moves and joint paths give theirs).
  if (input.optimize && input.optimize->values.redundancy) {
    append(violations, redundancy_violations(*input.optimize->values.redundancy, GeometryInput{}, robot.get()));
    if (!any_path && !any_line)
      violations.push_back({"optimize.redundancy", "chooses the joints along the paths and lines of a sequence, and "
                                                   "this one has none"});
    if (out.optimize) out.optimize->redundancy = input.optimize->values.redundancy;
  }
  if (robot && robot->tool_axis_free && !any_path && !any_line)
    violations.push_back({"robot.toolAxisFree", "frees the tool's roll along the paths and lines of a sequence, and "
                                                "this one has none"});
  // optimize.timing times the paths, lines and joint paths (a blended chain of lines
  // included); the shape optimisers need a path.
  if (input.optimize && !any_path && !any_line && !any_joint_path) {
    violations.push_back(
        {"optimize", "applies to the paths, lines and joint paths of a sequence, and this one has none"});
  } else if (input.optimize && !any_path && (input.optimize->tangent_scales || input.optimize->breakpoints)) {
    violations.push_back({input.optimize->tangent_scales ? "optimize.tangentScales" : "optimize.breakpoints",
                          "shapes the paths of a sequence, and this one has none (optimize.timing times its lines)"});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return out;
}

}  // namespace

core::Violations path_violations(const PathInput& path) {
  Violations out = path.violations;
  if (!path.read) return out;
  const bool pieces = path.spec.start || !path.spec.pieces.empty();
  Violations checked;
  if (pieces) {
    if (auto built = core::convert_path(path.spec); !built) checked = std::move(built.error());
  } else if (auto valid = core::validate_path(path.spec); !valid) {
    checked = std::move(valid.error());
  }
  for (auto& v : checked) {
    if (path.unchecked.count(v.field) == 0) out.push_back(std::move(v));
  }
  // In key-frame order, the wire's and core's of one frame together (the path's own fields
  // first).
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return index_under(a.field, "frames[") < index_under(b.field, "frames[");
  });
  return out;
}

core::Expected<core::PathSpec> admit_path(const std::optional<PathInput>& path) {
  if (!path) return tl::unexpected(Violations{{"path", "is required: the key frames of the path (at least 2)"}});
  if (path->usable()) return path->spec;
  return tl::unexpected(core::prefixed(path_violations(*path), "path."));
}

core::Expected<Request> admit(RequestInput input, const RobotCatalog& catalog, Use use, const StopAt& stop_at) {
  auto admitted = input.sequence_given == 0 ? admit_single(input, catalog, use, stop_at)
                                         : admit_sequence(input, catalog, use, stop_at);
  const auto usable = [](const GeometryInput& g) { return !g.path || g.path->usable(); };
  const bool read = input.violations.empty() && usable(input.geometry) &&
                    std::all_of(input.sequence.begin(), input.sequence.end(),
                                [&usable](const StepInput& step) { return usable(step.geometry); });
  if (admitted && read) return admitted;
  // Refused: what the wire could not read and every path's violations (core's of what could
  // be read included, so that one answer lists everything) in the request's order, a step's
  // after the request's own fields; then the admission's own.
  Violations violations;
  if (input.geometry.path) append(violations, core::prefixed(path_violations(*input.geometry.path), "path."));
  for (std::size_t i = 0; i < input.sequence.size(); ++i) {
    if (!input.sequence[i].geometry.path) continue;
    append(violations, core::prefixed(path_violations(*input.sequence[i].geometry.path),
                                      "sequence[" + std::to_string(i) + "].path."));
  }
  append(violations, std::move(input.violations));
  std::stable_sort(violations.begin(), violations.end(), [](const auto& a, const auto& b) {
    return index_under(a.field, "sequence[") < index_under(b.field, "sequence[");
  });
  if (!admitted) {
    for (auto& v : admitted.error()) {
      const bool seen = std::any_of(violations.begin(), violations.end(), [&v](const core::FieldViolation& w) {
        return w.field == v.field && w.description == v.description;
      });
      if (!seen) violations.push_back(std::move(v));
    }
  }
  return tl::unexpected(std::move(violations));
}

}  // namespace geotraj::planner
