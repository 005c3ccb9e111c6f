// The TrajectoryService: each RPC is a free function from request to response and status,
// and a reactor that runs it. Proto <-> core conversion lives in wire/ (convert.hpp), the
// mapping of violations to a status in wire/status.cpp.
#include "server/rpc/service.hpp"

#include <grpc/support/time.h>

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

#include "core/geometry/analysis.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/time_optimal.hpp"
#include "core/planning/trajectory.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/planner.hpp"
#include "server/ops/runtime.hpp"
#include "core/format.hpp"
#include "server/rpc/live.hpp"
#include "server/ops/tsan.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/kinematics.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server {
namespace {

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
                            "the call gave no deadline, and the server's default of " + core::number(default_s_, 6) +
                                " s (geotrajd --default-deadline-seconds) passed before the work was done");
      }
      return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "the deadline passed before the work was done");
    }
    if (cancelled) return grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled");
    return std::nullopt;
  }

  /// Requested when the call is cancelled (empty for work no client waits for).
  const std::stop_token& stop() const { return stop_; }

  /// The deadline and cancellation, for the parse of a request's URDF.
  planner::StopAt stop_at() const { return planner::StopAt{deadline(), stop_}; }

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

// The status of a request that did not convert: its deadline or cancellation when that is
// what stopped the conversion (a URDF's parse gives up on them), else INVALID_ARGUMENT.
grpc::Status not_converted(const Abandon& abandon, core::Violations violations) {
  if (auto stop = abandon.check()) return *stop;
  return invalid_argument(std::move(violations));
}

// What the work of one call needs from the service: its robots, its limits, its metrics.
struct Services {
  const RobotCatalog& robots;
  const ServiceLimits& limits;
  Metrics& metrics;
};

grpc::Status convert_constraints(const Abandon& abandon, const Services& services, const v1::ConvertRequest& request,
                                 v1::ConvertResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  const auto spec = path_from_request(request, services.limits);
  if (!spec) return invalid_argument(spec.error());
  const auto frames = planner::convert(*spec);
  if (!frames) return invalid_argument(frames.error().violations);
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

// The planner's error as the status to finish with (wire/status.hpp maps the kinds): a
// stopped or expired budget is the call's own cancellation or deadline, as Abandon words it.
grpc::Status to_status(const planner::Error& error, const Abandon& abandon) {
  if (error.kind == planner::ErrorKind::kStopped || error.kind == planner::ErrorKind::kDeadlineExceeded) {
    if (auto status = abandon.check()) return *status;
  }
  return status_of(error);
}

// The planner's budget of a call: its deadline and cancellation, and the optimisers' metrics.
planner::Budget budget_of(const Abandon& abandon, const Services& services) {
  planner::Budget budget;
  budget.deadline = abandon.deadline();
  budget.stop = abandon.stop();
  Metrics* metrics = &services.metrics;
  budget.on_optimizer = [metrics](std::string_view name, double seconds) {
    metrics->optimization(std::string(name), seconds);
  };
  return budget;
}

planner::Limits limits_of(const Services& services) {
  return planner::Limits{services.limits.max_stream_samples, "geotrajd --max-stream-samples"};
}

// The request read (once) and admitted for `use`, or every violation of it.
core::Expected<planner::Request> admitted(const Abandon& abandon, const Services& services,
                                          const v1::PlanRequest& request, planner::Use use) {
  return planner::admit(request_input_from_proto(request, services.limits), services.robots, use, abandon.stop_at());
}

// Admits the request for `use` and plans it; the status to finish with on any error.
tl::expected<planner::Plan, grpc::Status> plan_call(const Abandon& abandon, const Services& services,
                                                    const v1::PlanRequest& request, planner::Use use) {
  if (auto stop = abandon.check()) return tl::unexpected(*stop);
  auto input = admitted(abandon, services, request, use);
  if (!input) return tl::unexpected(not_converted(abandon, std::move(input.error())));
  auto plan = planner::plan(*input, budget_of(abandon, services), limits_of(services), use);
  if (!plan) return tl::unexpected(to_status(plan.error(), abandon));
  return std::move(*plan);
}

// PlanTrajectory: the geometry; with `motion`, the motion summary; with a robot, the joint
// report (or FAILED_PRECONDITION when the robot cannot follow, unless reportOnly).
grpc::Status plan_trajectory(const Abandon& abandon, const Services& services, const v1::PlanRequest& request,
                             v1::PlanResponse& response) {
  auto plan = plan_call(abandon, services, request, planner::Use::kPlan);
  if (!plan) return plan.error();
  to_proto(*plan, request.has_optimize(), response);
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

  /// Streams `planned` (from the worker that planned it; it has a trajectory).
  void start(planner::Plan planned, std::size_t batch_size, bool real_time) {
    planned_ = std::make_unique<planner::Plan>(std::move(planned));
    sampler_.emplace(*planned_->trajectory, planned_->robot ? &planned_->robot->model : nullptr,
                     planned_->robot ? planned_->robot->seed : core::JointVector());
    batch_size_ = batch_size;
    real_time_ = real_time;
    start_ = std::chrono::steady_clock::now();  // pacing on the monotonic clock: no wall-clock steps
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
  void WaitUntil(std::chrono::steady_clock::time_point due) {
    {
      const std::lock_guard lock(alarm_mutex_);
      if (!cancelled_) {
        alarm_set_ = true;
        handoff_release(this);
        // gRPC's monotonic clock is CLOCK_MONOTONIC, as steady_clock's: the same instant.
        const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(due - std::chrono::steady_clock::now());
        const gpr_timespec deadline = gpr_time_add(
            gpr_now(GPR_CLOCK_MONOTONIC), gpr_time_from_nanos(std::max<std::int64_t>(0, left.count()), GPR_TIMESPAN));
        alarm_.Set(deadline, [this](bool ok) {
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
    const auto now = std::chrono::steady_clock::now();
    while (static_cast<std::size_t>(batch_.samples_size()) < batch_size_) {
      if (!has_pending_ && !sampler_->next(pending_)) break;
      has_pending_ = true;
      if (real_time_) {
        const auto due = start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
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
  std::unique_ptr<planner::Plan> planned_;  // stable address: the sampler refers to it
  std::optional<core::TrajectorySampler> sampler_;
  std::size_t batch_size_ = 0;
  bool real_time_ = false;
  std::chrono::steady_clock::time_point start_;
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
// With a robot the whole motion is checked before the first sample is sent.
tl::expected<planner::Plan, grpc::Status> plan_stream(const Abandon& abandon, const Services& services,
                                                      const v1::PlanRequest& request) {
  return plan_call(abandon, services, request, planner::Use::kStream);
}

// The planning of an Execute call (on a worker): as a stream's, with `reserve` of every
// acceleration left free for speed changes; field paths from the message's root (`plan.`).
tl::expected<planner::Plan, grpc::Status> plan_execution(const Abandon& abandon, const Services& services,
                                                         const v1::PlanRequest& request, double reserve) {
  if (auto stop = abandon.check()) return tl::unexpected(*stop);
  auto input = admitted(abandon, services, request, planner::Use::kStream);
  if (!input) return tl::unexpected(not_converted(abandon, core::prefixed(std::move(input.error()), "plan.")));
  if (input->robot && input->robot->report_only) {
    return tl::unexpected(invalid_argument(core::Violations{
        {"plan.robot.reportOnly", "Execute drives the robot, within its limits: a plan that may break them "
                                  "(reportOnly) is for PlanTrajectory and StreamSamples"}}));
  }
  planner::reserve_room(*input, reserve);
  // A live plan's samples are bounded by --max-live-samples before the robot pass (IK at
  // every sample), whatever timing set its duration.
  planner::Limits limits = limits_of(services);
  if (services.limits.max_live_samples < limits.max_samples) {
    limits = planner::Limits{services.limits.max_live_samples, "geotrajd --max-live-samples"};
  }
  auto plan = planner::plan(*input, budget_of(abandon, services), limits, planner::Use::kStream);
  if (!plan) {
    plan.error().violations = core::prefixed(std::move(plan.error().violations), "plan.");
    return tl::unexpected(to_status(plan.error(), abandon));
  }
  return std::move(*plan);
}

// The analysis is the path's geometry: a robot, when given, does not change it.
grpc::Status analyze_path(const Abandon& abandon, const Services& services, const v1::PlanRequest& request,
                          v1::PathProfile& profile) {
  if (auto stop = abandon.check()) return *stop;
  auto input = admitted(abandon, services, request, planner::Use::kAnalyze);
  if (!input) return not_converted(abandon, std::move(input.error()));
  auto analysis = planner::analyze(*input, analysis_points(request), budget_of(abandon, services));
  if (!analysis) return to_status(analysis.error(), abandon);
  to_proto(analysis->path, analysis->points, profile);
  return grpc::Status::OK;
}

// ComputeForwardKinematics: the tool pose, Jacobian and axes of one configuration.
grpc::Status forward_kinematics(const Abandon& abandon, const Services& services,
                                const v1::ForwardKinematicsRequest& request, v1::ForwardKinematicsResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  auto input = planner::admit(forward_input_from_proto(request), services.robots, abandon.stop_at());
  if (!input) return not_converted(abandon, std::move(input.error()));
  to_proto(planner::forward_kinematics(*input), response);
  return grpc::Status::OK;
}

// ComputeInverseKinematics: the joints of a pose, or the closest pose when out of reach.
grpc::Status inverse_kinematics(const Abandon& abandon, const Services& services,
                                const v1::InverseKinematicsRequest& request, v1::InverseKinematicsResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  auto input = planner::admit(inverse_input_from_proto(request), services.robots, abandon.stop_at());
  if (!input) return not_converted(abandon, std::move(input.error()));
  auto answer = planner::inverse_kinematics(*input, budget_of(abandon, services));
  if (!answer) return to_status(answer.error(), abandon);
  to_proto(*answer, response);
  return grpc::Status::OK;
}

// The methods that take a request are registered raw (bytes in, bytes out) so that a
// request that does not parse is this service's INVALID_ARGUMENT, counted and logged like
// any call, rather than gRPC's own answer (UNIMPLEMENTED with no message, in 1.51).
using Api = v1::TrajectoryService;
using RawService = Api::WithRawCallbackMethod_ConvertConstraints<Api::WithRawCallbackMethod_PlanTrajectory<
    Api::WithRawCallbackMethod_StreamSamples<Api::WithRawCallbackMethod_AnalyzePath<
        Api::WithRawCallbackMethod_ComputeForwardKinematics<Api::WithRawCallbackMethod_ComputeInverseKinematics<
            Api::WithRawCallbackMethod_Execute<Api::WithRawCallbackMethod_Jog<
                Api::WithCallbackMethod_ListRobots<Api::Service>>>>>>>>>;

class TrajectoryService final : public RawService {
 public:
  // The synchronous overloads stay declared (the bases make them abort; never called).
  using RawService::AnalyzePath;
  using RawService::ComputeForwardKinematics;
  using RawService::ComputeInverseKinematics;
  using RawService::ConvertConstraints;
  using RawService::Execute;
  using RawService::Jog;
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
    handoff_release(stream);  // OnCancel may run on another of gRPC's threads
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

  // Live execution: the reactor reads the first message and plans it on a worker.
  grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Execute(grpc::CallbackServerContext* context) override {
    return execute_call(*context, *runtime_,
                        [this, context](const v1::PlanRequest& request, double reserve, std::stop_token stop) {
                          return plan_execution(abandon(*context, std::move(stop)), services(), request, reserve);
                        });
  }

  grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* Jog(grpc::CallbackServerContext* context) override {
    return jog_call(*context, *runtime_, robots_);
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
  grpc::ServerUnaryReactor* ComputeForwardKinematics(grpc::CallbackServerContext* context, const grpc::ByteBuffer* in,
                                                     grpc::ByteBuffer* out) override {
    return unary(*context, Method::kComputeForwardKinematics, [this, context, in, out](std::stop_token stop) {
      return raw<v1::ForwardKinematicsRequest, v1::ForwardKinematicsResponse>(
          *context, *in, *out, limits().max_response_bytes, [&](const auto& request, auto& response) {
            return forward_kinematics(abandon(*context, stop), services(), request, response);
          });
    });
  }

  grpc::ServerUnaryReactor* ComputeInverseKinematics(grpc::CallbackServerContext* context, const grpc::ByteBuffer* in,
                                                     grpc::ByteBuffer* out) override {
    return unary(*context, Method::kComputeInverseKinematics, [this, context, in, out](std::stop_token stop) {
      return raw<v1::InverseKinematicsRequest, v1::InverseKinematicsResponse>(
          *context, *in, *out, limits().max_response_bytes, [&](const auto& request, auto& response) {
            return inverse_kinematics(abandon(*context, stop), services(), request, response);
          });
    });
  }

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
