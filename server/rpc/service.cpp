// The TrajectoryService's registration: its raw callback methods, each admitted by `Call` and
// run by a reactor over the work in plan_calls.cpp and kinematics_calls.cpp; what they share.
#include "server/rpc/service.hpp"

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <stop_token>

#include <grpcpp/support/byte_buffer.h>

#include "core/format.hpp"
#include "planner/planner.hpp"
#include "server/ops/runtime.hpp"
#include "server/ops/tsan.hpp"
#include "server/rpc/live.hpp"
#include "server/rpc/service_calls.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server {

// --- what the calls share (service_calls.hpp) ---

namespace service_detail {

std::optional<grpc::Status> Abandon::check() const {
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

std::optional<grpc::Status> gone(grpc::CallbackServerContext& context, const grpc::ByteBuffer& in) {
  if (context.IsCancelled()) return grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled");
  if (!in.Valid()) return grpc::Status(grpc::StatusCode::CANCELLED, "the request did not arrive");
  return std::nullopt;
}

grpc::Status not_converted(const Abandon& abandon, core::Violations violations) {
  if (auto stop = abandon.check()) return *stop;
  return invalid_argument(std::move(violations));
}

grpc::Status to_status(const planner::Error& error, const Abandon& abandon) {
  if (error.kind == planner::ErrorKind::kStopped || error.kind == planner::ErrorKind::kDeadlineExceeded) {
    if (auto status = abandon.check()) return *status;
  }
  return status_of(error);
}

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

}  // namespace service_detail

using namespace service_detail;

namespace {

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
    return stream_call(*context, *in, *runtime_,
                       [this, context](const v1::PlanRequest& request, std::stop_token stop) {
                         return plan_stream(abandon(*context, std::move(stop)), services(), request);
                       });
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
