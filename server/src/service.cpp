// The TrajectoryService: each RPC is a free function from request to response and status,
// and a reactor that runs it. Proto <-> core conversion lives in convert.cpp, the mapping of
// violations to a status in status.cpp.
#include "service.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stop_token>

#include <grpcpp/alarm.h>
#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/proto_buffer_reader.h>
#include <grpcpp/support/proto_buffer_writer.h>

#include "convert.hpp"
#include "geotraj/core/analysis.hpp"
#include "geotraj/core/constraints.hpp"
#include "geotraj/core/kinematics.hpp"
#include "geotraj/core/motion.hpp"
#include "geotraj/core/orientation.hpp"
#include "geotraj/core/path.hpp"
#include "geotraj/core/trajectory.hpp"
#include "geotraj/optim/breakpoints.hpp"
#include "geotraj/optim/tangent_scales.hpp"
#include "geotraj/optim/time_optimal_jerk.hpp"
#include "geotraj/core/time_optimal.hpp"
#include "runtime.hpp"
#include "status.hpp"
#include "tsan.hpp"

namespace geotraj::server {
namespace {

// The path part of a PlanResponse: segments with the geometry between frames, the achieved
// frames, the closed loop and the warnings.
void report_path(const core::Path& path, v1::PlanResponse& response) {
  const auto achieved = core::achieved_geometry(path);
  to_proto(path, achieved, core::closed_loop_error(path, achieved), core::geometry_report(path), response);
}

std::string format_seconds(double s) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", s);
  return buffer;
}

// Whether the caller still wants the answer: checked before each stage of work, so that a
// cancelled call or a passed deadline stops it at the next stage.
class Abandon {
  static constexpr std::chrono::milliseconds kDeadlineSlack{20};

 public:
  explicit Abandon(grpc::CallbackServerContext& context) : context_(&context), deadline_(context.deadline()) {}
  /// The client's deadline, or the server's default for calls that carry none (or a later
  /// one): `default_s` from now (geotrajd --default-deadline-seconds).
  /// With `stop`, requested when gRPC cancels the call (OnCancel of its reactor): the
  /// optimisers stop on it within one iteration, not only at their next deadline check.
  Abandon(grpc::CallbackServerContext& context, double default_s, std::stop_token stop) : Abandon(context, default_s) {
    stop_ = std::move(stop);
  }
  Abandon(grpc::CallbackServerContext& context, double default_s) : Abandon(context) {
    const auto server = std::chrono::system_clock::now() +
                        std::chrono::duration_cast<std::chrono::system_clock::duration>(std::chrono::duration<double>(default_s));
    if (server < deadline_) {
      deadline_ = server;
      default_s_ = default_s;
    }
  }
  /// Work that no client waits for (the warm-up): only the deadline ends it.
  explicit Abandon(std::chrono::system_clock::time_point deadline) : deadline_(deadline) {}
  /// The status to finish with when the call is no longer wanted.
  /// A passed deadline first: gRPC also cancels the call then, and the code should say why.
  /// gRPC's timer may fire a little before this clock reaches the deadline, so a
  /// cancellation within kDeadlineSlack of it counts as the deadline.
  std::optional<grpc::Status> check() const {
    const auto now = std::chrono::system_clock::now();
    const bool cancelled = (context_ != nullptr && context_->IsCancelled()) || stop_.stop_requested();
    if (deadline_ <= now || (cancelled && deadline_ - now <= kDeadlineSlack)) {
      if (default_s_ > 0.0) {
        return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED,
                            "the call gave no deadline, and the server's default of " + format_seconds(default_s_) +
                                " s (geotrajd --default-deadline-seconds) passed before the work was done");
      }
      return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "the deadline passed before the work was done");
    }
    if (cancelled) return grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled");
    return std::nullopt;
  }

  /// Requested when the call is cancelled (empty for work no client waits for).
  const std::stop_token& stop() const { return stop_; }

  /// When the caller stops waiting, on the steady clock (the RPC's deadline).
  std::chrono::steady_clock::time_point deadline() const {
    const auto left = deadline_ - std::chrono::system_clock::now();
    if (left > std::chrono::hours(24 * 365)) return std::chrono::steady_clock::time_point::max();  // no deadline
    return std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(left);
  }

 private:
  grpc::CallbackServerContext* context_ = nullptr;
  std::chrono::system_clock::time_point deadline_;
  double default_s_ = 0.0;  // > 0 when deadline_ is the server's default
  std::stop_token stop_;
};

// What the work of one call needs from the service: its robots, its limits, its metrics.
struct Services {
  const RobotCatalog& robots;
  const ServiceLimits& limits;
  Metrics& metrics;
};

// INVALID_ARGUMENT when an analysis asks for more points than the server answers.
std::optional<grpc::Status> analysis_limit(const v1::PlanRequest& request, const ServiceLimits& limits) {
  if (!request.has_analysis_points() || request.analysis_points() <= limits.max_analysis_points) return std::nullopt;
  return invalid_argument(core::Violations{
      {"analysisPoints", "asks for " + std::to_string(request.analysis_points()) +
                             " points; this server answers at most " + std::to_string(limits.max_analysis_points) +
                             " (geotrajd --max-analysis-points)"}});
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// INVALID_ARGUMENT when a path has more key frames than the server accepts.
std::optional<grpc::Status> frame_limit(const v1::PathSpec& path, const ServiceLimits& limits) {
  if (path.frames_size() <= limits.max_frames) return std::nullopt;
  return invalid_argument(core::Violations{
      {"path.frames", "has " + std::to_string(path.frames_size()) + " key frames; this server accepts at most " +
                          std::to_string(limits.max_frames) + " (geotrajd --max-frames)"}});
}

// The request's path spec after the optimisers it asks for (tangent scales, then
// breakpoints; both within the RPC's deadline and optimize.timeBudgetS), their reports in
// `report`; or the status to finish with (every violation of the request together).
tl::expected<core::PathSpec, grpc::Status> optimized_path(const Abandon& abandon, const Services& services,
                                                          const v1::PlanRequest& request,
                                                          v1::OptimizationReport* report) {
  auto spec = path_from_request(request);
  if (!request.has_optimize()) {
    if (!spec) return tl::unexpected(invalid_argument(spec.error()));
    return std::move(*spec);
  }
  core::Violations violations = spec ? core::Violations{} : spec.error();
  const auto budget = optimize_budget(request, services.limits.max_optimize_seconds);
  if (!budget) violations.insert(violations.end(), budget.error().begin(), budget.error().end());
  const auto& optimize = request.optimize();
  std::optional<optim::TangentScaleOptions> scales;
  std::optional<optim::BreakpointOptions> breakpoints;
  if (optimize.has_tangent_scales()) {
    auto options = tangent_scale_options(request);
    if (options) {
      scales = std::move(*options);
    } else {
      violations.insert(violations.end(), options.error().begin(), options.error().end());
    }
  }
  if (optimize.has_breakpoints()) {
    auto options = breakpoint_options(request);
    if (options) {
      breakpoints = std::move(*options);
    } else {
      violations.insert(violations.end(), options.error().begin(), options.error().end());
    }
  }
  if (!violations.empty()) return tl::unexpected(invalid_argument(violations));
  // One deadline for all the optimisers: the earlier of the RPC's and the budget's.
  const auto deadline = std::min(abandon.deadline(), std::chrono::steady_clock::now() +
                                                         std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                             std::chrono::duration<double>(*budget)));
  core::PathSpec path = std::move(*spec);
  if (scales) {
    scales->deadline = deadline;
    scales->stop = abandon.stop();
    const auto started = std::chrono::steady_clock::now();
    auto result = optim::optimize_tangent_scales(path, *scales);
    services.metrics.optimization("tangent_scales", seconds_since(started));
    if (!result) return tl::unexpected(invalid_argument(result.error()));
    path = result->spec;
    if (report != nullptr) to_proto(*result, *report->mutable_tangent_scales());
  }
  if (breakpoints) {
    breakpoints->deadline = deadline;
    breakpoints->stop = abandon.stop();
    const auto started = std::chrono::steady_clock::now();
    auto result = optim::optimize_breakpoints(path, *breakpoints);
    services.metrics.optimization("breakpoints", seconds_since(started));
    if (!result) return tl::unexpected(invalid_argument(core::prefixed(result.error(), "path.")));
    path = result->spec;
    if (report != nullptr) to_proto(*result, *report->mutable_breakpoints());
  }
  if (auto stop = abandon.check()) return tl::unexpected(*stop);
  return path;
}

grpc::Status convert_constraints(const Abandon& abandon, const Services& services, const v1::ConvertRequest& request,
                                 v1::ConvertResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  if (auto refused = frame_limit(request.path(), services.limits)) return *refused;
  const auto spec = path_from_request(request);
  if (!spec) return invalid_argument(spec.error());
  const auto frames = core::convert_path(*spec);
  if (!frames) return invalid_argument(core::prefixed(frames.error(), "path."));
  to_proto(*frames, response);
  return grpc::Status::OK;
}

// The request in `bytes`, or INVALID_ARGUMENT when they are not one in the protobuf wire format.
template <class Message>
std::optional<grpc::Status> parse(const grpc::ByteBuffer& bytes, Message& message) {
  grpc::ByteBuffer copy(bytes);  // shares the slices; Deserialize consumes its buffer
  if (grpc::SerializationTraits<Message>::Deserialize(&copy, &message).ok()) return std::nullopt;
  return invalid_argument(core::Violations{
      {"", "the request is not a " + Message::descriptor()->full_name() + " in the protobuf wire format"}});
}

template <class Message>
void serialize(const Message& message, grpc::ByteBuffer& bytes) {
  bool own_buffer = false;
  bytes.Clear();  // the writer wants an empty buffer (a stream reuses its one)
  (void)grpc::SerializationTraits<Message>::Serialize(message, &bytes, &own_buffer);
}

// A call whose client reset it before (or just after) its request arrived: gRPC may hand
// the method an empty or invalid buffer then, which is no bad request of the client's.
std::optional<grpc::Status> gone(grpc::CallbackServerContext& context, const grpc::ByteBuffer& in) {
  if (context.IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled");
  if (!in.Valid()) return grpc::Status(grpc::StatusCode::CANCELLED, "the request did not arrive");
  return std::nullopt;
}

// RESOURCE_EXHAUSTED when an answer is larger than the server sends.
std::optional<grpc::Status> response_limit(std::size_t bytes, std::uint64_t limit) {
  if (bytes <= limit) return std::nullopt;
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      "the answer would have " + std::to_string(bytes) + " bytes; this server sends at most " +
                          std::to_string(limit) +
                          " (geotrajd --max-response-bytes): ask for less (fewer analysisPoints)");
}

// Parses the request, runs `work` on it and serializes its response when it succeeds.
template <class Request, class Response, typename Work>
grpc::Status raw(grpc::CallbackServerContext& context, const grpc::ByteBuffer& in, grpc::ByteBuffer& out,
                 std::uint64_t max_response_bytes, Work&& work) {
  if (auto stop = gone(context, in)) return *stop;
  Request request;
  if (auto bad = parse(in, request)) return *bad;
  Response response;
  const grpc::Status status = work(request, response);
  if (!status.ok()) return status;
  if (auto refused = response_limit(response.ByteSizeLong(), max_response_bytes)) return *refused;
  serialize(response, out);
  return status;
}

// The reactor of a unary call that a worker finishes: gRPC's cancellation (the client's, a
// deadline, a shutdown) trips its stop source, which the work's Abandon and the optimisers
// watch.
class UnaryReactor final : public grpc::ServerUnaryReactor {
 public:
  void OnCancel() override {
    handoff_acquire(this);
    stop_.request_stop();
  }
  void OnDone() override {
    handoff_acquire(this);
    delete this;
  }
  std::stop_token stop() const { return stop_.get_token(); }

 private:
  std::stop_source stop_;
};

// Everything a request plans: the trajectory (along the path, or a move) and, with a
// robot, the resolved robot. Used by PlanTrajectory (with `motion`) and StreamSamples.
// The robot is shared so that its model keeps one address: a joint move's plan points to it.
struct Planned {
  core::Trajectory trajectory;
  std::shared_ptr<const RobotRequest> robot;
};

core::Violations joined(core::Violations a, const core::Violations& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// A time-optimal planner's error: FAILED_PRECONDITION when the path cannot be followed at
// any speed (the field is `motion`: where, and which limit), INVALID_ARGUMENT for bad fields.
grpc::Status failed_precondition_or_invalid(const core::Violations& violations) {
  // `motion` names where the path cannot be followed; `motion.durationS` that the motion
  // the limits allow is too long to sample (the request's own durationS is 0 here).
  const bool precondition = std::all_of(violations.begin(), violations.end(), [](const core::FieldViolation& v) {
    return v.field == "motion" || v.field == "motion.durationS";
  });
  if (!precondition) return invalid_argument(violations);
  std::vector<PreconditionViolation> details;
  std::string message = "the path cannot be followed: ";
  for (std::size_t i = 0; i < violations.size(); ++i) {
    details.push_back({"TIME_OPTIMAL", "motion", violations[i].description});
    message += (i ? "; " : "") + violations[i].description;
  }
  return failed_precondition(message, details);
}

// The fastest timing along the path within the joint limits (with a robot) and the
// Cartesian ones given (thesis 6.4, TOPP in b = s_dot^2: core/time_optimal.hpp), with jerk
// limits by the NLP warm-started from it (optim/time_optimal_jerk.hpp). Its report, with
// which limit binds where, goes to `report` (PlanTrajectory). A path that no positive speed
// can follow is FAILED_PRECONDITION naming where.
tl::expected<core::MotionPlan, grpc::Status> time_optimal_timing(const Abandon& abandon, const Services& services,
                                                                  const core::Path& path,
                                                                  const core::OrientationPlan& orientation,
                                                                  const core::MotionSpec& motion,
                                                                  const RobotRequest* robot, bool jerk_limited,
                                                                  v1::OptimizationReport* report) {
  if (robot == nullptr && !motion.max_acceleration) {
    return tl::unexpected(invalid_argument(core::Violations{
        {"motion.maxAcceleration", "is needed for a time-optimal motion without a robot (and maxSpeed, optional)"}}));
  }
  const auto started = std::chrono::steady_clock::now();
  const core::RobotModel* model = robot ? &robot->model : nullptr;
  const core::JointVector seed = robot ? robot->seed : core::JointVector();
  core::MotionPlan plan;
  std::vector<core::BindingStretch> binding;
  optim::OptimizerReport solver;
  if (jerk_limited) {
    optim::JerkTimingOptions options;
    const auto left = std::chrono::duration<double>(abandon.deadline() - started).count();
    options.time_budget_s = std::clamp(left, 0.0, std::min(kDefaultOptimizeBudgetS, services.limits.max_optimize_seconds));
    options.stop = abandon.stop();
    auto result = optim::plan_time_optimal_jerk(path, orientation, motion, model, seed, {}, options);
    if (!result) return tl::unexpected(failed_precondition_or_invalid(result.error()));
    plan = std::move(result->motion);
    binding = result->exact.binding;
    solver = result->report;
  } else {
    auto result = core::plan_time_optimal(path, orientation, motion, model, seed);
    if (!result) return tl::unexpected(failed_precondition_or_invalid(result.error()));
    plan = std::move(result->motion);
    binding = std::move(result->binding);
    solver.status = optim::OptimizerStatus::kConverged;
    solver.iterations = result->refinements + 1;
    solver.objective_after = plan.duration_s;
  }
  services.metrics.optimization(jerk_limited ? "time_optimal_jerk" : "time_optimal", seconds_since(started));
  if (auto stop = abandon.check()) return tl::unexpected(*stop);
  if (report != nullptr) {
    solver.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    // Before: the move time the request would have had without the optimiser.
    double before = motion.duration_s;
    if (before == 0.0) {
      if (auto conservative = core::plan_motion(path, motion)) before = conservative->duration_s;
    }
    solver.objective_before = before;
    solver.objective_after = plan.duration_s;
    to_proto(solver, binding, *report->mutable_timing());
  }
  return plan;
}

// Plans the trajectory of a request with `motion`, or the status to finish with (every
// violation of the request's parts together).
tl::expected<Planned, grpc::Status> plan_request(const Abandon& abandon, const Services& services,
                                                 const v1::PlanRequest& request, v1::OptimizationReport* optimization) {
  const int kinds = int(request.has_path()) + int(request.has_joint_move()) + int(request.has_linear_move());
  if (kinds != 1) {
    return tl::unexpected(invalid_argument(core::Violations{
        {"path", kinds == 0 ? "is required: give the key frames of a `path`, or a `jointMove` or a `linearMove`"
                            : "give exactly one of `path`, `jointMove` and `linearMove`"}}));
  }
  core::Violations violations;
  if (request.has_optimize() && !request.has_path()) {
    violations.push_back({"optimize", "applies to a `path`: a jointMove or linearMove has nothing to optimise"});
  }
  auto motion = motion_from_request(request);
  if (!motion) violations = joined(std::move(violations), motion.error());
  std::shared_ptr<const RobotRequest> robot;
  if (request.has_robot()) {
    auto resolved = robot_from_request(request, services.robots);
    if (resolved) {
      robot = std::make_shared<const RobotRequest>(std::move(*resolved));
    } else {
      violations = joined(std::move(violations), resolved.error());
    }
  }
  if (request.has_joint_move()) {
    if (!request.has_robot()) {
      violations.push_back({"robot", "is required by a jointMove: the joints belong to a robot model"});
    }
    if (!violations.empty()) return tl::unexpected(invalid_argument(violations));
    auto move = joint_move_from_request(request, robot->model, robot->seed);
    if (!move) return tl::unexpected(invalid_argument(move.error()));
    auto plan = core::plan_joint_move(robot->model, *move, *motion);
    if (!plan) return tl::unexpected(invalid_argument(plan.error()));
    return Planned{core::Trajectory(std::in_place_type<core::JointMovePlan>, std::move(*plan)), std::move(robot)};
  }
  // Following a Cartesian pose (a path or a straight line) takes six joints at least.
  if (robot && !request.has_joint_move() && robot->model.dof() < 6) {
    violations.push_back({request.robot().has_model() ? "robot.model.links" : "robot",
                          "the robot has " + std::to_string(robot->model.dof()) +
                              " joints; following a tool pose (position and orientation) needs at least 6"});
  }
  if (request.has_linear_move()) {
    if (!violations.empty()) return tl::unexpected(invalid_argument(violations));
    auto move = linear_move_from_request(request, robot.get());
    if (!move) return tl::unexpected(invalid_argument(move.error()));
    auto plan = core::plan_linear_move(*move, *motion);
    if (!plan) return tl::unexpected(invalid_argument(plan.error()));
    return Planned{core::Trajectory(std::in_place_type<core::LinearMovePlan>, std::move(*plan)), std::move(robot)};
  }
  if (!violations.empty()) {  // with the path's own violations, so that one answer lists all
    const auto spec = path_from_request(request);
    return tl::unexpected(invalid_argument(spec ? violations : joined(spec.error(), violations)));
  }
  auto spec = optimized_path(abandon, services, request, optimization);
  if (!spec) return tl::unexpected(spec.error());
  auto path = core::build_path(*spec);
  if (!path) return tl::unexpected(invalid_argument(core::prefixed(path.error(), "path.")));
  // A straight start keeps the tool as the robot holds it at its initial joints (or the
  // world axes without a robot): see plan_orientation.
  const Eigen::Quaterniond start_W =
      robot ? Eigen::Quaterniond(core::forward_kinematics(robot->model, robot->seed).rotation())
            : Eigen::Quaterniond::Identity();
  auto orientation = core::plan_orientation(*path, start_W);
  if (!orientation) return tl::unexpected(invalid_argument(core::prefixed(orientation.error(), "path.")));
  const auto& timing_request = request.optimize().timing();
  // As fast as the limits allow: the time-optimal timing, with a robot (joint limits) or
  // without (Cartesian limits; the S-curve keeps its minimum-time double S, whose jerk bound
  // the sweep does not model, unless jerkLimited asks for the NLP).
  const bool minimum_time = motion->duration_s == 0.0 &&
                            (robot || motion->profile == core::ProfileShape::kTrapezoidal);
  const bool time_optimal = timing_request.time_optimal() || timing_request.jerk_limited() || minimum_time;
  if (time_optimal) {
    auto timing = time_optimal_timing(abandon, services, *path, *orientation, *motion, robot.get(), timing_request.jerk_limited(),
                                      optimization);
    if (!timing) return tl::unexpected(timing.error());
    return Planned{core::Trajectory(std::in_place_type<core::PathMotion>,
                                    core::PathMotion{std::move(*path), std::move(*timing), std::move(*orientation)}),
                   std::move(robot)};
  }
  auto timing = core::plan_motion(*path, *motion);
  if (!timing) return tl::unexpected(invalid_argument(timing.error()));
  return Planned{core::Trajectory(std::in_place_type<core::PathMotion>,
                                  core::PathMotion{std::move(*path), std::move(*timing), std::move(*orientation)}),
                 std::move(robot)};
}

// Samples between two checks of cancellation and deadline in the joint-space pass: an IK
// sample costs about a microsecond when the pose is within reach and milliseconds when the
// solver fails on one out of reach, so a check (two clock reads) every 16 keeps an
// abandoned call's overrun to tens of milliseconds at a cost below 0.5 %.
constexpr std::size_t kSamplesPerCheck = 16;

// The tool's peaks over the samples that StreamSamples sends: speed, whole acceleration
// (tangential and centripetal) and angular speed.
struct ToolPeaks {
  double speed = 0.0;          ///< [m/s]
  double acceleration = 0.0;   ///< |a_WT| [m/s^2]
  double angular_speed = 0.0;  ///< |omega_WT| [rad/s]
  void add(const core::TrajectorySample& sample) {
    speed = std::max(speed, sample.speed);
    acceleration = std::max(acceleration, sample.tool.a_WT.norm());
    angular_speed = std::max(angular_speed, sample.tool.omega_WT.norm());
  }
};

// The joint-space pass over every sample: the report, or the status when the call was
// abandoned. Also measures the tool's peaks.
struct RobotPass {
  core::JointMotionReport report;
  ToolPeaks tool;
};

// INVALID_ARGUMENT when a motion has more samples than the server allows: it is streamed,
// followed by a robot (the IK runs at every sample) or summarised from its samples.
std::optional<grpc::Status> sample_limit(const Planned& planned, const ServiceLimits& limits) {
  const auto count = core::sample_count(planned.trajectory);
  if (count <= limits.max_stream_samples) return std::nullopt;
  return invalid_argument(core::Violations{
      {"motion.durationS", "the motion has " + std::to_string(count) + " samples (" +
                               std::to_string(core::duration(planned.trajectory)) +
                               " s at the cycle rate); this server streams and checks at most " +
                               std::to_string(limits.max_stream_samples) +
                               " per call (geotrajd --max-stream-samples): shorten it or lower cycleRateHz"}});
}

tl::expected<RobotPass, grpc::Status> robot_pass(const Abandon& abandon, const Planned& planned) {
  const RobotRequest& robot = *planned.robot;
  core::TrajectorySampler sampler(planned.trajectory, &robot.model, robot.seed);
  core::JointReportBuilder builder(robot.model, robot.branch_tolerance);
  core::TrajectorySample sample;
  RobotPass pass;
  while (sampler.next(sample)) {
    const std::size_t k = sampler.index() - 1;
    builder.add(k, sample.t, sample.s, sample.joints);
    pass.tool.add(sample);
    if (k % kSamplesPerCheck == 0) {
      if (auto stop = abandon.check()) return tl::unexpected(*stop);
    }
  }
  pass.report = builder.report();
  return pass;
}

// The tool's peaks without a robot: the samples without IK (about a microsecond each).
tl::expected<ToolPeaks, grpc::Status> tool_pass(const Abandon& abandon, const core::Trajectory& trajectory) {
  core::TrajectorySampler sampler(trajectory, nullptr, {});
  core::TrajectorySample sample;
  ToolPeaks peaks;
  while (sampler.next(sample)) {
    peaks.add(sample);
    if (sampler.index() % 1024 == 0) {
      if (auto stop = abandon.check()) return tl::unexpected(*stop);
    }
  }
  return peaks;
}

// FAILED_PRECONDITION naming the first broken limit (time, sample, joint) in the message
// and every one in the details.
grpc::Status robot_cannot_follow(const std::string& robot_name, const core::JointMotionReport& report) {
  std::vector<PreconditionViolation> details;
  for (const auto& v : report.violations) {
    v1::LimitEvent event;
    to_proto(v, event);
    const bool per_joint = v.kind != core::LimitKind::kIk && v.kind != core::LimitKind::kBranch;
    details.push_back({v1::LimitKind_Name(event.kind()),
                       per_joint ? "joint " + std::to_string(v.joint) : "sample " + std::to_string(v.sample),
                       describe(v)});
  }
  std::string message = "robot '" + robot_name + "' cannot follow the plan: " + describe(report.violations.front());
  if (report.violations.size() > 1) {
    message += "; and " + std::to_string(report.violations.size() - 1) +
               " more in the PreconditionFailure details (set robot.reportOnly for the full report)";
  }
  return failed_precondition(message, details);
}

void summarize(const core::Trajectory& trajectory, const ToolPeaks& tool, v1::MotionSummary& summary) {
  summary.set_duration_s(core::duration(trajectory));
  summary.set_sample_count(core::sample_count(trajectory));
  summary.set_peak_speed(tool.speed);
  summary.set_peak_acceleration(tool.acceleration);
  summary.set_peak_angular_speed(tool.angular_speed);
  if (const auto* path = std::get_if<core::PathMotion>(&trajectory)) {
    summary.set_peak_tangential_acceleration(path->timing.peak_acceleration);
  } else if (const auto* linear = std::get_if<core::LinearMovePlan>(&trajectory)) {
    summary.set_peak_tangential_acceleration(linear->peak_acceleration);
  }
}

// PlanTrajectory: the geometry; with `motion`, the motion summary; with a robot, the joint
// report (or FAILED_PRECONDITION when the robot cannot follow, unless reportOnly).
grpc::Status plan_trajectory(const Abandon& abandon, const Services& services, const v1::PlanRequest& request,
                             v1::PlanResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  if (auto refused = frame_limit(request.path(), services.limits)) return *refused;
  const bool motion_needed = request.has_robot() || request.has_joint_move() || request.has_linear_move();
  if (request.has_motion() || motion_needed) {
    if (!request.has_motion()) {
      return invalid_argument(core::Violations{
          {"motion", "is required with a robot or a move: give durationS (s), or the limits for a minimum-time move"}});
    }
    auto planned = plan_request(abandon, services, request,
                                request.has_optimize() ? response.mutable_optimization() : nullptr);
    if (!planned) return planned.error();
    if (auto stop = abandon.check()) return *stop;
    if (const auto* path = std::get_if<core::PathMotion>(&planned->trajectory)) {
      report_path(path->path, response);
    }
    // The summary's peaks are those of the samples (tool_pass, robot_pass): bounded like a stream.
    if (auto refused = sample_limit(*planned, services.limits)) return *refused;
    std::optional<RobotPass> pass;
    if (planned->robot) {
      auto result = robot_pass(abandon, *planned);
      if (!result) return result.error();
      pass = std::move(*result);
      if (!pass->report.feasible() && !planned->robot->report_only) {
        return robot_cannot_follow(planned->robot->model.name, pass->report);
      }
      to_proto(planned->robot->model.name, pass->report, *response.mutable_robot());
    }
    ToolPeaks tool;
    if (pass) {
      tool = pass->tool;
    } else {
      auto peaks = tool_pass(abandon, planned->trajectory);
      if (!peaks) return peaks.error();
      tool = *peaks;
    }
    summarize(planned->trajectory, tool, *response.mutable_motion());
    return grpc::Status::OK;
  }
  const auto spec =
      optimized_path(abandon, services, request, request.has_optimize() ? response.mutable_optimization() : nullptr);
  if (!spec) return spec.error();
  const auto path = core::build_path(*spec);
  if (!path) return invalid_argument(core::prefixed(path.error(), "path."));
  if (auto stop = abandon.check()) return *stop;
  report_path(*path, response);
  return grpc::Status::OK;
}

// StreamSamples: the motion is planned on a worker (with a robot, the whole motion is
// checked by robot_pass before the first sample is sent, so that a controller never receives
// the beginning of a motion the robot cannot finish); then samples are produced batch by
// batch while the previous batch is being written (one write in flight), so memory is
// bounded by one batch whatever the motion's length. Cancellation or a passed deadline ends
// the stream at the next batch.
//
// Real-time pacing: a sample is sent when due (t seconds after the stream started); while
// the next one is not due, an alarm wakes the reactor, and cancellation cancels the alarm.
class SampleStreamer final : public grpc::ServerWriteReactor<grpc::ByteBuffer> {
 public:
  SampleStreamer(Call call, grpc::CallbackServerContext& context) : call_(std::move(call)), abandon_(context) {}

  /// Ends the call with `status` before any sample (refusals, bad requests, planning errors).
  void fail(const grpc::Status& status) { End(status); }

  /// Streams `planned` (from the worker that planned it).
  void start(Planned planned, std::size_t batch_size, bool real_time) {
    planned_ = std::make_unique<Planned>(std::move(planned));
    sampler_.emplace(planned_->trajectory, planned_->robot ? &planned_->robot->model : nullptr,
                     planned_->robot ? planned_->robot->seed : core::JointVector());
    batch_size_ = batch_size;
    real_time_ = real_time;
    start_ = std::chrono::system_clock::now();
    batch_.mutable_samples()->Reserve(static_cast<int>(batch_size_));
    NextWrite();
  }

  /// Requested when gRPC cancels the stream: stops its planning (optimisers included).
  std::stop_token stop() const { return stop_.get_token(); }

  void OnCancel() override {
    handoff_acquire(this);
    stop_.request_stop();
    const std::lock_guard lock(alarm_mutex_);
    cancelled_ = true;
    if (alarm_set_) alarm_.Cancel();  // a pending wait ends at once (its callback sees !ok)
  }

  void OnWriteDone(bool ok) override {
    handoff_acquire(this);
    if (!ok) {  // the client went away (cancelled, deadline, connection lost)
      End(abandon_.check().value_or(grpc::Status(grpc::StatusCode::CANCELLED, "the stream was cancelled")));
      return;
    }
    call_.runtime().metrics().samples_streamed(static_cast<std::uint64_t>(batch_.samples_size()));
    sent_ += static_cast<std::uint64_t>(batch_.samples_size());
    NextWrite();
  }

  void OnDone() override {
    handoff_acquire(this);
    delete this;
  }

 private:
  // No write is in flight here, so sent_ is final. The call is counted and logged before its
  // client can see its end (a scrape that sees the stream done sees it counted).
  void End(const grpc::Status& status) {
    const grpc::Status bounded_status = bounded(status);
    call_.finish(bounded_status, sent_);
    handoff_release(this);
    Finish(bounded_status);
  }

  // Waits for `due` on the alarm, unless the call was cancelled (then it ends now): the
  // flag and the alarm under one lock, so that a cancel between the check and the wait
  // still cancels the wait.
  void WaitUntil(std::chrono::system_clock::time_point due) {
    {
      const std::lock_guard lock(alarm_mutex_);
      if (!cancelled_) {
        alarm_set_ = true;
        handoff_release(this);
        alarm_.Set(due, [this](bool ok) {
          handoff_acquire(this);
          {  // WaitUntil has let go of the lock (the alarm may fire before it does)
            const std::lock_guard wait(alarm_mutex_);
            alarm_set_ = false;
          }
          if (ok) {
            NextWrite();
          } else {
            End(abandon_.check().value_or(grpc::Status(grpc::StatusCode::CANCELLED, "the stream was cancelled")));
          }
        });
        return;
      }
    }
    End(abandon_.check().value_or(grpc::Status(grpc::StatusCode::CANCELLED, "the stream was cancelled")));
  }

  void NextWrite() {
    if (auto stop = abandon_.check()) {
      End(*stop);
      return;
    }
    batch_.clear_samples();
    const auto now = std::chrono::system_clock::now();
    while (static_cast<std::size_t>(batch_.samples_size()) < batch_size_) {
      if (!has_pending_ && !sampler_->next(pending_)) break;
      has_pending_ = true;
      if (real_time_) {
        const auto due = start_ + std::chrono::duration_cast<std::chrono::system_clock::duration>(
                                      std::chrono::duration<double>(pending_.t));
        if (due > now) {
          if (batch_.samples_size() > 0) break;  // send what is due; the rest waits
          WaitUntil(due);
          return;
        }
      }
      to_proto(pending_, *batch_.add_samples());
      has_pending_ = false;
    }
    if (batch_.samples_size() == 0) {
      End(grpc::Status::OK);
      return;
    }
    serialize(batch_, bytes_);
    handoff_release(this);
    StartWrite(&bytes_);
  }

  Call call_;
  std::uint64_t sent_ = 0;  // samples written
  Abandon abandon_;         // the client's deadline: a stream may last as long as its motion
  std::unique_ptr<Planned> planned_;  // stable address: the sampler refers to it
  std::optional<core::TrajectorySampler> sampler_;
  std::size_t batch_size_ = 0;
  bool real_time_ = false;
  std::chrono::system_clock::time_point start_;
  std::stop_source stop_;
  std::mutex alarm_mutex_;
  bool cancelled_ = false;  // OnCancel ran
  bool alarm_set_ = false;
  grpc::Alarm alarm_;
  core::TrajectorySample pending_;  // taken from the sampler, not yet sent
  bool has_pending_ = false;
  v1::SampleBatch batch_;
  grpc::ByteBuffer bytes_;  // batch_ serialized: the one write in flight
};

// The planning of a stream (on a worker): the planned motion, or the status to end with.
tl::expected<Planned, grpc::Status> plan_stream(const Abandon& abandon, const Services& services,
                                                const v1::PlanRequest& request) {
  if (auto stop = abandon.check()) return tl::unexpected(*stop);
  if (auto refused = frame_limit(request.path(), services.limits)) return tl::unexpected(*refused);
  if (!request.has_motion()) {
    return tl::unexpected(invalid_argument(core::Violations{
        {"motion", "is required to stream samples: give durationS (s), or maxSpeed and maxAcceleration"}}));
  }
  if (!v1::StreamPacing_IsValid(request.pacing())) {
    return tl::unexpected(invalid_argument(
        core::Violations{{"pacing", "unknown value " + std::to_string(request.pacing()) +
                                        "; use STREAM_PACING_AS_FAST_AS_POSSIBLE or STREAM_PACING_REAL_TIME"}}));
  }
  auto planned = plan_request(abandon, services, request, nullptr);
  if (!planned) return tl::unexpected(planned.error());
  if (auto refused = sample_limit(*planned, services.limits)) return tl::unexpected(*refused);
  if (planned->robot) {
    auto pass = robot_pass(abandon, *planned);
    if (!pass) return tl::unexpected(pass.error());
    // reportOnly streams a motion that breaks joint limits (for simulation and analysis),
    // never one whose IK failed or jumped branches: those joints would be meaningless.
    const auto& violations = pass->report.violations;
    const bool only_limits = std::all_of(violations.begin(), violations.end(), [](const core::LimitEvent& e) {
      return e.kind != core::LimitKind::kIk && e.kind != core::LimitKind::kBranch;
    });
    if (!pass->report.feasible() && !(planned->robot->report_only && only_limits)) {
      return tl::unexpected(robot_cannot_follow(planned->robot->model.name, pass->report));
    }
  }
  if (auto stop = abandon.check()) return tl::unexpected(*stop);
  return planned;
}

// The analysis is the path's geometry: a robot, when given, does not change it.
grpc::Status analyze_path(const Abandon& abandon, const Services& services, const v1::PlanRequest& request,
                          v1::PathProfile& profile) {
  if (auto stop = abandon.check()) return *stop;
  if (auto refused = frame_limit(request.path(), services.limits)) return *refused;
  if (auto refused = analysis_limit(request, services.limits)) return *refused;
  const auto spec = optimized_path(abandon, services, request, nullptr);
  if (!spec) return spec.error();
  const auto path = core::build_path(*spec);
  if (!path) return invalid_argument(core::prefixed(path.error(), "path."));
  if (auto stop = abandon.check()) return *stop;
  to_proto(*path, core::analyze(*path, analysis_points(request)), profile);
  return grpc::Status::OK;
}

// The methods that take a request are registered raw (bytes in, bytes out) so that a
// request that does not parse is this service's INVALID_ARGUMENT, counted and logged like
// any call, rather than gRPC's own answer (UNIMPLEMENTED with no message, in 1.51).
using RawService = v1::TrajectoryService::WithRawCallbackMethod_ConvertConstraints<
    v1::TrajectoryService::WithRawCallbackMethod_PlanTrajectory<v1::TrajectoryService::WithRawCallbackMethod_StreamSamples<
        v1::TrajectoryService::WithRawCallbackMethod_AnalyzePath<
            v1::TrajectoryService::WithCallbackMethod_ListRobots<v1::TrajectoryService::Service>>>>>;

class TrajectoryService final : public RawService {
 public:
  // The synchronous overloads stay declared (the bases make them abort; never called).
  using RawService::AnalyzePath;
  using RawService::ConvertConstraints;
  using RawService::ListRobots;
  using RawService::PlanTrajectory;
  using RawService::StreamSamples;

  TrajectoryService(RobotCatalog robots, std::shared_ptr<Runtime> runtime)
      : robots_(std::move(robots)), runtime_(std::move(runtime)) {}

  // The unary methods run on a worker (unary() below): everything the work refers to
  // (context, request and response buffers, the service) lives until the reactor finishes.
  grpc::ServerUnaryReactor* ConvertConstraints(grpc::CallbackServerContext* context, const grpc::ByteBuffer* in,
                                               grpc::ByteBuffer* out) override {
    return unary(*context, Method::kConvertConstraints, [this, context, in, out](std::stop_token stop) {
      return raw<v1::ConvertRequest, v1::ConvertResponse>(
          *context, *in, *out, limits().max_response_bytes, [&](const auto& request, auto& response) {
            return convert_constraints(abandon(*context, stop), services(), request, response);
          });
    });
  }

  grpc::ServerUnaryReactor* PlanTrajectory(grpc::CallbackServerContext* context, const grpc::ByteBuffer* in,
                                           grpc::ByteBuffer* out) override {
    return unary(*context, Method::kPlanTrajectory, [this, context, in, out](std::stop_token stop) {
      return raw<v1::PlanRequest, v1::PlanResponse>(*context, *in, *out, limits().max_response_bytes,
                                                    [&](const auto& request, auto& response) {
                                                      return plan_trajectory(abandon(*context, stop), services(),
                                                                             request, response);
                                                    });
    });
  }

  // The reactor is returned at once; the planning runs on a worker (before the unary
  // calls queued there), then the samples are written from gRPC's threads.
  grpc::ServerWriteReactor<grpc::ByteBuffer>* StreamSamples(grpc::CallbackServerContext* context,
                                                            const grpc::ByteBuffer* in) override {
    Call call(*runtime_, *context, Method::kStreamSamples);
    const std::optional<grpc::Status> refusal = call.refusal();
    auto* stream = new SampleStreamer(std::move(call), *context);
    if (refusal) {
      stream->fail(*refusal);
      return stream;
    }
    if (auto stop = gone(*context, *in)) {
      stream->fail(*stop);
      return stream;
    }
    auto request = std::make_shared<v1::PlanRequest>();
    if (auto bad = parse(*in, *request)) {
      stream->fail(*bad);
      return stream;
    }
    runtime_->workers().submit(
        [this, context, stream, request] {
          auto planned = plan_stream(abandon(*context, stream->stop()), services(), *request);
          if (!planned) {
            stream->fail(planned.error());
            return;
          }
          stream->start(std::move(*planned), samples_per_batch(*request),
                        request->pacing() == v1::STREAM_PACING_REAL_TIME);
        },
        WorkerPool::Priority::kUrgent);
    return stream;
  }

  grpc::ServerUnaryReactor* AnalyzePath(grpc::CallbackServerContext* context, const grpc::ByteBuffer* in,
                                        grpc::ByteBuffer* out) override {
    return unary(*context, Method::kAnalyzePath, [this, context, in, out](std::stop_token stop) {
      return raw<v1::PlanRequest, v1::PathProfile>(*context, *in, *out, limits().max_response_bytes,
                                                   [&](const auto& request, auto& profile) {
                                                     return analyze_path(abandon(*context, stop), services(),
                                                                         request, profile);
                                                   });
    });
  }

  // Copies the catalog: no long work, answered on gRPC's thread.
  grpc::ServerUnaryReactor* ListRobots(grpc::CallbackServerContext* context, const v1::ListRobotsRequest* /*request*/,
                                       v1::ListRobotsResponse* response) override {
    auto* reactor = context->DefaultReactor();
    Call call(*runtime_, *context, Method::kListRobots);
    grpc::Status status = call.refusal() ? *call.refusal() : grpc::Status::OK;
    if (status.ok()) {
      for (const auto& model : robots_.models) to_proto(model, *response->add_robots());
      if (auto refused = response_limit(response->ByteSizeLong(), limits().max_response_bytes)) {
        response->Clear();
        status = *refused;
      }
    }
    call.finish(status);
    reactor->Finish(status);
    return reactor;
  }

  /// One plan with a motion and one analysis of a small path: the code paths of a real call
  /// run once (and their pages load) before the server reports ready.
  grpc::Status WarmUp() {
    const Abandon abandon(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::PlanRequest request;
    auto* path = request.mutable_path();
    const double points[3][3] = {{0.45, -0.2, 0.6}, {0.5, 0.0, 0.65}, {0.45, 0.2, 0.6}};
    for (const auto& p : points) {
      auto* frame = path->add_frames();
      frame->mutable_position()->set_x(p[0]);
      frame->mutable_position()->set_y(p[1]);
      frame->mutable_position()->set_z(p[2]);
      frame->mutable_tangent()->set_y(1.0);
      frame->set_tangent_scale(0.2);
    }
    request.mutable_motion()->set_duration_s(2.0);
    // Within --max-stream-samples however low it is set (at least 2: the two ends).
    const double samples = static_cast<double>(limits().max_stream_samples);
    request.mutable_motion()->set_cycle_rate_hz(std::min(100.0, (samples - 1.0) / 2.0));
    v1::PlanResponse plan;
    if (auto status = plan_trajectory(abandon, services(), request, plan); !status.ok()) return status;
    v1::PathProfile profile;
    return analyze_path(abandon, services(), request, profile);
  }

 private:
  Services services() const { return Services{robots_, runtime_->limits(), runtime_->metrics()}; }
  const ServiceLimits& limits() const { return runtime_->limits(); }
  // The client's deadline, or the server's default when the client gives none.
  Abandon abandon(grpc::CallbackServerContext& context, std::stop_token stop) const {
    return Abandon(context, limits().default_deadline_s, std::move(stop));
  }

  // Admits the call; runs `work` on a worker when admitted (a refusal is answered at once,
  // on gRPC's thread), then records and finishes it. Calls admitted wait in the workers'
  // queue: --max-unary-calls bounds how many, and the one beyond is RESOURCE_EXHAUSTED.
  template <typename Work>
  grpc::ServerUnaryReactor* unary(grpc::CallbackServerContext& context, Method method, Work&& work) {
    auto* reactor = new UnaryReactor();
    handoff_release(reactor);  // OnCancel may run on another of gRPC's threads
    auto call = std::make_shared<Call>(*runtime_, context, method);
    if (call->refusal()) {
      const grpc::Status status = *call->refusal();
      call->finish(status);
      reactor->Finish(status);
      return reactor;
    }
    runtime_->workers().submit([call, reactor, work = std::forward<Work>(work)]() mutable {
      const grpc::Status status = bounded(work(reactor->stop()));
      call->finish(status);
      handoff_release(reactor);
      reactor->Finish(status);
    });
    return reactor;
  }

  const RobotCatalog robots_;
  std::shared_ptr<Runtime> runtime_;
};

}  // namespace

std::unique_ptr<grpc::Service> make_trajectory_service(RobotCatalog robots,
                                                      std::shared_ptr<Runtime> runtime) {
  return std::make_unique<TrajectoryService>(std::move(robots), std::move(runtime));
}

grpc::Status warm_up(grpc::Service& service) { return static_cast<TrajectoryService&>(service).WarmUp(); }

}  // namespace geotraj::server
