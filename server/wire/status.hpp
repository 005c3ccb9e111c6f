// The status-mapping file: core violations and planner errors -> gRPC status with rich error
// details, each kind mapped here and nowhere else. With convert.hpp, the only place where
// proto and core types meet.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <grpcpp/support/status.h>

#include "core/error.hpp"
#include "planner/planner.hpp"
#include "server/status_codes.hpp"

namespace geotraj::server {

/// INVALID_ARGUMENT carrying every violation: the message lists them for people, and the
/// details (the `grpc-status-details-bin` trailer) hold a serialized google.rpc.Status with
/// one google.rpc.BadRequest whose field violations are `violations`, in order. The field
/// paths must already be complete (`path.frames[2].torsion`).
grpc::Status invalid_argument(const core::Violations& violations);

/// One unmet precondition of a plan (google.rpc.PreconditionFailure.Violation).
struct PreconditionViolation {
  std::string type;         ///< e.g. "LIMIT_KIND_VELOCITY"
  std::string subject;      ///< e.g. "joint 3"
  std::string description;  ///< a sentence naming time, sample, value and limit
};

/// FAILED_PRECONDITION: work the request describes well but that cannot be done (the robot
/// cannot follow the plan). The message is `message`; the details hold a
/// google.rpc.PreconditionFailure with `violations`.
grpc::Status failed_precondition(const std::string& message, const std::vector<PreconditionViolation>& violations);

/// The status of a planner error, its kind mapped once:
///   kInvalidArgument   -> INVALID_ARGUMENT with a BadRequest (invalid_argument)
///   kUnattainable      -> FAILED_PRECONDITION "the path cannot be followed: ...", a
///                         PreconditionFailure of type TIME_OPTIMAL per violation, its subject
///                         the violation's field (`motion`, `motion.durationS`)
///   kRobotCannotFollow -> FAILED_PRECONDITION naming the robot and its first broken limit,
///                         every one in the PreconditionFailure (type LIMIT_KIND_*)
///   kStopped           -> CANCELLED; kDeadlineExceeded -> DEADLINE_EXCEEDED (the reactor
///                         words these after the call's own cancellation or deadline when it can)
grpc::Status status_of(const planner::Error& error);

/// `status` within what every client takes: its message cut to kMaxStatusMessageBytes and
/// its details dropped beyond kMaxStatusDetailsBytes (invalid_argument and
/// failed_precondition keep theirs below it by leaving violations out, with a count).
/// gRPC clients refuse trailers beyond 8 KiB by default.
grpc::Status bounded(const grpc::Status& status);

inline constexpr std::size_t kMaxStatusMessageBytes = 1024;
inline constexpr std::size_t kMaxStatusDetailsBytes = 4096;


}  // namespace geotraj::server
