// The status-mapping file (see status.hpp).
#include "status.hpp"

#include <cstddef>

#include "google/rpc/error_details.pb.h"
#include "google/rpc/status.pb.h"

namespace geotraj::server {
namespace {

// The message lists this many violations; the details always hold all of them.
constexpr std::size_t kViolationsInMessage = 5;

std::string summary(const core::Violations& violations) {
  std::string message = "invalid request: " + std::to_string(violations.size()) +
                         (violations.size() == 1 ? " problem" : " problems");
  for (std::size_t i = 0; i < violations.size() && i < kViolationsInMessage; ++i) {
    // An empty field is the request as a whole (bytes that are no request).
    const std::string& field = violations[i].field;
    message += (i == 0 ? ": " : "; ") + (field.empty() ? "" : field + ": ") + violations[i].description;
  }
  if (violations.size() > kViolationsInMessage) {
    message += "; and " + std::to_string(violations.size() - kViolationsInMessage) +
               " more in the BadRequest details";
  }
  return message;
}

}  // namespace

grpc::Status invalid_argument(const core::Violations& violations) {
  google::rpc::BadRequest bad_request;
  for (const auto& v : violations) {
    auto* fv = bad_request.add_field_violations();
    fv->set_field(v.field);
    fv->set_description(v.description);
  }
  google::rpc::Status status;
  status.set_code(grpc::StatusCode::INVALID_ARGUMENT);
  status.set_message(summary(violations));
  status.add_details()->PackFrom(bad_request);
  return {grpc::StatusCode::INVALID_ARGUMENT, status.message(), status.SerializeAsString()};
}

grpc::Status failed_precondition(const std::string& message, const std::vector<PreconditionViolation>& violations) {
  google::rpc::PreconditionFailure failure;
  for (const auto& v : violations) {
    auto* out = failure.add_violations();
    out->set_type(v.type);
    out->set_subject(v.subject);
    out->set_description(v.description);
  }
  google::rpc::Status status;
  status.set_code(grpc::StatusCode::FAILED_PRECONDITION);
  status.set_message(message);
  status.add_details()->PackFrom(failure);
  return {grpc::StatusCode::FAILED_PRECONDITION, message, status.SerializeAsString()};
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

}  // namespace geotraj::server
