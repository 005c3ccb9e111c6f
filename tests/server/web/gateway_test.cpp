// The JSON API over HTTP (--web-address) against the gRPC answers to the same requests,
// its errors (google.rpc.Status JSON with the field violations, HTTP statuses, unknown
// routes and methods, bodies too large or not JSON), its streams (newline-delimited JSON,
// a client that leaves midway), the bearer tokens and scopes, the drain, the loopback rule,
// and the page's files.
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/message_differencer.h>

#include "server/ops/runtime.hpp"
#include "server/web/gateway.hpp"
#include "tests/server/support/production_support.hpp"

// After Eigen: httplib.h brings <resolv.h>, whose `_res` macro breaks Eigen.
#include <httplib.h>

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;
using google::protobuf::util::MessageDifferencer;

// A google.rpc.Status read back from an error body.
google::rpc::Status status_from(const std::string& body) {
  google::rpc::Status status;
  EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(body, &status).ok()) << body;
  return status;
}

// The field violations of an error body's BadRequest.
std::vector<Violation> violations_from(const std::string& body) {
  const auto status = status_from(body);
  std::vector<Violation> out;
  for (const auto& any : status.details()) {
    google::rpc::BadRequest bad;
    if (any.UnpackTo(&bad)) {
      for (const auto& v : bad.field_violations()) out.push_back({v.field(), v.description()});
    }
  }
  return out;
}

template <class Message>
Message message_from(const std::string& json) {
  Message m;
  const auto parsed = google::protobuf::util::JsonStringToMessage(json, &m);
  EXPECT_TRUE(parsed.ok()) << parsed.message() << "\n" << json.substr(0, 400);
  return m;
}

// Whether two messages are equal, with their differences when they are not. Equivalent,
// not identical: proto3 JSON leaves a -0.0 out like a 0.0, which the binary form keeps.
::testing::AssertionResult same(const google::protobuf::Message& a, const google::protobuf::Message& b) {
  MessageDifferencer differ;
  differ.set_message_field_comparison(MessageDifferencer::EQUIVALENT);
  std::string report;
  differ.ReportDifferencesToString(&report);
  if (differ.Compare(a, b)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << report.substr(0, 2000);
}

std::string json_of(const google::protobuf::Message& m) {
  std::string out;
  EXPECT_TRUE(google::protobuf::util::MessageToJsonString(m, &out).ok());
  return out;
}

class Web : public ::testing::Test {
 protected:
  void SetUp() override { serve(server::ServerOptions{}); }
  void TearDown() override {
    if (running_.server) server::stop_server(running_, std::chrono::seconds(5));
  }

  void serve(server::ServerOptions options) {
    if (running_.server) server::stop_server(running_, std::chrono::seconds(5));
    options.web_address = "127.0.0.1:0";
    running_ = start(options);
    ASSERT_NE(running_.web_port, 0);
    stub_ = stub_to(running_.port);
    http_ = std::make_unique<httplib::Client>("127.0.0.1", running_.web_port);
    http_->set_read_timeout(60, 0);
  }

  httplib::Result post(const std::string& route, const std::string& body, const httplib::Headers& headers = {}) {
    return http_->Post(route.c_str(), headers, body, "application/json");
  }

  server::RunningServer running_;
  std::unique_ptr<v1::TrajectoryService::Stub> stub_;
  std::unique_ptr<httplib::Client> http_;
};

TEST_F(Web, EveryUnaryRouteAnswersWhatTheRpcAnswers) {
  using Stub = v1::TrajectoryService::Stub;
  // The route's answer to `request` as JSON, and the RPC's to the same request.
  const auto check = [&]<class Request, class Response>(const std::string& route, const Request& request,
                                                        grpc::Status (Stub::*rpc)(grpc::ClientContext*, const Request&,
                                                                                  Response*)) {
    SCOPED_TRACE(route);
    const auto res = post(route, json_of(request));
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json; charset=utf-8");
    Response expected;
    ASSERT_TRUE(((*stub_).*rpc)(short_context().get(), request, &expected).ok());
    EXPECT_TRUE(same(message_from<Response>(res->body), expected));
  };
  // The thesis's path C, and path C on the PA-10 timed time-optimally.
  check("/v1/plan", example<v1::PlanRequest>("plan_demo_path_c.json"), &Stub::PlanTrajectory);
  check("/v1/plan", example<v1::PlanRequest>("plan_pa10_path_c.json"), &Stub::PlanTrajectory);
  auto analyze = example<v1::PlanRequest>("plan_demo_path_c.json");
  analyze.set_analysis_points(200);
  check("/v1/analyze", analyze, &Stub::AnalyzePath);
  check("/v1/convert", example<v1::ConvertRequest>("convert_table_5_10.json"), &Stub::ConvertConstraints);
  check("/v1/fk", example<v1::ForwardKinematicsRequest>("fk_pa10.json"), &Stub::ComputeForwardKinematics);
  check("/v1/ik", example<v1::InverseKinematicsRequest>("ik_ur5_all.json"), &Stub::ComputeInverseKinematics);
  // Sent as they are to a client that takes brotli and gzip (compressing a large analysis
  // costs far more than sending it on loopback or a LAN).
  analyze.set_analysis_points(1001);
  http_->set_decompress(false);
  const auto big = post("/v1/analyze", json_of(analyze), {{"Accept-Encoding", "br, gzip, deflate"}});
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 200);
  EXPECT_EQ(big->get_header_value("Content-Encoding"), "");
  EXPECT_GT(big->body.size(), 100000u);
  // The example files themselves are bodies too.
  EXPECT_EQ(post("/v1/plan", example_text("plan_pa10_path_c.json"))->status, 200);
  {
    const auto res = http_->Get("/v1/robots");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    v1::ListRobotsResponse expected;
    ASSERT_TRUE(stub_->ListRobots(short_context().get(), v1::ListRobotsRequest{}, &expected).ok());
    const auto got = message_from<v1::ListRobotsResponse>(res->body);
    EXPECT_TRUE(same(got, expected));
    EXPECT_GE(got.robots_size(), 3);
  }
}

TEST_F(Web, ABadRequestIsTheRpcsErrorAsStatusJson) {
  // A curvature the thesis cannot give (negative): the same violation as over gRPC.
  auto request = example<v1::PlanRequest>("plan_demo_path_c.json");
  request.mutable_path()->mutable_frames(1)->set_curvature(-5.0);
  const auto res = post("/v1/plan", json_of(request));
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400);
  EXPECT_EQ(res->get_header_value("Content-Type"), "application/json; charset=utf-8");
  EXPECT_EQ(status_from(res->body).code(), 3);
  v1::PlanResponse unused;
  const auto rpc = stub_->PlanTrajectory(short_context().get(), request, &unused);
  ASSERT_EQ(rpc.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto over_http = violations_from(res->body);
  const auto over_grpc = bad_request_violations(rpc);
  ASSERT_FALSE(over_grpc.empty());
  ASSERT_EQ(over_http.size(), over_grpc.size());
  for (std::size_t i = 0; i < over_grpc.size(); ++i) {
    EXPECT_EQ(over_http[i].field, over_grpc[i].field);
    EXPECT_EQ(over_http[i].description, over_grpc[i].description);
  }
  EXPECT_NE(violation_of(over_http, "path.frames[1].curvature"), "");
  EXPECT_EQ(status_from(res->body).message(), rpc.error_message());
}

TEST_F(Web, BodiesThatAreNoRequestAreRefusedWithTheReason) {
  struct Case {
    std::string body;
    std::string says;
  };
  for (const auto& c : std::vector<Case>{
           {"", "empty"},
           {"   \n", "empty"},
           {"{\"path\": ", "not a geotraj.v1.PlanRequest in proto JSON"},
           {"[1, 2]", "not a geotraj.v1.PlanRequest"},
           {"{\"pathh\": {}}", "pathh"},                        // a misspelt field is no silent default
           {"{\"path\": {\"frames\": [{\"curvature\": \"a lot\"}]}}", "curvature"},
           {"{\"robot\": {\"name\": \"pa\xff" "10\"}}", "not valid UTF-8 (byte 22)"},
       }) {
    SCOPED_TRACE(c.body);
    const auto res = post("/v1/plan", c.body);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 400);
    const auto status = status_from(res->body);
    EXPECT_EQ(status.code(), 3);
    EXPECT_THAT(status.message(), HasSubstr(c.says));
  }
}

TEST_F(Web, RoutesAndMethodsOutsideTheApiAreNamed) {
  auto res = post("/v1/plans", "{}");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404);
  EXPECT_EQ(status_from(res->body).code(), 5);
  EXPECT_THAT(status_from(res->body).message(), HasSubstr("/v1/plan"));

  res = http_->Get("/v1/plan");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 405);
  EXPECT_EQ(res->get_header_value("Allow"), "POST");
  res = post("/v1/robots", "{}");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 405);
  EXPECT_EQ(res->get_header_value("Allow"), "GET");
}

TEST_F(Web, ABodyBeyondTheRequestLimitIs413) {
  server::ServerOptions options;
  options.max_receive_message_bytes = 64 * 1024;
  serve(options);
  const auto res = post("/v1/plan", "{\"path\": {\"frames\": []}, \"x\": \"" + std::string(100 * 1024, 'a') + "\"}");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 413);
  EXPECT_EQ(status_from(res->body).code(), 8);
  EXPECT_THAT(status_from(res->body).message(), HasSubstr("--max-request-bytes"));
  // The server serves on.
  EXPECT_EQ(post("/v1/plan", example_text("plan_demo_path_c.json"))->status, 200);
}

TEST_F(Web, AStreamIsOneSampleBatchPerLine) {
  auto request = example<v1::PlanRequest>("plan_demo_path_c.json");
  const auto res = post("/v1/stream", json_of(request));
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "application/x-ndjson");
  std::vector<v1::Sample> over_http;
  std::istringstream lines(res->body);
  std::string line;
  while (std::getline(lines, line)) {
    ASSERT_THAT(line, ::testing::Not(HasSubstr("\"error\"")));
    const auto batch = message_from<v1::SampleBatch>(line);
    for (const auto& s : batch.samples()) over_http.push_back(s);
  }
  auto context = short_context();
  auto reader = stub_->StreamSamples(context.get(), request);
  std::vector<v1::Sample> over_grpc;
  v1::SampleBatch batch;
  while (reader->Read(&batch)) {
    for (const auto& s : batch.samples()) over_grpc.push_back(s);
  }
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_EQ(over_http.size(), over_grpc.size());
  ASSERT_GT(over_grpc.size(), 100u);
  for (std::size_t k = 0; k < over_grpc.size(); k += 97) {
    EXPECT_TRUE(same(over_http[k], over_grpc[k])) << "sample " << k;
  }
  EXPECT_TRUE(same(over_http.back(), over_grpc.back()));
}

TEST_F(Web, AStreamRefusedBeforeItsFirstBatchHasItsHttpStatus) {
  auto request = example<v1::PlanRequest>("plan_demo_path_c.json");
  request.mutable_motion()->set_cycle_rate_hz(-1.0);
  const auto res = post("/v1/stream", json_of(request));
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400);
  EXPECT_NE(violation_of(violations_from(res->body), "motion.cycleRateHz"), "");
}

TEST_F(Web, AClientThatLeavesAStreamEndsItsCall) {
  // A long stream (a 600 s motion at 1 kHz) whose reader stops after its first bytes.
  auto request = example<v1::PlanRequest>("plan_demo_path_c.json");
  request.mutable_motion()->set_duration_s(600.0);
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  std::size_t received = 0;
  httplib::Request req;
  req.method = "POST";
  req.path = "/v1/stream";
  req.body = json_of(request);
  req.set_header("Content-Type", "application/json");
  req.content_receiver = [&](const char*, std::size_t n, std::uint64_t, std::uint64_t) {
    received += n;
    return false;
  };
  (void)http_->send(req);
  EXPECT_GT(received, 0u);
  EXPECT_TRUE(eventually([&] { return running_.runtime->calls_in_flight() == 0; }));
}

TEST_F(Web, TokensAndScopesAreTheGrpcPorts) {
  const auto dir = std::filesystem::temp_directory_path() / ("geotraj_web_tokens_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "tokens") << "planner-token-0123456789 plan\nall-token-0123456789\n";
  server::ServerOptions options;
  options.auth_tokens_file = (dir / "tokens").string();
  serve(options);
  const std::string body = example_text("plan_demo_path_c.json");

  auto res = post("/v1/plan", body);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 401);
  EXPECT_EQ(status_from(res->body).code(), 16);
  EXPECT_THAT(status_from(res->body).message(), HasSubstr("bearer token"));
  EXPECT_EQ(post("/v1/plan", body, {{"Authorization", "Bearer nobody"}})->status, 401);
  EXPECT_EQ(post("/v1/plan", body, {{"Authorization", "Bearer planner-token-0123456789"}})->status, 200);
  res = http_->Get("/v1/robots", {{"Authorization", "Bearer planner-token-0123456789"}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  // Streaming needs the `stream` scope.
  res = post("/v1/stream", body, {{"Authorization", "Bearer planner-token-0123456789"}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 403);
  EXPECT_EQ(status_from(res->body).code(), 7);
  EXPECT_EQ(post("/v1/stream", body, {{"Authorization", "Bearer all-token-0123456789"}})->status, 200);
  std::filesystem::remove_all(dir);
}

TEST_F(Web, RequestIdsAndTheClientsAddressAreLogged) {
  const auto log_path = std::filesystem::temp_directory_path() / ("geotraj_web_log_" + std::to_string(::getpid()));
  std::FILE* log = std::fopen(log_path.c_str(), "w+");
  ASSERT_NE(log, nullptr);
  server::ServerOptions options;
  options.log_output = log;
  options.log_level = "info";
  serve(options);
  auto res = post("/v1/plan", example_text("plan_demo_path_c.json"), {{"X-Request-Id", "cell-7.plan-42"}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("X-Request-Id"), "cell-7.plan-42");
  // Without one, the call's own id comes back; a refused call has one too.
  res = post("/v1/plan", "{\"path\": {}}");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400);
  EXPECT_FALSE(res->get_header_value("X-Request-Id").empty());
  // A gRPC client cannot pass for the web side: its peer is its own address.
  grpc::ClientContext context;
  context.AddMetadata("geotraj-web-peer", "10.9.9.9:1");
  v1::ListRobotsResponse robots;
  ASSERT_TRUE(stub_->ListRobots(&context, v1::ListRobotsRequest{}, &robots).ok());
  server::stop_server(running_, std::chrono::seconds(5));
  running_ = {};
  std::fflush(log);
  std::fclose(log);
  std::ifstream in(log_path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(text, HasSubstr("request_id=cell-7.plan-42"));
  EXPECT_THAT(text, HasSubstr("peer=web:127.0.0.1:"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("10.9.9.9")));
  std::filesystem::remove(log_path);
}

TEST_F(Web, ADrainingServerRefusesWith503) {
  server::begin_drain(running_);
  const auto res = post("/v1/plan", example_text("plan_demo_path_c.json"));
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 503);
  EXPECT_EQ(status_from(res->body).code(), 14);
}

TEST_F(Web, ThePageIsServedFromTheWebRoot) {
  // No page installed: the API serves, GET / says where the page was looked for.
  auto res = http_->Get("/");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 503);
  EXPECT_THAT(res->body, HasSubstr("--web-root"));

  const auto root = std::filesystem::temp_directory_path() / ("geotraj_web_root_" + std::to_string(::getpid()));
  std::filesystem::create_directories(root);
  std::ofstream(root / "index.html") << "<!doctype html><title>geotraj</title><script src=\"app.js\"></script>";
  std::ofstream(root / "app.js") << "console.log('geotraj');";
  server::ServerOptions options;
  options.web_root = root.string();
  serve(options);
  res = http_->Get("/");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_THAT(res->get_header_value("Content-Type"), HasSubstr("text/html"));
  EXPECT_THAT(res->body, HasSubstr("<title>geotraj</title>"));
  EXPECT_THAT(res->get_header_value("Content-Security-Policy"), HasSubstr("default-src 'self'"));
  http_->set_decompress(false);
  res = http_->Get("/app.js", {{"Accept-Encoding", "br, gzip"}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_THAT(res->get_header_value("Content-Type"), HasSubstr("javascript"));
  EXPECT_EQ(res->get_header_value("Content-Encoding"), "");
  EXPECT_EQ(res->body, "console.log('geotraj');");
  EXPECT_EQ(http_->Get("/../../etc/passwd")->status, 404);
  std::filesystem::remove_all(root);
}

TEST_F(Web, ManyCallsOfEveryKindAtOnceSomeLeftMidway) {
  // 4 rounds of 8 clients at once, each on its own connection: plans, analyses, FK,
  // robots, a bad request, a whole stream and a stream left after its first bytes.
  const std::string plan = example_text("plan_demo_path_c.json");
  auto long_stream = example<v1::PlanRequest>("plan_demo_path_c.json");
  long_stream.mutable_motion()->set_duration_s(300.0);
  long_stream.mutable_motion()->set_cycle_rate_hz(1000.0);
  const std::string long_body = json_of(long_stream);
  std::atomic<int> failures{0};
  for (int round = 0; round < 4; ++round) {
    std::vector<std::thread> clients;
    for (int k = 0; k < 8; ++k) {
      clients.emplace_back([&, k] {
        httplib::Client client("127.0.0.1", running_.web_port);
        client.set_read_timeout(60, 0);
        const auto expect = [&](const httplib::Result& res, int status) {
          if (!res || res->status != status) failures.fetch_add(1);
        };
        switch (k) {
          case 0: expect(client.Post("/v1/plan", plan, "application/json"), 200); break;
          case 1: expect(client.Post("/v1/analyze", plan, "application/json"), 200); break;
          case 2: expect(client.Post("/v1/fk", example_text("fk_pa10.json"), "application/json"), 200); break;
          case 3: expect(client.Get("/v1/robots"), 200); break;
          case 4: expect(client.Post("/v1/plan", "{\"path\": 3}", "application/json"), 400); break;
          case 5: expect(client.Post("/v1/stream", plan, "application/json"), 200); break;
          default: {
            httplib::Request req;
            req.method = "POST";
            req.path = "/v1/stream";
            req.body = long_body;
            req.set_header("Content-Type", "application/json");
            req.content_receiver = [](const char*, std::size_t, std::uint64_t, std::uint64_t) { return false; };
            (void)client.send(req);
          }
        }
      });
    }
    for (auto& c : clients) c.join();
  }
  EXPECT_EQ(failures.load(), 0);
  EXPECT_TRUE(eventually([&] { return running_.runtime->calls_in_flight() == 0; }));
  // And it serves on.
  EXPECT_EQ(post("/v1/plan", plan)->status, 200);
}

TEST(WebPool, ConnectionsBeyondThePoolWaitAndAreServed) {
  // 2 threads, 2 queued connections: 8 silent connections fill the threads, the queue and the
  // accepting thread; each is closed after the idle timeout (1 s), and a plan that arrives
  // behind them is answered.
  server::ServerOptions options;
  options.address = "";
  auto running = start(options);
  ASSERT_TRUE(running.server);
  server::WebOptions web;
  web.address = "127.0.0.1:0";
  web.threads = 2;
  web.max_queued_connections = 2;
  web.idle_timeout = std::chrono::seconds(1);
  auto gateway = server::WebGateway::start(web, running.server->InProcessChannel(grpc::ChannelArguments{}));
  ASSERT_TRUE(gateway) << gateway.error();
  const int port = (*gateway)->port();
  std::vector<int> silent;
  for (int k = 0; k < 8; ++k) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    silent.push_back(fd);
  }
  std::vector<std::thread> clients;
  std::atomic<int> answered{0};
  for (int k = 0; k < 6; ++k) {
    clients.emplace_back([&] {
      httplib::Client client("127.0.0.1", port);
      client.set_read_timeout(60, 0);
      client.set_connection_timeout(60, 0);
      const auto res = client.Post("/v1/plan", example_text("plan_demo_path_c.json"), "application/json");
      if (res && res->status == 200) answered.fetch_add(1);
    });
  }
  for (auto& c : clients) c.join();
  EXPECT_EQ(answered.load(), 6);
  for (const int fd : silent) ::close(fd);
  (*gateway)->stop();
  server::stop_server(running, std::chrono::seconds(5));
}

TEST(WebTls, TheWebPortSpeaksHttpsWithTheGrpcPortsCertificate) {
  const auto dir = std::filesystem::temp_directory_path() / ("geotraj_web_tls_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string d = dir.string();
  ASSERT_EQ(std::system(("cd " + d +
                         " && openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -keyout "
                         "server.key -out server.pem -days 2 -subj /CN=localhost -addext subjectAltName=IP:127.0.0.1"
                         " > openssl.log 2>&1")
                            .c_str()),
            0);
  server::ServerOptions options;
  options.address = "127.0.0.1:0";
  options.web_address = "127.0.0.1:0";
  options.tls.cert_file = d + "/server.pem";
  options.tls.key_file = d + "/server.key";
  auto running = start(options);
  ASSERT_NE(running.web_port, 0);

  httplib::SSLClient https("127.0.0.1", running.web_port);
  https.set_ca_cert_path((d + "/server.pem").c_str());
  https.enable_server_certificate_verification(true);
  const auto res = https.Get("/v1/robots");
  ASSERT_TRUE(res) << httplib::to_string(res.error());
  EXPECT_EQ(res->status, 200);
  // Plain HTTP gets no answer from it.
  httplib::Client http("127.0.0.1", running.web_port);
  http.set_read_timeout(5, 0);
  const auto plain = http.Get("/v1/robots");
  EXPECT_TRUE(!plain || plain->status != 200);
  server::stop_server(running, std::chrono::seconds(5));
  std::filesystem::remove_all(dir);
}

TEST(WebStart, PlaintextOnAPublicAddressIsRefused) {
  server::ServerOptions options;
  options.address = "127.0.0.1:0";
  options.web_address = "0.0.0.0:0";
  const auto started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), HasSubstr("web address \"0.0.0.0:0\""));
  EXPECT_THAT(started.error(), HasSubstr("--tls-cert"));
}

TEST(WebStart, ABadWebAddressIsNamed) {
  for (const char* address : {"127.0.0.1", "127.0.0.1:99999", "[::1:80"}) {
    server::ServerOptions options;
    options.address = "127.0.0.1:0";
    options.web_address = address;
    const auto started = server::start_server(options);
    ASSERT_FALSE(started) << address;
    EXPECT_THAT(started.error(), HasSubstr(std::string("web address \"") + address + "\""));
  }
}

TEST(WebStatus, CodesMapToTheirHttpStatus) {
  EXPECT_EQ(server::http_status(grpc::StatusCode::OK), 200);
  EXPECT_EQ(server::http_status(grpc::StatusCode::INVALID_ARGUMENT), 400);
  EXPECT_EQ(server::http_status(grpc::StatusCode::FAILED_PRECONDITION), 400);
  EXPECT_EQ(server::http_status(grpc::StatusCode::UNAUTHENTICATED), 401);
  EXPECT_EQ(server::http_status(grpc::StatusCode::PERMISSION_DENIED), 403);
  EXPECT_EQ(server::http_status(grpc::StatusCode::NOT_FOUND), 404);
  EXPECT_EQ(server::http_status(grpc::StatusCode::RESOURCE_EXHAUSTED), 429);
  EXPECT_EQ(server::http_status(grpc::StatusCode::CANCELLED), 499);
  EXPECT_EQ(server::http_status(grpc::StatusCode::INTERNAL), 500);
  EXPECT_EQ(server::http_status(grpc::StatusCode::UNAVAILABLE), 503);
  EXPECT_EQ(server::http_status(grpc::StatusCode::DEADLINE_EXCEEDED), 504);
  // A status without details still has its code and message.
  const auto status = status_from(server::status_json(grpc::Status(grpc::StatusCode::NOT_FOUND, "no \"robot\"")));
  EXPECT_EQ(status.code(), 5);
  EXPECT_EQ(status.message(), "no \"robot\"");
}

}  // namespace
}  // namespace geotraj::testing
