// What the TrajectoryService's calls share, private to server/rpc: each RPC is a free function
// from request to response and status (plan_calls.cpp, kinematics_calls.cpp), and a reactor
// that runs it (service.cpp registers them). Proto <-> core conversion lives in wire/
// (convert.hpp), the mapping of violations to a status in wire/status.cpp.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <stop_token>

#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/proto_buffer_reader.h>
#include <grpcpp/support/proto_buffer_writer.h>
#include <grpcpp/support/server_callback.h>
#include <tl/expected.hpp>

#include "core/error.hpp"
#include "geotraj/v1/geotraj.grpc.pb.h"
#include "planner/planner.hpp"
#include "server/ops/runtime.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server::service_detail {

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
  std::optional<grpc::Status> check() const;

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

// What the work of one call needs from the service: its robots, its limits, its metrics.
struct Services {
  const RobotCatalog& robots;
  const ServiceLimits& limits;
  Metrics& metrics;
};

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
std::optional<grpc::Status> gone(grpc::CallbackServerContext& context, const grpc::ByteBuffer& in);

// The status of a request that did not convert: its deadline or cancellation when that is
// what stopped the conversion (a URDF's parse gives up on them), else INVALID_ARGUMENT.
grpc::Status not_converted(const Abandon& abandon, core::Violations violations);

// The planner's error as the status to finish with (wire/status.hpp maps the kinds): a
// stopped or expired budget is the call's own cancellation or deadline, as Abandon words it.
grpc::Status to_status(const planner::Error& error, const Abandon& abandon);

// The planner's budget of a call: its deadline and cancellation, and the optimisers' metrics.
planner::Budget budget_of(const Abandon& abandon, const Services& services);

// --- the work of each call (plan_calls.cpp, kinematics_calls.cpp) ---

// ConvertConstraints: the key frames of a path given by constraints.
grpc::Status convert_constraints(const Abandon& abandon, const Services& services, const v1::ConvertRequest& request,
                                 v1::ConvertResponse& response);

// PlanTrajectory: the geometry; with `motion`, the motion summary; with a robot, the joint
// report (or FAILED_PRECONDITION when the robot cannot follow, unless reportOnly).
grpc::Status plan_trajectory(const Abandon& abandon, const Services& services, const v1::PlanRequest& request,
                             v1::PlanResponse& response);

// The planning of a stream (on a worker): the planned motion, or the status to end with.
// With a robot the whole motion is checked before the first sample is sent.
tl::expected<planner::Plan, grpc::Status> plan_stream(const Abandon& abandon, const Services& services,
                                                      const v1::PlanRequest& request);

/// Plans a StreamSamples call's request on a worker: the plan, or the status to end with.
using StreamPlanning = std::function<tl::expected<planner::Plan, grpc::Status>(const v1::PlanRequest& request,
                                                                              std::stop_token stop)>;

/// The reactor of one StreamSamples call (admitted or refused by `Call`): the request planned
/// by `planning` on a worker, then its samples written from gRPC's threads.
grpc::ServerWriteReactor<grpc::ByteBuffer>* stream_call(grpc::CallbackServerContext& context,
                                                        const grpc::ByteBuffer& in, Runtime& runtime,
                                                        StreamPlanning planning);

// The planning of an Execute call (on a worker): as a stream's, with `reserve` of every
// acceleration left free for speed changes; field paths from the message's root (`plan.`).
tl::expected<planner::Plan, grpc::Status> plan_execution(const Abandon& abandon, const Services& services,
                                                         const v1::PlanRequest& request, double reserve);

// The analysis is the path's geometry: a robot, when given, does not change it.
grpc::Status analyze_path(const Abandon& abandon, const Services& services, const v1::PlanRequest& request,
                          v1::PathProfile& profile);

// ComputeForwardKinematics: the tool pose, Jacobian and axes of one configuration.
grpc::Status forward_kinematics(const Abandon& abandon, const Services& services,
                                const v1::ForwardKinematicsRequest& request, v1::ForwardKinematicsResponse& response);

// ComputeInverseKinematics: the joints of a pose, or the closest pose when out of reach.
grpc::Status inverse_kinematics(const Abandon& abandon, const Services& services,
                                const v1::InverseKinematicsRequest& request, v1::InverseKinematicsResponse& response);

}  // namespace geotraj::server::service_detail
