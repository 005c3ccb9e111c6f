// The CLI is a gRPC client: to a server at --server, or to a service it starts in process.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <grpcpp/channel.h>
#include <tl/expected.hpp>

#include "server/server.hpp"

namespace geotraj::cli {

/// How to reach a server: its address, TLS, a bearer token.
struct ServerAddress {
  std::string address;  ///< HOST:PORT; empty: a service started in this process
  bool tls = false;     ///< TLS (implied by any of the files below)
  std::string ca_file;  ///< CA certificates that sign the server's certificate (PEM); empty: the system's
  std::string cert_file;  ///< client certificate for mutual TLS (PEM)
  std::string key_file;   ///< its private key (PEM)
  std::string token;      ///< bearer token sent as `authorization: Bearer ...` on every call
};

struct Connection {
  std::optional<server::RunningServer> local;  ///< the in-process service, without --server
  std::shared_ptr<grpc::Channel> channel;      ///< declared last: released before `local`
};

/// A channel to `server.address` (plaintext, or TLS), or, when the address is empty, to a
/// service started in this process. Error: a file that cannot be read, or why the
/// in-process service could not start.
tl::expected<Connection, std::string> connect(const ServerAddress& server);

}  // namespace geotraj::cli
