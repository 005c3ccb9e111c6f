// The TrajectoryService: each RPC is a free function from request to response and status,
// and a reactor that runs it. Proto <-> core conversion lives in convert.cpp, the mapping of
// violations to a status in status.cpp.
#include "service.hpp"

#include <chrono>
#include <functional>
#include <memory>
#include <optional>

#include <grpcpp/alarm.h>

#include "convert.hpp"
#include "geotraj/core/analysis.hpp"
#include "geotraj/core/constraints.hpp"
#include "geotraj/core/motion.hpp"
#include "geotraj/core/orientation.hpp"
#include "geotraj/core/path.hpp"
#include "status.hpp"

namespace geotraj::server {
namespace {

// Whether the caller still wants the answer: checked before each stage of work, so that a
// cancelled call or a passed deadline stops it at the next stage.
class Abandon {
 public:
  explicit Abandon(grpc::CallbackServerContext& context) : context_(context) {}
  /// The status to finish with when the call is no longer wanted.
  std::optional<grpc::Status> check() const {
    if (context_.IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled");
    if (context_.deadline() <= std::chrono::system_clock::now()) {
      return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "the deadline passed before the work was done");
    }
    return std::nullopt;
  }

 private:
  grpc::CallbackServerContext& context_;
};

// Features of the contract that later work adds; until then they get UNIMPLEMENTED naming
// the request field.
grpc::Status unsupported_parts(const v1::PlanRequest& request, bool robot_allowed) {
  if (request.has_optimize()) {
    return unimplemented("optimization is not available yet: send the PlanRequest without `optimize`");
  }
  if (request.has_robot() && !robot_allowed) {
    return unimplemented("robot kinematics is not available yet: send the PlanRequest without `robot`");
  }
  return grpc::Status::OK;
}

grpc::Status convert_constraints(const Abandon& abandon, const v1::ConvertRequest& request,
                                 v1::ConvertResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  const auto spec = path_from_request(request);
  if (!spec) return invalid_argument(spec.error());
  const auto frames = core::convert_path(*spec);
  if (!frames) return invalid_argument(core::prefixed(frames.error(), "path."));
  to_proto(*frames, response);
  return grpc::Status::OK;
}

// A server-streaming call that ends at once with `status`.
class FinishedWriter final : public grpc::ServerWriteReactor<v1::SampleBatch> {
 public:
  explicit FinishedWriter(const grpc::Status& status) { Finish(status); }
  void OnDone() override { delete this; }
};

// Everything a motion needs, planned from one request: the path, the timing along it and
// the tool orientation. Used by PlanTrajectory (with `motion`) and StreamSamples.
struct PlannedMotion {
  core::Path path;
  core::MotionPlan timing;
  core::OrientationPlan orientation;
};

// Plans the path and its motion, or the status to finish with (every violation of path and
// motion together).
tl::expected<PlannedMotion, grpc::Status> plan_motion(const v1::PlanRequest& request) {
  const auto spec = path_from_request(request);
  const auto motion = motion_from_request(request);
  if (!spec || !motion) {
    core::Violations all = spec ? core::Violations{} : spec.error();
    if (!motion) all.insert(all.end(), motion.error().begin(), motion.error().end());
    return tl::unexpected(invalid_argument(all));
  }
  auto path = core::build_path(*spec);
  if (!path) return tl::unexpected(invalid_argument(core::prefixed(path.error(), "path.")));
  auto timing = core::plan_motion(*path, *motion);
  auto orientation = core::plan_orientation(*path);
  if (!timing || !orientation) {
    core::Violations all = timing ? core::Violations{} : timing.error();
    if (!orientation) {
      const auto more = core::prefixed(orientation.error(), "path.");
      all.insert(all.end(), more.begin(), more.end());
    }
    return tl::unexpected(invalid_argument(all));
  }
  return PlannedMotion{std::move(*path), std::move(*timing), std::move(*orientation)};
}

// The geometry, and with `motion` the motion summary too.
grpc::Status plan_trajectory(const Abandon& abandon, const v1::PlanRequest& request, v1::PlanResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  if (auto status = unsupported_parts(request, /*robot_allowed=*/false); !status.ok()) return status;
  if (request.has_motion()) {
    auto planned = plan_motion(request);
    if (!planned) return planned.error();
    if (auto stop = abandon.check()) return *stop;
    const auto achieved = core::achieved_geometry(planned->path);
    to_proto(planned->path, achieved, core::closed_loop_error(planned->path, achieved), response);
    to_proto(planned->timing, *response.mutable_motion());
    return grpc::Status::OK;
  }
  const auto spec = path_from_request(request);
  if (!spec) return invalid_argument(spec.error());
  const auto path = core::build_path(*spec);
  if (!path) return invalid_argument(core::prefixed(path.error(), "path."));
  if (auto stop = abandon.check()) return *stop;
  const auto achieved = core::achieved_geometry(*path);
  to_proto(*path, achieved, core::closed_loop_error(*path, achieved), response);
  return grpc::Status::OK;
}

// StreamSamples: samples are produced batch by batch while the previous batch is being
// written (one write in flight), so memory is bounded by one batch whatever the motion's
// length. Cancellation or a passed deadline ends the stream at the next batch.
//
// Real-time pacing: a sample is sent when due (t seconds after the stream started); while
// the next one is not due, an alarm wakes the reactor, and cancellation cancels the alarm.
class SampleStreamer final : public grpc::ServerWriteReactor<v1::SampleBatch> {
 public:
  SampleStreamer(grpc::CallbackServerContext& context, PlannedMotion planned, std::size_t batch_size, bool real_time)
      : abandon_(context),
        planned_(std::make_unique<PlannedMotion>(std::move(planned))),
        sampler_(planned_->path, planned_->timing),
        batch_size_(batch_size),
        real_time_(real_time),
        start_(std::chrono::system_clock::now()) {
    batch_.mutable_samples()->Reserve(static_cast<int>(batch_size_));
    NextWrite();
  }

  void OnCancel() override {
    if (real_time_) alarm_.Cancel();  // a pending wait ends at once (its callback sees !ok)
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {  // the client went away (cancelled, deadline, connection lost)
      Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the stream was cancelled"));
      return;
    }
    NextWrite();
  }

  void OnDone() override { delete this; }

 private:
  void NextWrite() {
    if (auto stop = abandon_.check()) {
      Finish(*stop);
      return;
    }
    batch_.clear_samples();
    const auto now = std::chrono::system_clock::now();
    while (static_cast<std::size_t>(batch_.samples_size()) < batch_size_) {
      if (!has_pending_ && !sampler_.next(pending_)) break;
      has_pending_ = true;
      if (real_time_) {
        const auto due = start_ + std::chrono::duration_cast<std::chrono::system_clock::duration>(
                                      std::chrono::duration<double>(pending_.t));
        if (due > now) {
          if (batch_.samples_size() > 0) break;  // send what is due; the rest waits
          alarm_.Set(due, [this](bool ok) {
            if (ok) {
              NextWrite();
            } else {
              Finish(abandon_.check().value_or(grpc::Status(grpc::StatusCode::CANCELLED, "the stream was cancelled")));
            }
          });
          return;
        }
      }
      auto orientation = core::orientation_at(planned_->orientation, planned_->path, pending_.segment,
                                              pending_.u - static_cast<double>(pending_.segment), pending_.s,
                                              pending_.speed);
      // q and -q are one rotation: keep successive samples in one hemisphere.
      if (orientation.q_WT.coeffs().dot(previous_q_.coeffs()) < 0.0) orientation.q_WT.coeffs() *= -1.0;
      previous_q_ = orientation.q_WT;
      to_proto(pending_, orientation, *batch_.add_samples());
      has_pending_ = false;
    }
    if (batch_.samples_size() == 0) {
      Finish(grpc::Status::OK);
      return;
    }
    StartWrite(&batch_);
  }

  Abandon abandon_;
  std::unique_ptr<PlannedMotion> planned_;  // stable address: the sampler refers to it
  core::MotionSampler sampler_;
  std::size_t batch_size_;
  bool real_time_;
  std::chrono::system_clock::time_point start_;
  grpc::Alarm alarm_;
  core::MotionSample pending_;  // taken from the sampler, not yet sent
  bool has_pending_ = false;
  v1::SampleBatch batch_;
  Eigen::Quaterniond previous_q_ = Eigen::Quaterniond::Identity();
};

grpc::ServerWriteReactor<v1::SampleBatch>* stream_samples(grpc::CallbackServerContext& context,
                                                          const v1::PlanRequest& request) {
  if (auto stop = Abandon(context).check()) return new FinishedWriter(*stop);
  if (auto status = unsupported_parts(request, /*robot_allowed=*/false); !status.ok()) {
    return new FinishedWriter(status);
  }
  if (!request.has_motion()) {
    return new FinishedWriter(invalid_argument(core::Violations{
        {"motion", "is required to stream samples: give durationS (s), or maxSpeed and maxAcceleration"}}));
  }
  if (!v1::StreamPacing_IsValid(request.pacing())) {
    return new FinishedWriter(invalid_argument(
        core::Violations{{"pacing", "unknown value " + std::to_string(request.pacing()) +
                                        "; use STREAM_PACING_AS_FAST_AS_POSSIBLE or STREAM_PACING_REAL_TIME"}}));
  }
  auto planned = plan_motion(request);
  if (!planned) return new FinishedWriter(planned.error());
  return new SampleStreamer(context, std::move(*planned), samples_per_batch(request),
                            request.pacing() == v1::STREAM_PACING_REAL_TIME);
}

// The analysis is the path's geometry: a robot, when given, does not change it.
grpc::Status analyze_path(const Abandon& abandon, const v1::PlanRequest& request, v1::PathProfile& profile) {
  if (auto stop = abandon.check()) return *stop;
  if (auto status = unsupported_parts(request, /*robot_allowed=*/true); !status.ok()) return status;
  const auto spec = path_from_request(request);
  if (!spec) return invalid_argument(spec.error());
  const auto path = core::build_path(*spec);
  if (!path) return invalid_argument(core::prefixed(path.error(), "path."));
  if (auto stop = abandon.check()) return *stop;
  to_proto(*path, core::analyze(*path, analysis_points(request)), profile);
  return grpc::Status::OK;
}

class TrajectoryService final : public v1::TrajectoryService::CallbackService {
  grpc::ServerUnaryReactor* ConvertConstraints(grpc::CallbackServerContext* context,
                                               const v1::ConvertRequest* request,
                                               v1::ConvertResponse* response) override {
    auto* reactor = context->DefaultReactor();
    reactor->Finish(convert_constraints(Abandon(*context), *request, *response));
    return reactor;
  }

  grpc::ServerUnaryReactor* PlanTrajectory(grpc::CallbackServerContext* context, const v1::PlanRequest* request,
                                           v1::PlanResponse* response) override {
    auto* reactor = context->DefaultReactor();
    reactor->Finish(plan_trajectory(Abandon(*context), *request, *response));
    return reactor;
  }

  grpc::ServerWriteReactor<v1::SampleBatch>* StreamSamples(grpc::CallbackServerContext* context,
                                                           const v1::PlanRequest* request) override {
    return stream_samples(*context, *request);
  }

  grpc::ServerUnaryReactor* AnalyzePath(grpc::CallbackServerContext* context, const v1::PlanRequest* request,
                                        v1::PathProfile* profile) override {
    auto* reactor = context->DefaultReactor();
    reactor->Finish(analyze_path(Abandon(*context), *request, *profile));
    return reactor;
  }

  grpc::ServerUnaryReactor* ListRobots(grpc::CallbackServerContext* context, const v1::ListRobotsRequest* /*request*/,
                                       v1::ListRobotsResponse* /*response*/) override {
    auto* reactor = context->DefaultReactor();
    reactor->Finish(
        unimplemented("ListRobots is not available yet: the built-in robot models (PA-10) are future work"));
    return reactor;
  }
};

}  // namespace

std::unique_ptr<v1::TrajectoryService::CallbackService> make_trajectory_service() {
  return std::make_unique<TrajectoryService>();
}

}  // namespace geotraj::server
