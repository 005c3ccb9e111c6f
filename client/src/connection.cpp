#include "connection.hpp"

#include <cstdlib>

#include <fstream>
#include <sstream>

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/support/channel_arguments.h>
#include <grpcpp/support/client_interceptor.h>

namespace geotraj::cli {
namespace {

// Adds `authorization: Bearer <token>` to every call of a channel, plaintext or TLS (call
// credentials would be refused on a plaintext channel, which local tests use).
class BearerToken final : public grpc::experimental::Interceptor {
 public:
  explicit BearerToken(const std::string& header) : header_(header) {}
  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(grpc::experimental::InterceptionHookPoints::PRE_SEND_INITIAL_METADATA)) {
      methods->GetSendInitialMetadata()->insert({"authorization", header_});
    }
    methods->Proceed();
  }

 private:
  const std::string& header_;
};

class BearerTokenFactory final : public grpc::experimental::ClientInterceptorFactoryInterface {
 public:
  explicit BearerTokenFactory(std::string token) : header_("Bearer " + std::move(token)) {}
  grpc::experimental::Interceptor* CreateClientInterceptor(grpc::experimental::ClientRpcInfo* /*info*/) override {
    return new BearerToken(header_);
  }

 private:
  std::string header_;
};

tl::expected<std::string, std::string> read_file(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return tl::unexpected("cannot read the " + std::string(what) + " \"" + path + "\"");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

tl::expected<std::shared_ptr<grpc::ChannelCredentials>, std::string> credentials(const ServerAddress& server) {
  if (!server.tls && server.ca_file.empty() && server.cert_file.empty() && server.key_file.empty()) {
    return grpc::InsecureChannelCredentials();
  }
  if (server.cert_file.empty() != server.key_file.empty()) {
    return tl::unexpected(std::string("a client certificate needs both --tls-cert and --tls-key"));
  }
  grpc::SslCredentialsOptions ssl;
  const std::pair<const std::string*, std::string*> files[] = {
      {&server.ca_file, &ssl.pem_root_certs}, {&server.cert_file, &ssl.pem_cert_chain}, {&server.key_file, &ssl.pem_private_key}};
  const char* names[] = {"CA file (--tls-ca)", "client certificate (--tls-cert)", "client key (--tls-key)"};
  for (std::size_t i = 0; i < 3; ++i) {
    if (files[i].first->empty()) continue;
    auto text = read_file(*files[i].first, names[i]);
    if (!text) return tl::unexpected(text.error());
    *files[i].second = std::move(*text);
  }
  return grpc::SslCredentials(ssl);
}

}  // namespace

tl::expected<Connection, std::string> connect(const ServerAddress& server) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);  // a dense AnalyzePath profile can be large
  std::vector<std::unique_ptr<grpc::experimental::ClientInterceptorFactoryInterface>> interceptors;
  if (!server.token.empty()) interceptors.push_back(std::make_unique<BearerTokenFactory>(server.token));
  Connection c;
  if (!server.address.empty()) {
    auto creds = credentials(server);
    if (!creds) return tl::unexpected(creds.error());
    c.channel = grpc::experimental::CreateCustomChannelWithInterceptors(server.address, *creds, args,
                                                                        std::move(interceptors));
    return c;
  }
  server::ServerOptions options;
  options.address.clear();  // in-process channels only: no port is opened
  // Its log lines only when asked (GEOTRAJ_LOG_LEVEL=info): the CLI's output is the answer.
  const char* level = std::getenv("GEOTRAJ_LOG_LEVEL");
  options.log_level = level != nullptr && *level != '\0' ? level : "warning";
  auto running = server::start_server(options);
  if (!running) return tl::unexpected(running.error());
  c.local = std::move(*running);
  c.channel = c.local->server->experimental().InProcessChannelWithInterceptors(args, std::move(interceptors));
  return c;
}

}  // namespace geotraj::cli
