// The path and planning calls' work (service_calls.hpp): ConvertConstraints, PlanTrajectory,
// StreamSamples (its reactor, SampleStreamer), AnalyzePath and the planning of Execute.
#include "server/rpc/service_calls.hpp"

#include <grpc/support/time.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <stop_token>

#include <grpcpp/alarm.h>

#include "core/geometry/analysis.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/path.hpp"
#include "core/planning/trajectory.hpp"
#include "planner/planner.hpp"
#include "server/ops/runtime.hpp"
#include "server/ops/tsan.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server::service_detail {
namespace {

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
    sampler_.emplace(*planned_->trajectory, planned_->robot ? &planned_->robot->model.model() : nullptr,
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

}  // namespace

grpc::Status convert_constraints(const Abandon& abandon, const Services& services, const v1::ConvertRequest& request,
                                 v1::ConvertResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  const auto spec = planner::admit_path(path_input(request, services.limits));
  if (!spec) return invalid_argument(spec.error());
  const auto frames = planner::convert(*spec);
  if (!frames) return invalid_argument(frames.error().violations);
  to_proto(*frames, response);
  return grpc::Status::OK;
}

grpc::Status plan_trajectory(const Abandon& abandon, const Services& services, const v1::PlanRequest& request,
                             v1::PlanResponse& response) {
  auto plan = plan_call(abandon, services, request, planner::Use::kPlan);
  if (!plan) return plan.error();
  // The optimisers' report where the request asks for one, or where an optimiser ran unasked
  // (the joints of a straight line to goal joints on a redundant arm).
  to_proto(*plan, request.has_optimize() || plan->optimizers.redundancy.has_value(), response);
  return grpc::Status::OK;
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* stream_call(grpc::CallbackServerContext& context,
                                                        const grpc::ByteBuffer& in, Runtime& runtime,
                                                        StreamPlanning planning) {
  Call call(runtime, context, Method::kStreamSamples);
  const std::optional<grpc::Status> refusal = call.refusal();
  auto* stream = new SampleStreamer(std::move(call), context);
  handoff_release(stream);  // OnCancel may run on another of gRPC's threads
  if (refusal) {
    stream->fail(*refusal);
    return stream;
  }
  if (auto stop = gone(context, in)) {
    stream->fail(*stop);
    return stream;
  }
  auto request = std::make_shared<v1::PlanRequest>();
  if (auto bad = parse(in, *request)) {
    stream->fail(*bad);
    return stream;
  }
  runtime.workers().submit(
      [planning = std::move(planning), stream, request] {
        auto planned = planning(*request, stream->stop());
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

tl::expected<planner::Plan, grpc::Status> plan_stream(const Abandon& abandon, const Services& services,
                                                      const v1::PlanRequest& request) {
  return plan_call(abandon, services, request, planner::Use::kStream);
}

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

}  // namespace geotraj::server::service_detail
