// The TrajectoryService: each RPC is a free function from request to response and status,
// and a reactor that runs it. Proto <-> core conversion lives in convert.cpp, the mapping of
// violations to a status in status.cpp.
#include "service.hpp"

#include <chrono>
#include <optional>

#include "convert.hpp"
#include "geotraj/core/analysis.hpp"
#include "geotraj/core/constraints.hpp"
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

// Geometry only for now: `motion` is accepted and not yet planned (PlanResponse.motion
// stays absent).
grpc::Status plan_trajectory(const Abandon& abandon, const v1::PlanRequest& request, v1::PlanResponse& response) {
  if (auto stop = abandon.check()) return *stop;
  if (auto status = unsupported_parts(request, /*robot_allowed=*/false); !status.ok()) return status;
  const auto spec = path_from_request(request);
  if (!spec) return invalid_argument(spec.error());
  const auto path = core::build_path(*spec);
  if (!path) return invalid_argument(core::prefixed(path.error(), "path."));
  if (auto stop = abandon.check()) return *stop;
  const auto achieved = core::achieved_geometry(*path);
  to_proto(*path, achieved, core::closed_loop_error(*path, achieved), response);
  return grpc::Status::OK;
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

// A server-streaming call that ends at once with `status`.
class FinishedWriter final : public grpc::ServerWriteReactor<v1::SampleBatch> {
 public:
  explicit FinishedWriter(const grpc::Status& status) { Finish(status); }
  void OnDone() override { delete this; }
};

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

  grpc::ServerWriteReactor<v1::SampleBatch>* StreamSamples(grpc::CallbackServerContext* /*context*/,
                                                           const v1::PlanRequest* /*request*/) override {
    return new FinishedWriter(unimplemented(
        "StreamSamples is not available yet: motion planning (time parameterization and sampling) is "
        "future work; PlanTrajectory and AnalyzePath serve the path geometry"));
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
