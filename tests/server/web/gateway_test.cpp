// The JSON API over HTTP (--web-address) against the gRPC answers to the same requests,
// its errors (google.rpc.Status JSON with the field violations, HTTP statuses, unknown
// routes and methods, bodies too large or not JSON), its streams (newline-delimited JSON,
// a client that leaves midway), the bearer tokens and scopes, the drain, the loopback rule,
// the page's files, and what one client may take (deadlines, sizes, connections, streams,
// ranges, pipelining, header bytes gRPC cannot carry), with raw sockets where no
// well-behaved client would do it.
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string_view>
#include <thread>

#include <arpa/inet.h>
#include <poll.h>
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

// A raw connection to the web port, for what no well-behaved client sends: bytes of any
// kind in a header, a head sent a byte at a time, two requests at once. Closed with it.
class Raw {
 public:
  explicit Raw(int port) : fd_(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  }
  ~Raw() { ::close(fd_); }
  Raw(const Raw&) = delete;
  Raw& operator=(const Raw&) = delete;

  bool connected() const { return connected_; }
  // Shuts the writing side: the request is whole, the answer still wanted.
  void half_close() { ::shutdown(fd_, SHUT_WR); }
  // Whether every byte went out (false once the server closed the connection).
  bool send(std::string_view bytes) {
    while (!bytes.empty()) {
      const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
      if (n <= 0) return false;
      bytes.remove_prefix(static_cast<std::size_t>(n));
    }
    return true;
  }
  // What arrives until the server closes the connection, or `within` passes.
  std::string read_all(std::chrono::milliseconds within = std::chrono::seconds(30)) {
    std::string out;
    const auto until = std::chrono::steady_clock::now() + within;
    char buffer[65536];
    while (std::chrono::steady_clock::now() < until) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
      if (n <= 0) break;
      out.append(buffer, static_cast<std::size_t>(n));
    }
    return out;
  }
  // What arrives first (within `within`): empty when nothing did.
  std::string read_some(std::chrono::milliseconds within) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(within.count())) <= 0) return "";
    char buffer[65536];
    const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
    return n <= 0 ? "" : std::string(buffer, static_cast<std::size_t>(n));
  }
  // Whether the server closed the connection (within `within`), reading what it sent first.
  bool closed_within(std::chrono::milliseconds within) {
    const auto until = std::chrono::steady_clock::now() + within;
    char buffer[65536];
    while (std::chrono::steady_clock::now() < until) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
      if (n <= 0) return true;
    }
    return false;
  }

 private:
  int fd_;
  bool connected_ = false;
};

// The status of an HTTP/1.1 answer's first line (0 when there is none).
int status_of(const std::string& answer) {
  if (!answer.starts_with("HTTP/1.1 ") || answer.size() < 12) return 0;
  return std::atoi(answer.substr(9, 3).c_str());
}

// The value of a header of the first answer in `answer` ("" when absent).
std::string header_of(const std::string& answer, const std::string& name) {
  const std::size_t end = answer.find("\r\n\r\n");
  std::istringstream lines(answer.substr(0, end));
  std::string line;
  while (std::getline(lines, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string key = line.substr(0, colon);
    std::transform(key.begin(), key.end(), key.begin(), [](unsigned char c) { return std::tolower(c); });
    std::string want = name;
    std::transform(want.begin(), want.end(), want.begin(), [](unsigned char c) { return std::tolower(c); });
    if (key == want) return line.substr(line.find_first_not_of(' ', colon + 1));
  }
  return "";
}

// The body of the first answer in `answer` (by its Content-Length).
std::string body_of(const std::string& answer) {
  const std::size_t end = answer.find("\r\n\r\n");
  if (end == std::string::npos) return "";
  const std::string length = header_of(answer, "Content-Length");
  if (length.empty()) return answer.substr(end + 4);
  return answer.substr(end + 4, std::stoul(length));
}

// One request on its own connection, closed after the answer; the whole answer.
std::string round_trip(int port, const std::string& request) {
  Raw raw(port);
  if (!raw.connected() || !raw.send(request)) return "";
  return raw.read_all();
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

TEST_F(Web, HeaderBytesThatGrpcMetadataCannotCarryAreRefusedAndTheServerLives) {
  // A tab, control bytes, DEL, bytes above 0x7f and UTF-8 in X-Request-Id or Authorization,
  // with and without a tokens file: gRPC aborts the process on such metadata, so the
  // gateway checks them first. A bad Authorization is 400 naming the header; a request id
  // the service would not take is left out (the call gets an id of its own, as over gRPC).
  const auto dir = std::filesystem::temp_directory_path() / ("geotraj_web_bytes_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "tokens") << "all-token-0123456789\n";
  for (const bool with_tokens : {false, true}) {
    server::ServerOptions options;
    if (with_tokens) options.auth_tokens_file = (dir / "tokens").string();
    serve(options);
    const int port = running_.web_port;
    const std::string token = with_tokens ? "Authorization: Bearer all-token-0123456789\r\n" : "";
    const auto robots = [&](const std::string& headers) {
      return round_trip(port, "GET /v1/robots HTTP/1.1\r\nHost: t\r\nConnection: close\r\n" + headers + "\r\n");
    };
    for (const std::string bad : {"a\tb", "a\x01" "b", "a\x7f" "b", "a\x80" "b", "a\xff" "b", "caf\xc3\xa9"}) {
      SCOPED_TRACE(::testing::PrintToString(bad) + (with_tokens ? " with a tokens file" : " without tokens"));
      // Authorization: 400 naming the header (HTTP itself forbids \x01 and \x7f in a
      // field value: the answer may be the parser's 400).
      std::string answer = robots("Authorization: Bearer " + bad + "\r\n");
      EXPECT_EQ(status_of(answer), 400) << answer;
      if (bad.find_first_of("\x01\x7f") == std::string::npos) {
        EXPECT_THAT(status_from(body_of(answer)).message(), HasSubstr("Authorization")) << answer;
      }
      // X-Request-Id: the call is served under an id of its own.
      answer = robots(token + "X-Request-Id: " + bad + "\r\n");
      const int status = status_of(answer);
      if (bad.find_first_of("\x01\x7f") == std::string::npos) {
        EXPECT_EQ(status, 200) << answer;
      } else {
        EXPECT_TRUE(status == 200 || status == 400) << answer;
      }
      if (status == 200) {
        EXPECT_FALSE(header_of(answer, "X-Request-Id").empty());
        EXPECT_EQ(header_of(answer, "X-Request-Id").find(bad), std::string::npos);
      }
      // And the server still answers, on both ports.
      EXPECT_EQ(status_of(robots(token)), 200);
      EXPECT_TRUE(list_robots(*stub_, with_tokens ? "all-token-0123456789" : "").ok());
    }
  }
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

TEST(WebPool, SilentConnectionsHoldNoCallThread) {
  // 2 call threads, 4 calls queued: 8 connections that send nothing hold no call thread
  // (they are read without one), and 6 plans that arrive beside them are answered.
  server::ServerOptions options;
  options.address = "";
  auto running = start(options);
  ASSERT_TRUE(running.server);
  server::WebOptions web;
  web.address = "127.0.0.1:0";
  web.threads = 2;
  web.max_queued_calls = 4;
  web.idle_timeout = std::chrono::seconds(30);
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

// A gateway of its own on a server without a gRPC port, with the web options a test needs.
struct Gateway {
  explicit Gateway(server::WebOptions web, server::ServerOptions options = {}) {
    options.address = "";
    running = start(options);
    web.address = "127.0.0.1:0";
    auto started = server::WebGateway::start(web, running.server->InProcessChannel(grpc::ChannelArguments{}));
    EXPECT_TRUE(started) << started.error();
    if (started) gateway = std::move(*started);
  }
  ~Gateway() {
    if (gateway) gateway->stop();
    server::stop_server(running, std::chrono::seconds(5));
  }
  int port() const { return gateway->port(); }
  int plan() const {
    const std::string body = example_text("plan_demo_path_c.json");
    return status_of(round_trip(port(), "POST /v1/plan HTTP/1.1\r\nHost: t\r\nConnection: close\r\nContent-Length: " +
                                            std::to_string(body.size()) + "\r\n\r\n" + body));
  }
  server::RunningServer running;
  std::unique_ptr<server::WebGateway> gateway;
};

// Sends `head` a byte at a time, one every `every`, until the server closes the
// connection or `bytes` were sent; how many were sent.
std::size_t trickle(Raw& raw, const std::string& head, std::size_t bytes, std::chrono::milliseconds every) {
  for (std::size_t k = 0; k < bytes; ++k) {
    if (!raw.send(std::string(1, head[k % head.size()]))) return k;
    if (raw.closed_within(every)) return k + 1;
  }
  return bytes;
}

TEST(WebLimits, AHeadThatTricklesIsCutAtItsDeadlineWhileOthersAreServed) {
  // A head sent a byte every 100 ms (never silent for the idle timeout): the connection is
  // closed at the header deadline (1 s), long before 100 bytes (10 s) went; a plan sent
  // meanwhile on another connection is answered.
  server::WebOptions web;
  web.header_timeout = std::chrono::seconds(1);
  Gateway g(web);
  std::atomic<int> planned{0};
  std::thread other([&] { planned = g.plan(); });
  Raw raw(g.port());
  ASSERT_TRUE(raw.connected());
  const std::size_t sent = trickle(raw, "GET /v1/robots HTTP/1.1\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa", 100,
                                   std::chrono::milliseconds(100));
  other.join();
  EXPECT_LT(sent, 100u) << "the trickling head was not cut";
  EXPECT_EQ(planned.load(), 200);
}

TEST(WebLimits, ABodyThatTricklesIsCutAtTheRequestDeadline) {
  server::WebOptions web;
  web.request_timeout = std::chrono::seconds(1);
  Gateway g(web);
  Raw raw(g.port());
  ASSERT_TRUE(raw.send("POST /v1/plan HTTP/1.1\r\nHost: t\r\nContent-Length: 100000\r\n\r\n"));
  EXPECT_LT(trickle(raw, "{", 100, std::chrono::milliseconds(100)), 100u);
}

TEST(WebLimits, AChunkedBodyBeyondTheLimitIs413) {
  // 100 KiB in chunks of 4 KiB against a 64 KiB limit: refused when the limit is passed,
  // not read whole; the answer names the flag.
  server::WebOptions web;
  web.max_request_bytes = 64 * 1024;
  Gateway g(web);
  Raw raw(g.port());
  ASSERT_TRUE(raw.send("POST /v1/plan HTTP/1.1\r\nHost: t\r\nTransfer-Encoding: chunked\r\n\r\n"));
  for (int k = 0; k < 25; ++k) {
    if (!raw.send("1000\r\n" + std::string(4096, ' ') + "\r\n")) break;
  }
  (void)raw.send("0\r\n\r\n");
  const std::string answer = raw.read_all();
  EXPECT_EQ(status_of(answer), 413) << answer.substr(0, 300);
  EXPECT_EQ(status_from(body_of(answer)).code(), 8);
  EXPECT_THAT(status_from(body_of(answer)).message(), HasSubstr("--max-request-bytes"));
  EXPECT_EQ(g.plan(), 200);
}

TEST(WebLimits, AChunkLineLongerThanTheReadBufferIs413) {
  // Beast bounds neither a chunk's size line (with extensions) nor the trailer: the read
  // buffer does, and the answer says so at once rather than after the idle timeout.
  server::WebOptions web;
  web.idle_timeout = std::chrono::seconds(60);
  web.request_timeout = std::chrono::seconds(60);
  Gateway g(web);
  for (const std::string& framing : {"1;" + std::string(200 * 1024, 'a'),
                                    "1\r\na\r\n0\r\nX-Trailer: " + std::string(200 * 1024, 'b')}) {
    Raw raw(g.port());
    ASSERT_TRUE(raw.send("POST /v1/plan HTTP/1.1\r\nHost: t\r\nTransfer-Encoding: chunked\r\n\r\n"));
    (void)raw.send(framing);
    const std::string answer = raw.read_all(std::chrono::seconds(20));
    EXPECT_EQ(status_of(answer), 413) << answer.substr(0, 300);
  }
  EXPECT_EQ(g.plan(), 200);
}

TEST(WebLimits, AHeadRequestGetsNoBodyAndTheNextAnswerIsIntact) {
  // An answer to HEAD without its body, on the API's routes too (a 405, a 404): a body
  // would be read as the start of the next answer on the kept-alive connection.
  Gateway g(server::WebOptions{});
  for (const auto& [path, status] : std::vector<std::pair<std::string, int>>{
           {"/v1/plan", 405}, {"/v1/nothing", 404}, {"/v1/robots", 405}, {"/", 503}}) {
    SCOPED_TRACE(path);
    const std::string answer = round_trip(
        g.port(), "HEAD " + path +
                      " HTTP/1.1\r\nHost: t\r\n\r\nGET /v1/robots HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n");
    const std::size_t first_end = answer.find("\r\n\r\n");
    ASSERT_NE(first_end, std::string::npos) << answer.substr(0, 300);
    EXPECT_EQ(status_of(answer), status);
    EXPECT_NE(header_of(answer, "Content-Length"), "0") << "the length of the body left out";
    const std::string second = answer.substr(first_end + 4);
    EXPECT_EQ(status_of(second), 200) << second.substr(0, 300);
    EXPECT_THAT(body_of(second), HasSubstr("\"robots\""));
  }
}

TEST(WebLimits, AnHttp10StreamIsOneLinePerBatchWithoutChunks) {
  Gateway g(server::WebOptions{});
  const std::string body = example_text("plan_demo_path_c.json");
  const std::string answer =
      round_trip(g.port(), "POST /v1/stream HTTP/1.0\r\nContent-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body);
  ASSERT_EQ(status_of(answer), 200) << answer.substr(0, 300);
  EXPECT_EQ(header_of(answer, "Transfer-Encoding"), "");
  std::istringstream lines(body_of(answer));
  int batches = 0;
  for (std::string line; std::getline(lines, line);) {
    ASSERT_TRUE(line.starts_with("{")) << "not a batch: " << line.substr(0, 80);
    EXPECT_GT(message_from<v1::SampleBatch>(line).samples_size(), 0);
    ++batches;
  }
  EXPECT_GT(batches, 1);
}

TEST(WebLimits, AHeadBeyondItsLimitIs431) {
  server::WebOptions web;
  web.max_header_bytes = 4096;
  Gateway g(web);
  const std::string answer =
      round_trip(g.port(), "GET /v1/robots HTTP/1.1\r\nHost: t\r\nX-Big: " + std::string(8000, 'a') + "\r\n\r\n");
  EXPECT_EQ(status_of(answer), 431) << answer.substr(0, 300);
}

TEST(WebLimits, PipelinedRequestsAreAnsweredInOrder) {
  server::WebOptions web;
  Gateway g(web);
  const std::string body = example_text("plan_demo_path_c.json");
  const std::string answer =
      round_trip(g.port(), "GET /v1/robots HTTP/1.1\r\nHost: t\r\n\r\n"
                           "POST /v1/plans HTTP/1.1\r\nHost: t\r\nContent-Length: 2\r\n\r\n{}"
                           "POST /v1/plan HTTP/1.1\r\nHost: t\r\nConnection: close\r\nContent-Length: " +
                               std::to_string(body.size()) + "\r\n\r\n" + body);
  // Three answers: 200 (the robots), 404 (no such route), 200 (the plan), in that order.
  std::vector<int> statuses;
  for (std::size_t at = answer.find("HTTP/1.1 "); at != std::string::npos; at = answer.find("HTTP/1.1 ", at + 1)) {
    statuses.push_back(status_of(answer.substr(at)));
  }
  EXPECT_EQ(statuses, (std::vector<int>{200, 404, 200})) << answer.substr(0, 2000);
  EXPECT_THAT(answer, HasSubstr("\"robots\""));
  EXPECT_THAT(answer, HasSubstr("\"frames\""));
}

TEST(WebLimits, AClientThatShutsItsWritingSideGetsItsAnswer) {
  server::WebOptions web;
  Gateway g(web);
  Raw raw(g.port());
  ASSERT_TRUE(raw.send("GET /v1/robots HTTP/1.1\r\nHost: t\r\n\r\n"));
  raw.half_close();
  const std::string answer = raw.read_all();
  EXPECT_EQ(status_of(answer), 200) << answer.substr(0, 300);
  EXPECT_THAT(answer, HasSubstr("\"robots\""));
}

TEST(WebLimits, ManyRangesNeverAmplifyAndNulPathsAreRefused) {
  const auto root = std::filesystem::temp_directory_path() / ("geotraj_web_range_" + std::to_string(::getpid()));
  std::filesystem::create_directories(root);
  std::ofstream(root / "index.html") << "<!doctype html><title>geotraj</title>";
  const std::string script(8241, 'x');
  std::ofstream(root / "app.js") << script;
  server::WebOptions web;
  web.root = root.string();
  Gateway g(web);
  std::string ranges = "bytes=0-";
  for (int k = 0; k < 2000; ++k) ranges += ",0-";
  std::string answer =
      round_trip(g.port(), "GET /app.js HTTP/1.1\r\nHost: t\r\nConnection: close\r\nRange: " + ranges + "\r\n\r\n");
  // Range is not honoured: the file once, whole, as it is.
  EXPECT_EQ(status_of(answer), 200);
  EXPECT_EQ(body_of(answer), script);
  EXPECT_LT(answer.size(), script.size() + 2000);
  EXPECT_THAT(header_of(answer, "Content-Type"), HasSubstr("javascript"));
  // A NUL (%00) in a path is refused, never served under another file's type.
  for (const char* path : {"/app.js%00.html", "/index.html%00", "/%00"}) {
    SCOPED_TRACE(path);
    answer = round_trip(g.port(), std::string("GET ") + path + " HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n");
    EXPECT_EQ(status_of(answer), 400);
    EXPECT_THAT(header_of(answer, "Content-Type"), HasSubstr("text/plain"));
  }
  // Nothing outside the root: dot segments, and absolute paths (`root / "/etc/passwd"` is
  // /etc/passwd), the root's own files named by their absolute path included.
  const std::string own = "/" + (root / "index.html").string();
  for (const std::string& path : {std::string("/../../etc/passwd"), std::string("/%2e%2e/%2e%2e/etc/passwd"),
                                 std::string("/..%2fapp.js"), std::string("/nothing.js"), std::string("//etc/passwd"),
                                 std::string("/%2Fetc/passwd"), std::string("/%2fetc%2fpasswd"), own}) {
    SCOPED_TRACE(path);
    answer = round_trip(g.port(), "GET " + path + " HTTP/1.1\r\nHost: t\r\nConnection: close\r\n\r\n");
    EXPECT_EQ(status_of(answer), 404) << answer.substr(0, 200);
    EXPECT_THAT(answer, ::testing::Not(HasSubstr("root:"))) << "a file outside the web root was served";
  }
  std::filesystem::remove_all(root);
}

TEST(WebLimits, ANewConnectionBeyondTheCapClosesTheOldestIdleOne) {
  server::WebOptions web;
  web.max_connections = 4;
  web.idle_timeout = std::chrono::seconds(60);
  web.header_timeout = std::chrono::seconds(60);
  Gateway g(web);
  std::vector<std::unique_ptr<Raw>> idle;
  for (int k = 0; k < 4; ++k) {
    idle.push_back(std::make_unique<Raw>(g.port()));
    ASSERT_TRUE(idle.back()->connected());
    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // accepted in this order
  }
  EXPECT_EQ(g.plan(), 200);  // the fifth
  EXPECT_TRUE(idle.front()->closed_within(std::chrono::seconds(10)));
  EXPECT_FALSE(idle.back()->closed_within(std::chrono::milliseconds(200)));
}

TEST(WebLimits, SlowClientsAndRealTimeStreamsLeaveThePortUsable) {
  // 16 clients trickling heads, 16 trickling bodies and 16 real-time streams whose
  // clients read nothing more after their first line: a plan is still answered.
  server::WebOptions web;
  web.idle_timeout = std::chrono::seconds(60);
  web.header_timeout = std::chrono::seconds(60);
  web.request_timeout = std::chrono::seconds(60);
  Gateway g(web);
  std::vector<std::unique_ptr<Raw>> slow;
  for (int k = 0; k < 16; ++k) {
    slow.push_back(std::make_unique<Raw>(g.port()));
    ASSERT_TRUE(slow.back()->send("GET /v1/robots HTTP/1.1\r\nHo"));
    slow.push_back(std::make_unique<Raw>(g.port()));
    ASSERT_TRUE(slow.back()->send("POST /v1/plan HTTP/1.1\r\nHost: t\r\nContent-Length: 1000\r\n\r\n{\"pa"));
  }
  auto request = real_time_request(60.0);
  const std::string body = json_of(request);
  std::vector<std::unique_ptr<Raw>> streams;
  for (int k = 0; k < 16; ++k) {
    streams.push_back(std::make_unique<Raw>(g.port()));
    ASSERT_TRUE(streams.back()->send("POST /v1/stream HTTP/1.1\r\nHost: t\r\nContent-Length: " +
                                     std::to_string(body.size()) + "\r\n\r\n" + body));
  }
  for (auto& stream : streams) EXPECT_EQ(status_of(stream->read_some(std::chrono::seconds(30))), 200);
  EXPECT_EQ(g.plan(), 200);
  for (int k = 0; k < 8; ++k) EXPECT_EQ(g.plan(), 200);
}

TEST(WebLimits, StreamsBeyondTheWebPortsCapAre429) {
  server::WebOptions web;
  web.max_streams = 2;
  Gateway g(web);
  const std::string body = json_of(real_time_request(60.0));
  const std::string stream = "POST /v1/stream HTTP/1.1\r\nHost: t\r\nConnection: close\r\nContent-Length: " + std::to_string(body.size()) +
                             "\r\n\r\n" + body;
  std::vector<std::unique_ptr<Raw>> open;
  for (int k = 0; k < 2; ++k) {
    open.push_back(std::make_unique<Raw>(g.port()));
    ASSERT_TRUE(open.back()->send(stream));
    const std::string first = open.back()->read_some(std::chrono::seconds(30));
    EXPECT_EQ(status_of(first), 200) << first.substr(0, 300);
  }
  const std::string answer = round_trip(g.port(), stream);
  EXPECT_EQ(status_of(answer), 429) << answer.substr(0, 300);
  EXPECT_EQ(status_from(body_of(answer)).code(), 8);
  open.clear();  // their calls are cancelled
  EXPECT_TRUE(eventually([&] { return g.running.runtime->calls_in_flight() == 0; }));
  EXPECT_EQ(g.plan(), 200);
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
