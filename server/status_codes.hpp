// The canonical names of gRPC status codes, shared by geotrajd (logs, metrics labels) and the
// geotraj CLI (its error lines), so that both spell a code the same way.
#pragma once

#include <string_view>

#include <grpcpp/support/status.h>

namespace geotraj::server {

/// The canonical name of a status code ("OK", "INVALID_ARGUMENT", ...), as gRPC documents it;
/// "UNKNOWN" for a value outside the 17 codes.
std::string_view status_code_name(grpc::StatusCode code);

}  // namespace geotraj::server
