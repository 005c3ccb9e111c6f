// The service as operators run it: bearer tokens, TLS and mutual TLS, the caps on calls in
// flight, the per-call limits, graceful drain, readiness, the health-only port, request
// ids, JSON logs, metrics over HTTP and the maximum connection age.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

#include <gmock/gmock.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/security/credentials.h>
#include <nlohmann/json.hpp>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "tests/server/support/production_support.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

// ---- Bearer tokens --------------------------------------------------------------------

class TokenTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("geotraj_tokens_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    std::ofstream(dir_ / "tokens") << "# operators\n"
                                   << "planner-token-0123456789 plan\n"
                                   << "\n"
                                   << "cell-token-0123456789abc plan,stream\n";
    server::ServerOptions options;
    options.auth_tokens_file = (dir_ / "tokens").string();
    options.auth_token = "environment-token-0123456789";
    running_ = start(options);
    stub_ = stub_to(running_.port);
  }
  void TearDown() override {
    server::stop_server(running_, std::chrono::seconds(1));
    std::filesystem::remove_all(dir_);
  }

  std::filesystem::path dir_;
  server::RunningServer running_;
  std::unique_ptr<v1::TrajectoryService::Stub> stub_;
};

TEST_F(TokenTest, RefusesCallsWithoutAValidToken) {
  auto missing = list_robots(*stub_);
  EXPECT_EQ(missing.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_THAT(missing.error_message(), HasSubstr("authorization: Bearer"));
  auto wrong = list_robots(*stub_, "planner-token-0123456780");
  EXPECT_EQ(wrong.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_THAT(wrong.error_message(), HasSubstr("not valid"));
  auto ctx = short_context();
  ctx->AddMetadata("authorization", "Basic planner-token-0123456789");
  v1::ListRobotsResponse response;
  EXPECT_EQ(stub_->ListRobots(ctx.get(), {}, &response).error_code(), grpc::StatusCode::UNAUTHENTICATED);
}

TEST_F(TokenTest, AcceptsTokensFromTheFileAndTheEnvironment) {
  EXPECT_TRUE(list_robots(*stub_, "planner-token-0123456789").ok());
  EXPECT_TRUE(list_robots(*stub_, "cell-token-0123456789abc").ok());
  EXPECT_TRUE(list_robots(*stub_, "environment-token-0123456789").ok());
}

TEST_F(TokenTest, ScopesLimitWhatATokenMayCall) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(0.05);
  std::size_t samples = 0;
  auto planner = short_context();
  planner->AddMetadata("authorization", "Bearer planner-token-0123456789");
  const auto denied = read_stream(*stub_, request, samples, *planner);
  EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_THAT(denied.error_message(), HasSubstr("scope `stream`"));
  EXPECT_EQ(samples, 0u);
  auto cell = short_context();
  cell->AddMetadata("authorization", "bearer cell-token-0123456789abc");  // the scheme is case-insensitive
  EXPECT_TRUE(read_stream(*stub_, request, samples, *cell).ok());
  EXPECT_EQ(samples, 6u);
  const auto exposition = server::metrics_exposition(running_);
  EXPECT_EQ(series(exposition, R"(geotraj_rpc_rejected_total{method="StreamSamples",reason="permission_denied"})"), 1);
}

TEST_F(TokenTest, HealthAndReflectionNeedNoToken) {
  EXPECT_EQ(health(running_.port, ""), HealthStatus::SERVING);
  EXPECT_EQ(health(running_.port, server::kReadinessService), HealthStatus::SERVING);
}

TEST(TokenFile, ErrorsNameTheFileAndLineButNotTheToken) {
  const auto path = std::filesystem::temp_directory_path() / ("geotraj_bad_tokens_" + std::to_string(::getpid()));
  std::ofstream(path) << "good-token-0123456789\nsecret-token-0123456789 plan,drive\n";
  server::ServerOptions options;
  options.address = "127.0.0.1:0";
  options.auth_tokens_file = path.string();
  auto started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), HasSubstr("line 2"));
  EXPECT_THAT(started.error(), HasSubstr("\"drive\""));
  EXPECT_THAT(started.error(), ::testing::Not(HasSubstr("secret-token")));
  std::ofstream(path) << "short\n";
  started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), HasSubstr("at least 16 characters"));
  std::filesystem::remove(path);
}

// ---- TLS --------------------------------------------------------------------------------

// A CA, a server certificate for 127.0.0.1 and a client certificate, made by openssl.
class TlsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::filesystem::temp_directory_path() / ("geotraj_tls_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    const std::string d = dir_.string();
    std::ofstream(dir_ / "server.ext") << "subjectAltName=IP:127.0.0.1,DNS:localhost\n";
    std::ofstream(dir_ / "client.ext") << "extendedKeyUsage=clientAuth\n";
    const std::string ec = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes ";
    const std::string script =
        "cd " + d + " && openssl req -x509" + ec + "-keyout ca.key -out ca.pem -days 2 -subj /CN=geotraj-test-ca" +
        " && openssl req" + ec + "-keyout server.key -out server.csr -subj /CN=localhost" +
        " && openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem -days 2"
        " -extfile server.ext" +
        " && openssl req" + ec + "-keyout client.key -out client.csr -subj /CN=cell-7" +
        " && openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out client.pem -days 2"
        " -extfile client.ext" +
        " && openssl req -x509" + ec + "-keyout other.key -out other.pem -days 2 -subj /CN=stranger";
    ASSERT_EQ(std::system((script + " > openssl.log 2>&1").c_str()), 0) << "openssl failed, see " << d;
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(dir_); }

  static std::string file(const std::string& name) {
    std::ifstream in(dir_ / name);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }
  static server::ServerOptions tls_options(bool mutual) {
    server::ServerOptions options;
    options.tls.cert_file = (dir_ / "server.pem").string();
    options.tls.key_file = (dir_ / "server.key").string();
    if (mutual) options.tls.client_ca_file = (dir_ / "ca.pem").string();
    return options;
  }
  static std::shared_ptr<grpc::ChannelCredentials> client(const std::string& cert = "", const std::string& key = "") {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = file("ca.pem");
    if (!cert.empty()) {
      ssl.pem_cert_chain = file(cert);
      ssl.pem_private_key = file(key);
    }
    return grpc::SslCredentials(ssl);
  }

  static std::filesystem::path dir_;
};
std::filesystem::path TlsTest::dir_;

TEST_F(TlsTest, ServesTlsAndNotPlaintext) {
  auto running = start(tls_options(false));
  EXPECT_TRUE(list_robots(*stub_to(running.port, client())).ok());
  // A plaintext client cannot talk to a TLS port.
  const auto plaintext = list_robots(*stub_to(running.port));
  EXPECT_EQ(plaintext.error_code(), grpc::StatusCode::UNAVAILABLE);
  server::stop_server(running, std::chrono::seconds(1));
}

TEST_F(TlsTest, MutualTlsNeedsACertificateTheCaSigned) {
  auto running = start(tls_options(true));
  EXPECT_TRUE(list_robots(*stub_to(running.port, client("client.pem", "client.key"))).ok());
  EXPECT_EQ(list_robots(*stub_to(running.port, client())).error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(list_robots(*stub_to(running.port, client("other.pem", "other.key"))).error_code(),
            grpc::StatusCode::UNAVAILABLE);
  server::stop_server(running, std::chrono::seconds(1));
}

TEST_F(TlsTest, TokensWorkOverTls) {
  auto options = tls_options(false);
  options.auth_token = "tls-token-0123456789abcdef";
  auto running = start(options);
  auto stub = stub_to(running.port, client());
  EXPECT_EQ(list_robots(*stub).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(list_robots(*stub, "tls-token-0123456789abcdef").ok());
  server::stop_server(running, std::chrono::seconds(1));
}

TEST_F(TlsTest, StartupErrorsNameTheFile) {
  auto options = tls_options(false);
  options.address = "127.0.0.1:0";
  options.tls.key_file = (dir_ / "missing.key").string();
  auto started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), HasSubstr("missing.key"));
  options = tls_options(false);
  options.address = "127.0.0.1:0";
  options.tls.key_file.clear();
  started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), HasSubstr("--tls-key"));
}

TEST_F(TlsTest, AKeyOfAnotherCertificateIsNamed) {
  auto options = tls_options(false);
  options.address = "127.0.0.1:0";
  options.tls.key_file = (dir_ / "other.key").string();
  const auto started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), HasSubstr("does not belong to the certificate"));
  EXPECT_THAT(started.error(), HasSubstr("other.key"));
}

// A self-signed certificate for localhost that expired a day ago, and its key (PEM files).
void write_expired_certificate(const std::filesystem::path& cert_file, const std::filesystem::path& key_file) {
  EVP_PKEY* key = EVP_EC_gen("P-256");
  X509* cert = X509_new();
  ASN1_INTEGER_set(X509_get_serialNumber(cert), 1);
  X509_gmtime_adj(X509_getm_notBefore(cert), -2 * 86400L);
  X509_gmtime_adj(X509_getm_notAfter(cert), -86400L);
  X509_set_pubkey(cert, key);
  X509_NAME* name = X509_get_subject_name(cert);
  X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC, reinterpret_cast<const unsigned char*>("localhost"), -1, -1, 0);
  X509_set_issuer_name(cert, name);
  X509_sign(cert, key, EVP_sha256());
  std::FILE* out = std::fopen(cert_file.c_str(), "w");
  PEM_write_X509(out, cert);
  std::fclose(out);
  out = std::fopen(key_file.c_str(), "w");
  PEM_write_PrivateKey(out, key, nullptr, nullptr, 0, nullptr, nullptr);
  std::fclose(out);
  X509_free(cert);
  EVP_PKEY_free(key);
}

TEST_F(TlsTest, AnExpiredCertificateIsAWarning) {
  write_expired_certificate(dir_ / "expired.pem", dir_ / "expired.key");
  const auto log_path = dir_ / "expired.log";
  std::FILE* log = std::fopen(log_path.c_str(), "w+");
  server::ServerOptions options;
  options.address = "127.0.0.1:0";
  options.tls.cert_file = (dir_ / "expired.pem").string();
  options.tls.key_file = (dir_ / "expired.key").string();
  options.log_output = log;
  options.log_level = "warning";
  auto started = server::start_server(options);
  ASSERT_TRUE(started) << started.error();  // it serves (an operator may be replacing it)
  server::stop_server(*started, std::chrono::seconds(1));
  *started = {};
  std::fflush(log);
  std::fclose(log);
  EXPECT_THAT(file("expired.log"), HasSubstr("expired on"));
  EXPECT_THAT(file("expired.log"), HasSubstr("expired.pem"));
}

// The CLI as an operator uses it: CA, client certificate and a token from the environment.
TEST_F(TlsTest, TheCliSpeaksMutualTlsWithAToken) {
  auto options = tls_options(true);
  options.auth_token = "cli-token-0123456789abcdef";
  auto running = start(options);
  const std::string cli = std::string(build_paths::cli()) + " --server 127.0.0.1:" + std::to_string(running.port) +
                          " --tls-ca " + (dir_ / "ca.pem").string() + " --tls-cert " + (dir_ / "client.pem").string() +
                          " --tls-key " + (dir_ / "client.key").string() + " robots";
  const auto run = [](const std::string& command) {
    std::string out;
    std::FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
    char buffer[4096];
    while (std::fgets(buffer, sizeof buffer, pipe)) out += buffer;
    return std::make_pair(::pclose(pipe), out);
  };
  const auto [denied, denied_out] = run(cli);
  EXPECT_NE(denied, 0);
  EXPECT_THAT(denied_out, HasSubstr("UNAUTHENTICATED"));
  const auto [ok, ok_out] = run("GEOTRAJ_TOKEN=cli-token-0123456789abcdef " + cli);
  EXPECT_EQ(ok, 0) << ok_out;
  EXPECT_THAT(ok_out, HasSubstr("pa10"));
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Plaintext, OnlyLoopbackWithoutTheFlag) {
  server::ServerOptions options;
  options.address = "0.0.0.0:0";
  auto refused = server::start_server(options);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error(), HasSubstr("--plaintext"));
  // A host name that merely starts like a loopback address is not one.
  options.address = "127.0.0.1.example.invalid:0";
  refused = server::start_server(options);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error(), HasSubstr("--plaintext"));
  options.address = "0.0.0.0:0";
  options.plaintext = true;
  auto running = server::start_server(options);
  ASSERT_TRUE(running) << running.error();
  EXPECT_TRUE(list_robots(*stub_to(running->port)).ok());
  server::stop_server(*running, std::chrono::seconds(1));
}

// ---- Caps and limits --------------------------------------------------------------------

TEST(Caps, StreamsBeyondTheCapAreResourceExhausted) {
  server::ServerOptions options;
  options.limits.max_streams = 2;
  auto running = start(options);
  auto stub = stub_to(running.port);
  const auto request = real_time_request(1.5);
  grpc::ClientContext c1, c2;
  auto r1 = stub->StreamSamples(&c1, request);
  auto r2 = stub->StreamSamples(&c2, request);
  v1::SampleBatch batch;
  ASSERT_TRUE(r1->Read(&batch));  // both streams are running
  ASSERT_TRUE(r2->Read(&batch));
  std::size_t samples = 0;
  auto ctx = short_context();
  const auto third = read_stream(*stub, request, samples, *ctx);
  EXPECT_EQ(third.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(third.error_message(), HasSubstr("--max-streams"));
  c1.TryCancel();
  while (r1->Read(&batch)) {
  }
  EXPECT_EQ(r1->Finish().error_code(), grpc::StatusCode::CANCELLED);
  // The slot is free again once the cancelled stream is done on the server.
  ASSERT_TRUE(eventually([&] { return series(server::metrics_exposition(running), "geotraj_active_streams") == 1; }));
  auto again = short_context();
  auto short_request = request;
  short_request.mutable_motion()->set_duration_s(0.05);
  EXPECT_TRUE(read_stream(*stub, short_request, samples, *again).ok());
  c2.TryCancel();
  while (r2->Read(&batch)) {
  }
  r2->Finish();
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Caps, UnaryCallsBeyondTheCapAreResourceExhausted) {
  server::ServerOptions options;
  options.limits.max_unary_calls = 1;
  auto running = start(options);
  auto stub = stub_to(running.port);
  // A breakpoint optimisation that runs for its whole budget keeps the one slot busy.
  auto slow = example<v1::PlanRequest>("appendix_b_optimized.json");
  slow.mutable_optimize()->set_time_budget_s(2.0);
  auto busy = std::async(std::launch::async, [&] {
    v1::PlanResponse response;
    return stub->PlanTrajectory(short_context().get(), slow, &response);
  });
  ASSERT_TRUE(
      eventually([&] { return series(server::metrics_exposition(running), "geotraj_active_unary_calls") == 1; }));
  const auto refused = list_robots(*stub);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("--max-unary-calls"));
  EXPECT_TRUE(busy.get().ok());
  EXPECT_TRUE(list_robots(*stub).ok());
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Limits, EachRefusalNamesItsLimit) {
  server::ServerOptions options;
  options.limits.max_frames = 3;
  options.limits.max_stream_samples = 100;
  options.limits.max_optimize_seconds = 0.5;
  options.max_receive_message_bytes = 4096;
  auto running = start(options);
  auto stub = stub_to(running.port);

  auto four_frames = demo_request('a');  // path A has 4 key frames
  v1::PlanResponse plan;
  auto status = stub->PlanTrajectory(short_context().get(), four_frames, &plan);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "path.frames"), HasSubstr("--max-frames"));

  auto three = demo_request('a');
  three.mutable_path()->mutable_frames()->DeleteSubrange(2, 1);
  three.mutable_motion()->set_duration_s(2.0);  // 201 samples at 100 Hz
  std::size_t samples = 0;
  auto ctx = short_context();
  status = read_stream(*stub, three, samples, *ctx);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "motion.durationS"), HasSubstr("--max-stream-samples"));
  // PlanTrajectory summarises the motion from its samples: bounded alike.
  status = stub->PlanTrajectory(short_context().get(), three, &plan);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "motion.durationS"), HasSubstr("--max-stream-samples"));
  three.mutable_motion()->set_duration_s(0.5);  // 51 samples
  ctx = short_context();
  EXPECT_TRUE(read_stream(*stub, three, samples, *ctx).ok());
  EXPECT_EQ(samples, 51u);

  auto optimise = three;
  optimise.mutable_optimize()->mutable_tangent_scales();
  optimise.mutable_optimize()->set_time_budget_s(5.0);
  status = stub->PlanTrajectory(short_context().get(), optimise, &plan);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "optimize.timeBudgetS"),
              HasSubstr("--max-optimize-seconds"));

  auto big = three;
  for (int i = 0; i < 1000; ++i) big.mutable_robot()->mutable_initial_joints()->Add(0.0);
  ASSERT_GT(big.ByteSizeLong(), 4096u);
  status = stub->PlanTrajectory(short_context().get(), big, &plan);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  server::stop_server(running, std::chrono::seconds(1));
}

// ---- Drain, readiness, the health port --------------------------------------------------

TEST(Drain, StreamsInFlightFinishWhileNewCallsAreRefused) {
  server::ServerOptions options;
  options.health_address = "127.0.0.1:0";
  auto running = start(options);
  ASSERT_GT(running.health_port, 0);
  auto stub = stub_to(running.port);
  const auto request = real_time_request(1.0);  // 101 samples over 1 s
  grpc::ClientContext context;
  auto reader = stub->StreamSamples(&context, request);
  v1::SampleBatch batch;
  ASSERT_TRUE(reader->Read(&batch));
  std::size_t samples = static_cast<std::size_t>(batch.samples_size());

  auto stopping = std::async(std::launch::async, [&] { server::stop_server(running, std::chrono::seconds(20)); });
  ASSERT_TRUE(eventually([&] { return health(running.health_port, server::kReadinessService) == HealthStatus::NOT_SERVING; }));
  EXPECT_EQ(health(running.port, ""), HealthStatus::NOT_SERVING);  // the main port still answers health
  const auto refused = list_robots(*stub);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_THAT(refused.error_message(), HasSubstr("shutting down"));

  while (reader->Read(&batch)) samples += static_cast<std::size_t>(batch.samples_size());
  EXPECT_TRUE(reader->Finish().ok());
  EXPECT_EQ(samples, 101u);
  EXPECT_EQ(stopping.wait_for(std::chrono::seconds(10)), std::future_status::ready);
}

TEST(Drain, TheDrainTimeEndsLongStreams) {
  auto running = start(server::ServerOptions{});
  auto stub = stub_to(running.port);
  grpc::ClientContext context;
  auto reader = stub->StreamSamples(&context, real_time_request(60.0));
  v1::SampleBatch batch;
  ASSERT_TRUE(reader->Read(&batch));
  const auto before = std::chrono::steady_clock::now();
  server::stop_server(running, std::chrono::milliseconds(300));
  // A stop that let the stream run would take its minute: 30 s leaves no room for doubt.
  EXPECT_LT(std::chrono::steady_clock::now() - before, std::chrono::seconds(30));
  while (reader->Read(&batch)) {
  }
  EXPECT_FALSE(reader->Finish().ok());
}

TEST(Health, ReadinessAndTheHealthOnlyPort) {
  server::ServerOptions options;
  options.health_address = "127.0.0.1:0";
  auto running = start(options);
  for (int port : {running.port, running.health_port}) {
    EXPECT_EQ(health(port, ""), HealthStatus::SERVING);
    EXPECT_EQ(health(port, server::kServiceName), HealthStatus::SERVING);
    EXPECT_EQ(health(port, server::kReadinessService), HealthStatus::SERVING);
  }
  // The health port serves health only.
  EXPECT_EQ(list_robots(*stub_to(running.health_port)).error_code(), grpc::StatusCode::UNIMPLEMENTED);
  server::stop_server(running, std::chrono::seconds(1));
}

// ---- Request ids, logs, metrics ---------------------------------------------------------

std::string http_get(int port, const std::string& path) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    ::close(fd);
    return "";
  }
  const std::string request = "GET " + path + " HTTP/1.1\r\nHost: localhost\r\n\r\n";
  (void)!::write(fd, request.data(), request.size());
  std::string response;
  char buffer[4096];
  for (ssize_t n; (n = ::read(fd, buffer, sizeof buffer)) > 0;) response.append(buffer, static_cast<std::size_t>(n));
  ::close(fd);
  return response;
}

TEST(Observability, RequestIdsLogsAndMetrics) {
  std::FILE* log = std::tmpfile();
  ASSERT_NE(log, nullptr);
  server::ServerOptions options;
  options.log_format = "json";
  options.log_output = log;
  options.metrics_address = "127.0.0.1:0";
  auto running = start(options);
  ASSERT_GT(running.metrics_port, 0);
  auto stub = stub_to(running.port);

  grpc::ClientContext given;
  given.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  given.AddMetadata("x-request-id", "cell7-run42.a");
  v1::PlanResponse plan;
  ASSERT_TRUE(stub->PlanTrajectory(&given, demo_request('a'), &plan).ok());
  EXPECT_EQ(given.GetServerInitialMetadata().find("x-request-id")->second, "cell7-run42.a");
  grpc::ClientContext fresh;
  fresh.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  auto bad = demo_request('a');
  bad.mutable_path()->mutable_frames(1)->set_curvature(-1.0);
  EXPECT_EQ(stub->PlanTrajectory(&fresh, bad, &plan).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto generated = fresh.GetServerInitialMetadata().find("x-request-id");
  ASSERT_NE(generated, fresh.GetServerInitialMetadata().end());
  const std::string generated_id(generated->second.data(), generated->second.size());
  EXPECT_EQ(generated_id.size(), 16u);
  auto stream = demo_request('a');
  stream.mutable_motion()->set_duration_s(1.0);
  std::size_t samples = 0;
  auto ctx = short_context();
  ASSERT_TRUE(read_stream(*stub, stream, samples, *ctx).ok());

  // The server records a stream when it is done with it, which may follow the client's end.
  ASSERT_TRUE(eventually([&] { return series(server::metrics_exposition(running), "geotraj_active_streams") == 0; }));
  const std::string response = http_get(running.metrics_port, "/metrics");
  EXPECT_THAT(response, HasSubstr("200 OK"));
  EXPECT_EQ(series(response, R"(geotraj_rpc_calls_total{method="PlanTrajectory",code="OK"})"), 1);
  EXPECT_EQ(series(response, R"(geotraj_rpc_calls_total{method="PlanTrajectory",code="INVALID_ARGUMENT"})"), 1);
  EXPECT_EQ(series(response, R"(geotraj_rpc_calls_total{method="StreamSamples",code="OK"})"), 1);
  EXPECT_EQ(series(response, "geotraj_samples_streamed_total"), 101);
  EXPECT_EQ(series(response, "geotraj_active_streams"), 0);
  server::stop_server(running, std::chrono::seconds(1));

  // One JSON object per line; each call's line carries its request id, method and code.
  std::rewind(log);
  std::vector<nlohmann::json> calls;
  char line[8192];
  while (std::fgets(line, sizeof line, log)) {
    const auto event = nlohmann::json::parse(line);
    if (event.at("msg") == "call") calls.push_back(event);
  }
  std::fclose(log);
  ASSERT_EQ(calls.size(), 3u);
  EXPECT_EQ(calls[0].at("request_id"), "cell7-run42.a");
  EXPECT_EQ(calls[0].at("method"), "PlanTrajectory");
  EXPECT_EQ(calls[0].at("code"), "OK");
  EXPECT_EQ(calls[1].at("request_id"), generated_id);
  EXPECT_EQ(calls[1].at("code"), "INVALID_ARGUMENT");
  EXPECT_THAT(calls[1].at("error").get<std::string>(), HasSubstr("path.frames[1].curvature"));
  EXPECT_EQ(calls[2].at("method"), "StreamSamples");
  EXPECT_EQ(calls[2].at("samples"), 101);
}

// ---- Malformed requests ------------------------------------------------------------------

// Bytes that are not a request are the service's INVALID_ARGUMENT, counted like any call.
TEST(Malformed, BytesThatAreNotARequestAreInvalidArgument) {
  auto running = start(server::ServerOptions{});
  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(running.port), grpc::InsecureChannelCredentials());
  grpc::GenericStub generic(channel);
  const char garbage[] = {'\x0a', '\x7f', '\x01'};  // field 1, length 127, one byte given
  grpc::Slice slice(garbage, sizeof garbage);
  const grpc::ByteBuffer bytes(&slice, 1);
  for (const char* method : {"/geotraj.v1.TrajectoryService/PlanTrajectory",
                             "/geotraj.v1.TrajectoryService/AnalyzePath",
                             "/geotraj.v1.TrajectoryService/ConvertConstraints"}) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    std::promise<grpc::Status> done;
    grpc::ByteBuffer response;
    generic.UnaryCall(&context, method, grpc::StubOptions(), &bytes, &response,
                      [&done](grpc::Status status) { done.set_value(std::move(status)); });
    const auto status = done.get_future().get();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << method;
    EXPECT_THAT(status.error_message(), HasSubstr("protobuf wire format")) << method;
    EXPECT_EQ(bad_request_violations(status).size(), 1u) << method;
  }
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  grpc::CompletionQueue queue;
  auto reader = generic.PrepareCall(&context, "/geotraj.v1.TrajectoryService/StreamSamples", &queue);
  reader->StartCall(reinterpret_cast<void*>(1));
  void* tag = nullptr;
  bool ok = false;
  ASSERT_TRUE(queue.Next(&tag, &ok));
  reader->Write(bytes, grpc::WriteOptions().set_last_message(), reinterpret_cast<void*>(2));
  ASSERT_TRUE(queue.Next(&tag, &ok));
  grpc::ByteBuffer batch;
  reader->Read(&batch, reinterpret_cast<void*>(3));
  ASSERT_TRUE(queue.Next(&tag, &ok));
  EXPECT_FALSE(ok);  // no batch
  grpc::Status status;
  reader->Finish(&status, reinterpret_cast<void*>(4));
  ASSERT_TRUE(queue.Next(&tag, &ok));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto exposition = server::metrics_exposition(running);
  EXPECT_EQ(series(exposition, R"(geotraj_rpc_calls_total{method="PlanTrajectory",code="INVALID_ARGUMENT"})"), 1);
  EXPECT_EQ(series(exposition, R"(geotraj_rpc_calls_total{method="StreamSamples",code="INVALID_ARGUMENT"})"), 1);
  // And the server goes on serving.
  EXPECT_TRUE(list_robots(*stub_to(running.port)).ok());
  queue.Shutdown();
  while (queue.Next(&tag, &ok)) {
  }
  server::stop_server(running, std::chrono::seconds(1));
}

// ---- Connections ------------------------------------------------------------------------

TEST(Connections, AStreamOutlivesTheMaximumConnectionAgeWithinItsGrace) {
  server::ServerOptions options;
  options.connections.max_connection_age_s = 0.5;
  options.connections.max_connection_age_grace_s = 10.0;
  auto running = start(options);
  auto stub = stub_to(running.port);
  std::size_t samples = 0;
  auto ctx = short_context();
  EXPECT_TRUE(read_stream(*stub, real_time_request(1.5), samples, *ctx).ok());
  EXPECT_EQ(samples, 151u);
  // The aged connection was closed; the channel reconnects for the next call.
  EXPECT_TRUE(list_robots(*stub).ok());
  server::stop_server(running, std::chrono::seconds(1));
}

}  // namespace
}  // namespace geotraj::testing
