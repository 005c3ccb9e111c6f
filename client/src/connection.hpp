// The CLI is a gRPC client: to a server at --server, or to a service it starts in process.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <grpcpp/channel.h>
#include <tl/expected.hpp>

#include "geotraj/server/server.hpp"

namespace geotraj::cli {

struct Connection {
  std::optional<server::RunningServer> local;  ///< the in-process service, without --server
  std::shared_ptr<grpc::Channel> channel;      ///< declared last: released before `local`
};

/// A channel to `server` (HOST:PORT, plaintext), or, when it is empty, to a service started
/// in this process. Error: why the in-process service could not start.
tl::expected<Connection, std::string> connect(const std::string& server);

}  // namespace geotraj::cli
