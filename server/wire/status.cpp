// The status-mapping file (see status.hpp).
#include "server/wire/status.hpp"

#include <algorithm>
#include <cstddef>

#include "google/rpc/error_details.pb.h"
#include "google/rpc/status.pb.h"
#include "server/wire/convert.hpp"
#include "server/wire/text.hpp"

namespace geotraj::server {
namespace {

// The message lists this many violations; the details list as many as fit in
// kDetailBudget bytes, and say how many they left out.
constexpr std::size_t kViolationsInMessage = 5;
// Bytes of violations in the details (the rest of kMaxStatusDetailsBytes is the message).
constexpr std::size_t kDetailBudget = kMaxStatusDetailsBytes - kMaxStatusMessageBytes - 256;
// Longest field path and description in an answer [bytes]: a request's strings (names,
// values) are quoted in descriptions, and a client's 1 MB name must not come back whole.
constexpr std::size_t kMaxFieldBytes = 256;
constexpr std::size_t kMaxDescriptionBytes = 512;

std::string summary(const core::Violations& violations) {
  std::string message = "invalid request: " + std::to_string(violations.size()) +
                         (violations.size() == 1 ? " problem" : " problems");
  for (std::size_t i = 0; i < violations.size() && i < kViolationsInMessage; ++i) {
    // An empty field is the request as a whole (bytes that are no request).
    const std::string field = truncated(violations[i].field, kMaxFieldBytes);
    message += (i == 0 ? ": " : "; ") + (field.empty() ? "" : field + ": ") +
               truncated(violations[i].description, kMaxDescriptionBytes / 4);
  }
  if (violations.size() > kViolationsInMessage) {
    message += "; and " + std::to_string(violations.size() - kViolationsInMessage) +
               " more in the BadRequest details";
  }
  return truncated(message, kMaxStatusMessageBytes);
}

// Adds one entry to `repeated` for each of `items`, filled by `fill`, while `details` stays
// within kDetailBudget bytes; then, when some did not fit, one made by `left_out(count)`.
template <class Details, class Repeated, class Items, typename Fill, typename LeftOut>
void add_within_budget(const Details& details, Repeated& repeated, const Items& items, Fill&& fill,
                       LeftOut&& left_out) {
  std::size_t kept = 0;
  for (const auto& item : items) {
    fill(item, *repeated.Add());
    if (details.ByteSizeLong() > kDetailBudget) {
      repeated.RemoveLast();
      break;
    }
    ++kept;
  }
  if (kept < items.size()) {
    left_out(*repeated.Add(), std::to_string(items.size() - kept) + " more violations left out (of " +
                                  std::to_string(items.size()) + ")");
  }
}

// A google.rpc.Status of `code` and `message` with `detail` packed, as a grpc::Status.
template <class Detail>
grpc::Status with_details(grpc::StatusCode code, const std::string& message, const Detail& detail) {
  google::rpc::Status status;
  status.set_code(code);
  status.set_message(message);
  status.add_details()->PackFrom(detail);
  return {code, message, status.SerializeAsString()};
}

}  // namespace

grpc::Status invalid_argument(const core::Violations& violations) {
  google::rpc::BadRequest bad_request;
  add_within_budget(
      bad_request, *bad_request.mutable_field_violations(), violations,
      [](const core::FieldViolation& v, auto& out) {
        out.set_field(truncated(v.field, kMaxFieldBytes));
        out.set_description(truncated(v.description, kMaxDescriptionBytes));
      },
      [](auto& out, const std::string& text) { out.set_description(text + ": mend these first"); });
  return with_details(grpc::StatusCode::INVALID_ARGUMENT, summary(violations), bad_request);
}

grpc::Status failed_precondition(const std::string& message, const std::vector<PreconditionViolation>& violations) {
  google::rpc::PreconditionFailure failure;
  add_within_budget(
      failure, *failure.mutable_violations(), violations,
      [](const PreconditionViolation& v, auto& out) {
        out.set_type(truncated(v.type, kMaxFieldBytes));
        out.set_subject(truncated(v.subject, kMaxFieldBytes));
        out.set_description(truncated(v.description, kMaxDescriptionBytes));
      },
      [](auto& out, const std::string& text) {
        out.set_type("LEFT_OUT");
        out.set_description(text);
      });
  return with_details(grpc::StatusCode::FAILED_PRECONDITION, truncated(message, kMaxStatusMessageBytes), failure);
}

grpc::Status bounded(const grpc::Status& status) {
  if (status.ok()) return status;
  const bool long_message = status.error_message().size() > kMaxStatusMessageBytes;
  const bool long_details = status.error_details().size() > kMaxStatusDetailsBytes;
  if (!long_message && !long_details) return status;
  return {status.error_code(), truncated(status.error_message(), kMaxStatusMessageBytes),
          long_details ? std::string() : status.error_details()};
}


std::string_view status_code_name(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK: return "OK";
    case grpc::StatusCode::CANCELLED: return "CANCELLED";
    case grpc::StatusCode::UNKNOWN: return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED: return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND: return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS: return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED: return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED: return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION: return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED: return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE: return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED: return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL: return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE: return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS: return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED: return "UNAUTHENTICATED";
    default: return "UNKNOWN";
  }
}

grpc::Status status_of(const planner::Error& error) {
  switch (error.kind) {
    case planner::ErrorKind::kInvalidArgument: return invalid_argument(error.violations);
    case planner::ErrorKind::kUnattainable: {
      std::vector<PreconditionViolation> details;
      std::string message = "the path cannot be followed: ";
      for (std::size_t i = 0; i < error.violations.size(); ++i) {
        details.push_back({"TIME_OPTIMAL", error.violations[i].field, error.violations[i].description});
        message += (i ? "; " : "") + error.violations[i].description;
      }
      return failed_precondition(message, details);
    }
    case planner::ErrorKind::kRobotCannotFollow: {
      // The first broken limit (time, sample, joint) in the message and every one in the details.
      std::vector<PreconditionViolation> details;
      for (const auto& v : error.limits) {
        const bool per_joint = v.kind != core::LimitKind::kIk && v.kind != core::LimitKind::kBranch;
        v1::LimitEvent event;
        to_proto(v, event);
        details.push_back({v1::LimitKind_Name(event.kind()),
                           per_joint ? "joint " + std::to_string(v.joint) : "sample " + std::to_string(v.sample),
                           describe(v)});
      }
      std::string message = "robot '" + error.robot + "' cannot follow the plan: " +
                            (error.limits.empty() ? std::string("a limit is broken") : describe(error.limits.front()));
      std::size_t named = 1;
      const auto blocking = std::find_if(error.limits.begin(), error.limits.end(), [](const core::LimitEvent& e) {
        return e.kind == core::LimitKind::kIk || e.kind == core::LimitKind::kBranch;
      });
      if (error.report_only && blocking != error.limits.end()) {
        // What reportOnly cannot let through, and the joint held at its limit just before.
        message = "robot '" + error.robot + "' cannot follow the plan, even with robot.reportOnly (which streams " +
                  "broken joint limits, never a failed IK or a branch jump): " + describe(*blocking);
        const auto held = std::find_if(error.limits.begin(), blocking, [&](const core::LimitEvent& e) {
          return e.kind == core::LimitKind::kPosition && e.margin >= 0.0 && e.sample + 1 >= blocking->sample;
        });
        if (held != blocking) {
          message += ", after " + describe(*held);
          ++named;
        }
      }
      if (error.limits.size() > named) {
        message += "; and " + std::to_string(error.limits.size() - named) + " more in the PreconditionFailure details" +
                   (error.report_only ? "" : " (set robot.reportOnly for the full report)");
      }
      return failed_precondition(message, details);
    }
    case planner::ErrorKind::kStopped: return grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled");
    case planner::ErrorKind::kDeadlineExceeded:
      return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "the deadline passed before the work was done");
  }
  return grpc::Status(grpc::StatusCode::INTERNAL, "unknown planner error");
}

}  // namespace geotraj::server
