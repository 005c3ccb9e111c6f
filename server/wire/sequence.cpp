// PlanRequest.sequence as the planner's request (convert.hpp): each step as a request of
// its own, every violation named from the request's root.
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

namespace {

constexpr int kMaxSequenceSteps = 64;

// The fields a step's own motion gives, by their API names ("maxSpeed", ...).
std::vector<std::string> given_motion_fields(const v1::SequenceStep& step) {
  std::vector<const google::protobuf::FieldDescriptor*> fields;
  if (step.has_motion()) v1::MotionSpec::GetReflection()->ListFields(step.motion(), &fields);
  std::vector<std::string> names;
  for (const auto* f : fields) names.push_back(f->camelcase_name());
  return names;
}

// Whether a step's own motion gives the field `field` names ("motion.maxSpeed"; "motion"
// alone: the step has a motion), so that a violation is named where the user wrote it.
bool step_gives(const v1::SequenceStep& step, std::string_view field) {
  if (!step.has_motion()) return false;
  if (field == "motion") return true;
  field.remove_prefix(std::string_view("motion.").size());
  const auto given = given_motion_fields(step);
  return std::find(given.begin(), given.end(), field.substr(0, field.find_first_of(".["))) != given.end();
}

// A violation of a step's own request, named from the root: the step's fields under
// `sequence[i].` (a motion field only when the step's motion gives it; else the request's
// `motion`, which it took the field from), the request's as they are.
core::FieldViolation in_step(core::FieldViolation v, int i, const v1::SequenceStep& step) {
  const auto starts = [&v](std::string_view prefix) {
    return v.field.rfind(prefix, 0) == 0 && (v.field.size() == prefix.size() || v.field[prefix.size()] == '.' ||
                                             v.field[prefix.size()] == '[');
  };
  if (starts("path") || starts("jointMove") || starts("linearMove") || (starts("motion") && step_gives(step, v.field))) {
    v.field = "sequence[" + std::to_string(i) + "]." + v.field;
  }
  return v;
}

// The rate a step streams at and the field that set it: the step's motion, else the
// request's, else core::MotionSpec's default.
std::pair<double, std::string> step_rate(const v1::PlanRequest& request, int i) {
  const auto& step = request.sequence(i);
  if (step.has_motion() && step.motion().has_cycle_rate_hz()) {
    return {step.motion().cycle_rate_hz(), "sequence[" + std::to_string(i) + "].motion.cycleRateHz"};
  }
  if (request.has_motion() && request.motion().has_cycle_rate_hz()) {
    return {request.motion().cycle_rate_hz(), "motion.cycleRateHz"};
  }
  return {core::MotionSpec{}.cycle_rate_hz, "the default"};
}

}  // namespace

// PlanRequest.sequence: each step converted as a request of its own (the request's robot,
// motion unless the step gives one, optimize for paths), every violation named from the root.
core::Expected<planner::Request> wire_detail::sequence_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                     const ServiceLimits& limits, RequestUse use,
                                                     const planner::StopAt& stop_at) {
  core::Violations violations;
  if (use == RequestUse::kAnalyze) {
    return tl::unexpected(core::Violations{
        {"sequence", "AnalyzePath analyses one `path`: send each path of the sequence on its own"}});
  }
  if (request.has_path() || request.has_joint_move() || request.has_linear_move()) {
    violations.push_back({"sequence", "give a sequence, or one `path`, `jointMove` or `linearMove`, not both"});
  }
  if (request.sequence_size() > kMaxSequenceSteps) {
    violations.push_back({"sequence", "has " + std::to_string(request.sequence_size()) + " steps; at most " +
                                          std::to_string(kMaxSequenceSteps) + " are planned in one request"});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  // The robot, once for every step (a URDF is read once, not once a step); the steps of a
  // sequence whose robot does not resolve are not checked.
  std::shared_ptr<const planner::Robot> robot;
  if (request.has_robot()) {
    auto resolved = robot_from_request(request.robot(), catalog, true, stop_at);
    if (!resolved) return tl::unexpected(std::move(resolved.error()));
    robot = std::make_shared<const planner::Robot>(std::move(*resolved));
  }
  planner::Request out;
  bool any_path = false, any_line = false;
  bool first_rate_named = false;
  for (int i = 0; i < request.sequence_size(); ++i) {
    const auto& step = request.sequence(i);
    const std::string field = "sequence[" + std::to_string(i) + "]";
    if (!step.has_motion() && !request.has_motion()) {
      violations.push_back({field + ".motion", "is required: a sequence step's timing, or the request's `motion`"});
      continue;
    }
    v1::PlanRequest sub;
    if (request.has_robot()) *sub.mutable_robot() = request.robot();
    // The step's motion over the request's: every field the step does not give, the
    // request's motion gives.
    *sub.mutable_motion() = request.motion();
    if (step.has_motion()) sub.mutable_motion()->MergeFrom(step.motion());
    // The request's accelerationScale scales the steps the limits time; a step timed by its
    // own durationS takes none (unless it gives one, which is then refused as at the top).
    if (step.motion().duration_s() > 0.0 && !step.motion().has_acceleration_scale()) {
      sub.mutable_motion()->clear_acceleration_scale();
    }
    sub.set_pacing(request.pacing());
    if (request.has_samples_per_batch()) sub.set_samples_per_batch(request.samples_per_batch());
    bool start_given = false;
    if (step.has_path()) {
      *sub.mutable_path() = step.path();
      if (request.has_optimize()) *sub.mutable_optimize() = request.optimize();
      any_path = true;
    }
    if (step.has_joint_move()) {
      *sub.mutable_joint_move() = step.joint_move();
      start_given = step.joint_move().start_size() > 0;
    }
    if (step.has_linear_move()) {
      *sub.mutable_linear_move() = step.linear_move();
      any_line = true;
      if (request.has_optimize()) {  // its timing (a line has no shape to optimise)
        *sub.mutable_optimize()->mutable_timing() = request.optimize().timing();
        if (request.optimize().has_time_budget_s()) sub.mutable_optimize()->set_time_budget_s(request.optimize().time_budget_s());
      }
      start_given = step.linear_move().has_start();
      // After the first step an absent start is where the previous step ends, known when
      // the planner gets there: a placeholder the planner replaces.
      if (!start_given && i > 0) sub.mutable_linear_move()->mutable_start()->mutable_orientation()->set_w(1.0);
    }
    double blend = 0.0;
    if (step.has_blend_tolerance()) {
      blend = step.blend_tolerance();
      if (!(std::isfinite(blend) && blend >= 0.0 && blend <= 1e3)) {
        violations.push_back({field + ".blendTolerance", "must be a distance in [0, 1000] m, got " + core::number(blend)});
      } else if (blend > 0.0 && i + 1 == request.sequence_size()) {
        violations.push_back({field + ".blendTolerance", "the last step has no corner after it to blend"});
      }
    }
    if (const auto [rate, source] = step_rate(request, i); i > 0 && rate != step_rate(request, 0).first) {
      const auto [first_rate, first_source] = step_rate(request, 0);
      // Named on the field the user gave: this step's, else (once) the first step's.
      const bool own = source.starts_with("sequence[");
      if (own || !first_rate_named) {
        violations.push_back({own ? source : first_source,
                              "is " + core::number(own ? rate : first_rate) +
                                  " Hz; every step of a sequence streams at one rate, " +
                                  core::number(own ? first_rate : rate) + " Hz (" + (own ? first_source : source) +
                                  ")"});
        first_rate_named = first_rate_named || !own;
      }
    }
    const int kinds = int(step.has_path()) + int(step.has_joint_move()) + int(step.has_linear_move());
    if (kinds != 1) {
      violations.push_back({field, kinds == 0 ? "is empty: give a `path`, a `jointMove` or a `linearMove`"
                                              : "give exactly one of `path`, `jointMove` and `linearMove`"});
      continue;
    }
    auto converted = single_from_proto(sub, catalog, limits, use, stop_at, robot);
    if (!converted) {
      for (auto& v : converted.error()) {
        auto named = in_step(std::move(v), i, step);
        const bool seen = std::any_of(violations.begin(), violations.end(), [&named](const core::FieldViolation& w) {
          return w.field == named.field && w.description == named.description;
        });
        if (!seen) violations.push_back(std::move(named));
      }
      continue;
    }
    if (!out.robot) out.robot = converted->robot;
    if (!out.optimize) out.optimize = converted->optimize;
    if (!out.motion) out.motion = converted->motion;
    out.sequence.push_back(
        planner::Step{std::move(converted->geometry), *converted->motion, step.has_motion(), given_motion_fields(step),
                      start_given, blend, {}});
  }
  // optimize.timing times the paths and lines (a blended chain of lines included); the
  // shape optimisers need a path.
  if (request.has_optimize() && !any_path && !any_line) {
    violations.push_back({"optimize", "applies to the paths and lines of a sequence, and this one has neither"});
  } else if (request.has_optimize() && !any_path &&
             (request.optimize().has_tangent_scales() || request.optimize().has_breakpoints())) {
    violations.push_back({request.optimize().has_tangent_scales() ? "optimize.tangentScales" : "optimize.breakpoints",
                          "shapes the paths of a sequence, and this one has none (optimize.timing times its lines)"});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return out;
}

}  // namespace geotraj::server
