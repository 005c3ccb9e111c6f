#include "connection.hpp"

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>

namespace geotraj::cli {

tl::expected<Connection, std::string> connect(const std::string& server) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);  // a dense AnalyzePath profile can be large
  Connection c;
  if (!server.empty()) {
    c.channel = grpc::CreateCustomChannel(server, grpc::InsecureChannelCredentials(), args);
    return c;
  }
  server::ServerOptions options;
  options.address.clear();  // in-process channels only: no port is opened
  auto running = server::start_server(options);
  if (!running) return tl::unexpected(running.error());
  c.local = std::move(*running);
  c.channel = c.local->server->InProcessChannel(args);
  return c;
}

}  // namespace geotraj::cli
