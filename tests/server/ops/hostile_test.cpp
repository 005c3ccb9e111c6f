// What a hostile or merely busy client meets: long work off gRPC's threads (health and
// streams answer while every worker plans), the admission queue and its cap, the server's
// default deadline, bounded answers and error details, health watches under the stream
// cap, calls reset at once, the health-only port, addresses and ports, connection caps and
// silent connections, descriptor exhaustion, gRPC's own log lines, a second SIGTERM, and
// an exit by a library.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

#include <gmock/gmock.h>
#include <google/protobuf/util/json_util.h>
#include <grpc/support/log.h>
#include <grpcpp/generic/generic_stub.h>
#include <nlohmann/json.hpp>

#include "server/ops/exit_guard.hpp"
#include "tests/server/support/daemon.hpp"
#include "tests/server/support/production_support.hpp"
#include "tests/server/support/raw_sockets.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

// An optimisation that runs for its whole budget: the breakpoints of Appendix B.
v1::PlanRequest slow_request(double budget_s) {
  auto request = example<v1::PlanRequest>("appendix_b_optimized.json");
  request.mutable_optimize()->set_time_budget_s(budget_s);
  return request;
}

grpc::Status plan_on(v1::TrajectoryService::Stub& stub, const v1::PlanRequest& request, double deadline_s = 60) {
  v1::PlanResponse response;
  return stub.PlanTrajectory(short_context(deadline_s).get(), request, &response);
}

// A channel of its own (no subchannel shared with other channels of the process).
std::shared_ptr<grpc::Channel> own_channel(int port) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials(), args);
}

double labelled(const std::string& exposition, const std::string& name_and_labels) {
  return series(exposition, name_and_labels);
}

// ---- Work off gRPC's threads ------------------------------------------------------------

TEST(Workers, HealthAndStreamsDoNotWaitBehindLongPlans) {
  server::ServerOptions options;
  options.limits.workers = 1;
  auto running = start(options);
  auto stub = stub_to(running.port);
  std::vector<std::future<grpc::Status>> busy;
  for (int i = 0; i < 3; ++i) {
    busy.push_back(std::async(std::launch::async, [&] { return plan_on(*stub, slow_request(2.0)); }));
  }
  ASSERT_TRUE(eventually([&] {
    const auto m = server::metrics_exposition(running);
    return series(m, "geotraj_busy_workers") == 1 && series(m, "geotraj_queued_calls") == 2;
  }));
  // Health is answered on gRPC's threads, a stream is planned by its own worker: neither
  // waits for the three plans (each of 2 s on one worker).
  EXPECT_EQ(health(running.port, ""), HealthStatus::SERVING);
  std::size_t samples = 0;
  auto ctx = short_context(60.0);
  const auto status = read_stream(*stub, real_time_request(0.5), samples, *ctx);
  EXPECT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(samples, 51u);
  // Ordered, not timed: the stream has ended while the last plan (the third of 2 s on the one
  // worker) is still queued or running.
  EXPECT_NE(busy.back().wait_for(std::chrono::seconds(0)), std::future_status::ready) << "the stream waited for the plans";
  for (auto& b : busy) EXPECT_TRUE(b.get().ok());
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Workers, CallsQueueUpToTheCapAndTheNextIsResourceExhausted) {
  server::ServerOptions options;
  options.limits.workers = 1;
  options.limits.max_unary_calls = 2;  // one running, one queued
  auto running = start(options);
  auto stub = stub_to(running.port);
  auto first = std::async(std::launch::async, [&] { return plan_on(*stub, slow_request(1.0)); });
  auto second = std::async(std::launch::async, [&] { return plan_on(*stub, slow_request(1.0)); });
  ASSERT_TRUE(eventually([&] { return series(server::metrics_exposition(running), "geotraj_active_unary_calls") == 2; }));
  const auto refused = list_robots(*stub);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("--max-unary-calls"));
  EXPECT_TRUE(first.get().ok());
  EXPECT_TRUE(second.get().ok());  // queued, not refused
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Deadlines, ACallWithoutADeadlineHasTheServersDefault) {
  server::ServerOptions options;
  options.limits.default_deadline_s = 0.5;
  auto running = start(options);
  auto stub = stub_to(running.port);
  grpc::ClientContext no_deadline;
  v1::PlanResponse response;
  const auto status = stub->PlanTrajectory(&no_deadline, slow_request(5.0), &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  EXPECT_THAT(status.error_message(), HasSubstr("--default-deadline-seconds"));
  server::stop_server(running, std::chrono::seconds(1));
}

// ---- Bounded answers ----------------------------------------------------------------------

TEST(Bounds, AnalysisPointsBeyondTheCapAreRefused) {
  server::ServerOptions options;
  options.limits.max_analysis_points = 1001;
  auto running = start(options);
  auto stub = stub_to(running.port);
  auto request = demo_request('a');
  request.set_analysis_points(1'000'000);
  v1::PathProfile profile;
  const auto status = stub->AnalyzePath(short_context().get(), request, &profile);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "analysisPoints"), HasSubstr("--max-analysis-points"));
  request.set_analysis_points(1001);
  EXPECT_TRUE(stub->AnalyzePath(short_context().get(), request, &profile).ok());
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Bounds, AnswersBeyondTheResponseCapAreRefused) {
  server::ServerOptions options;
  options.limits.max_response_bytes = 4096;
  auto running = start(options);
  auto stub = stub_to(running.port);
  auto request = demo_request('a');
  request.set_analysis_points(1000);
  v1::PathProfile profile;
  const auto status = stub->AnalyzePath(short_context().get(), request, &profile);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(status.error_message(), HasSubstr("--max-response-bytes"));
  request.set_analysis_points(3);
  EXPECT_TRUE(stub->AnalyzePath(short_context().get(), request, &profile).ok());
  server::stop_server(running, std::chrono::seconds(1));
}

class BoundedErrors : public ServerTest {};

TEST_F(BoundedErrors, ManyEmptyBreakpointEntriesAreOneViolation) {
  auto request = example<v1::PlanRequest>("appendix_b_uniform.json");
  request.mutable_path()->clear_breakpoints();
  for (int i = 0; i < 1000; ++i) request.mutable_path()->add_breakpoints();
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto violations = bad_request_violations(status);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "path.breakpoints");
  EXPECT_THAT(violations[0].description, HasSubstr("1000 entries"));
}

TEST_F(BoundedErrors, DetailsStayWithinWhatClientsAcceptAndSayWhatWasLeftOut) {
  // 900 frames, each with a torsion but no curvature: 900 violations.
  v1::PlanRequest request;
  for (int i = 0; i < 900; ++i) {
    auto* f = request.mutable_path()->add_frames();
    f->mutable_position()->set_x(0.01 * i);
    f->mutable_tangent()->set_x(1.0);
    f->set_torsion(1.0);
  }
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_LE(status.error_details().size(), 4096u);
  EXPECT_LE(status.error_message().size(), 1100u);
  const auto violations = bad_request_violations(status);
  ASSERT_GE(violations.size(), 2u);
  EXPECT_EQ(violations.front().field, "path.frames[0].torsion");
  EXPECT_THAT(violations.back().description, HasSubstr("more violations left out (of 900)"));
}

TEST_F(BoundedErrors, AHugeNameDoesNotComeBackWhole) {
  auto request = demo_request('a');
  request.mutable_robot()->set_name(std::string(1'000'000, 'x'));
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_LE(status.error_details().size(), 4096u);
  EXPECT_LE(status.error_message().size(), 1100u);
  EXPECT_THAT(status.error_message(), HasSubstr("more bytes)"));
}

TEST_F(BoundedErrors, SamplesPerBatchIsBounded) {
  auto request = demo_request('a');
  request.set_samples_per_batch(2147483647u);
  grpc::Status status;
  stream_all(request, status);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "samplesPerBatch"), HasSubstr("between 1 and 1024"));
}

TEST(Bounds, LogLinesAreBounded) {
  const auto path = std::filesystem::temp_directory_path() / ("geotraj_log_bound_" + std::to_string(::getpid()));
  std::FILE* log = std::fopen(path.c_str(), "w+");
  ASSERT_NE(log, nullptr);
  server::ServerOptions options;
  options.log_format = "json";
  options.log_output = log;
  auto running = start(options);
  auto stub = stub_to(running.port);
  auto request = demo_request('a');
  request.mutable_robot()->set_name(std::string(1'000'000, 'x'));
  EXPECT_EQ(plan_on(*stub, request).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  server::stop_server(running, std::chrono::seconds(1));
  running = {};
  std::fflush(log);
  std::ifstream in(path);
  std::size_t longest = 0, lines = 0;
  for (std::string line; std::getline(in, line); ++lines) {
    longest = std::max(longest, line.size());
    EXPECT_TRUE(nlohmann::json::accept(line)) << line.substr(0, 200);
  }
  EXPECT_GT(lines, 0u);
  EXPECT_LT(longest, 8192u);
  std::fclose(log);
  std::filesystem::remove(path);
}

TEST(Robot, AnUnreachableReportOnlyPlanHasNoInfinity) {
  auto running = start({});
  auto stub = stub_to(running.port);
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  for (auto& frame : *request.mutable_path()->mutable_frames()) {
    frame.mutable_position()->set_x(frame.position().x() + 5.0);  // 5 m away: nothing in reach
  }
  request.mutable_robot()->set_report_only(true);
  v1::PlanResponse response;
  // A path that does not start at the robot is refused first, naming how far it is.
  auto status = stub->PlanTrajectory(short_context(120).get(), request, &response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("the path starts 5 m and "));
  // Tolerated (for simulation), it is reported sample by sample.
  request.mutable_robot()->set_start_position_tolerance(10.0);
  status = stub->PlanTrajectory(short_context(120).get(), request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.robot().converged_samples(), 0u);
  EXPECT_FALSE(response.robot().feasible());
  std::string json;
  ASSERT_TRUE(google::protobuf::util::MessageToJsonString(response, &json).ok());
  EXPECT_THAT(json, ::testing::Not(HasSubstr("Infinity")));
  EXPECT_THAT(json, ::testing::Not(HasSubstr("NaN")));
  server::stop_server(running, std::chrono::seconds(1));
}

// ---- Health ----------------------------------------------------------------------------

TEST(HealthWatch, WatchesCountAgainstTheStreamCapAndSeeTheDrain) {
  server::ServerOptions options;
  options.limits.max_streams = 2;
  auto running = start(options);
  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(running.port), grpc::InsecureChannelCredentials());
  auto health_stub = grpc::health::v1::Health::NewStub(channel);
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(server::kReadinessService);
  struct Watch {
    std::unique_ptr<grpc::ClientContext> context = short_context(30);
    std::unique_ptr<grpc::ClientReader<HealthStatus>> reader;
  };
  std::vector<Watch> watches(2);
  for (auto& w : watches) {
    w.reader = health_stub->Watch(w.context.get(), request);
    HealthStatus first;
    ASSERT_TRUE(w.reader->Read(&first));
    EXPECT_EQ(first.status(), HealthStatus::SERVING);
  }
  // A third watch, and a stream, are beyond the cap.
  Watch third;
  third.reader = health_stub->Watch(third.context.get(), request);
  HealthStatus ignored;
  EXPECT_FALSE(third.reader->Read(&ignored));
  const auto refused = third.reader->Finish();
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("--max-streams"));
  std::size_t samples = 0;
  auto stream_context = short_context();
  EXPECT_EQ(read_stream(*stub_to(running.port), demo_request('a'), samples, *stream_context).error_code(),
            grpc::StatusCode::RESOURCE_EXHAUSTED);
  // The drain: each watch is told NOT_SERVING, then ends.
  auto stopping = std::async(std::launch::async, [&] { server::stop_server(running, std::chrono::seconds(2)); });
  for (auto& w : watches) {
    HealthStatus next;
    ASSERT_TRUE(w.reader->Read(&next));
    EXPECT_EQ(next.status(), HealthStatus::NOT_SERVING);
    while (w.reader->Read(&next)) {
    }
    w.reader->Finish();
  }
  stopping.get();
}

TEST(HealthWatch, WatchesHaveACapOfTheirOwn) {
  server::ServerOptions options;
  options.limits.max_health_watches = 1;
  auto running = start(options);
  auto health_stub = grpc::health::v1::Health::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(running.port), grpc::InsecureChannelCredentials()));
  grpc::health::v1::HealthCheckRequest request;
  auto first_context = short_context(30);
  auto first = health_stub->Watch(first_context.get(), request);
  HealthStatus status;
  ASSERT_TRUE(first->Read(&status));
  auto second_context = short_context(30);
  auto second = health_stub->Watch(second_context.get(), request);
  EXPECT_FALSE(second->Read(&status));
  const auto refused = second->Finish();
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("--max-health-watches"));
  // Streams of the API still get their slots.
  std::size_t samples = 0;
  auto stream_context = short_context();
  EXPECT_TRUE(read_stream(*stub_to(running.port), demo_request('a'), samples, *stream_context).ok());
  first_context->TryCancel();
  while (first->Read(&status)) {
  }
  first->Finish();
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(HealthPort, ServesHealthAndNothingElse) {
  server::ServerOptions options;
  options.health_address = "127.0.0.1:0";
  auto running = start(options);
  ASSERT_GT(running.health_port, 0);
  EXPECT_EQ(health(running.health_port, ""), HealthStatus::SERVING);
  // Neither the API nor reflection (which would describe the whole API).
  EXPECT_EQ(list_robots(*stub_to(running.health_port)).error_code(), grpc::StatusCode::UNIMPLEMENTED);
  grpc::GenericStub generic(grpc::CreateChannel("127.0.0.1:" + std::to_string(running.health_port),
                                                grpc::InsecureChannelCredentials()));
  grpc::CompletionQueue cq;
  auto ctx = short_context(10);
  grpc::ByteBuffer in, out;
  grpc::Status status;
  auto call = generic.PrepareUnaryCall(ctx.get(), "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", out, &cq);
  call->StartCall();
  call->Finish(&in, &status, reinterpret_cast<void*>(1));
  void* tag = nullptr;
  bool ok = false;
  ASSERT_TRUE(cq.Next(&tag, &ok));
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNIMPLEMENTED);
  cq.Shutdown();
  while (cq.Next(&tag, &ok)) {
  }
  server::stop_server(running, std::chrono::seconds(1));
}

// ---- Calls reset at once -------------------------------------------------------------------

TEST(Cancel, ACallResetRightAfterItsRequestIsNotABadRequest) {
  auto running = start({});
  grpc::GenericStub generic(grpc::CreateChannel("127.0.0.1:" + std::to_string(running.port),
                                                grpc::InsecureChannelCredentials()));
  std::string bytes;
  ASSERT_TRUE(demo_request('a').SerializeToString(&bytes));
  grpc::CompletionQueue cq;
  for (int i = 0; i < 200; ++i) {
    grpc::ClientContext ctx;
    grpc::Slice slice(bytes);
    grpc::ByteBuffer request(&slice, 1), response;
    grpc::Status status;
    auto call = generic.PrepareUnaryCall(&ctx, "/geotraj.v1.TrajectoryService/PlanTrajectory", request, &cq);
    call->StartCall();
    call->Finish(&response, &status, reinterpret_cast<void*>(1));
    ctx.TryCancel();
    void* tag = nullptr;
    bool ok = false;
    ASSERT_TRUE(cq.Next(&tag, &ok));
  }
  cq.Shutdown();
  void* tag = nullptr;
  bool ok = false;
  while (cq.Next(&tag, &ok)) {
  }
  server::stop_server(running, std::chrono::seconds(2));
  const auto m = server::metrics_exposition(running);
  EXPECT_EQ(labelled(m, "geotraj_rpc_calls_total{method=\"PlanTrajectory\",code=\"INVALID_ARGUMENT\"}"), 0.0) << m;
}

// A cancelled optimisation stops its work at once (its reactor's stop token reaches the
// optimiser), not at the end of its 20 s budget.
TEST(Cancel, ACancelledOptimisationStopsItsWork) {
  auto running = start({});
  auto stub = stub_to(running.port);
  grpc::ClientContext ctx;
  auto call = std::async(std::launch::async, [&] {
    v1::PlanResponse response;
    return stub->PlanTrajectory(&ctx, slow_request(20.0), &response);
  });
  ASSERT_TRUE(eventually([&] { return series(server::metrics_exposition(running), "geotraj_busy_workers") == 1; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto cancelled = std::chrono::steady_clock::now();
  ctx.TryCancel();
  EXPECT_EQ(call.get().error_code(), grpc::StatusCode::CANCELLED);
  ASSERT_TRUE(eventually([&] { return series(server::metrics_exposition(running), "geotraj_busy_workers") == 0; }));
  const double stopped_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - cancelled).count();
  std::printf("[ measured ] the optimisation's worker was free %.0f ms after the cancel\n", stopped_s * 1e3);
  EXPECT_LT(stopped_s, 5.0);  // a quarter of the budget it would otherwise have used
  server::stop_server(running, std::chrono::seconds(1));
}

// ---- Addresses -----------------------------------------------------------------------------

TEST(Addresses, APortIsRequired) {
  server::ServerOptions options;
  options.address = "127.0.0.1";
  const auto started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), HasSubstr("has no port"));
}

TEST(Addresses, ASecondServerCannotTakeAPortInUse) {
  auto first = start({});
  server::ServerOptions options;
  options.address = "127.0.0.1:" + std::to_string(first.port);
  options.log_level = "warning";
  const auto second = server::start_server(options);
  ASSERT_FALSE(second);
  EXPECT_THAT(second.error(), HasSubstr("in use"));
  server::stop_server(first, std::chrono::seconds(1));
}

// ---- Logs -------------------------------------------------------------------------------------

TEST(Logs, GrpcCoreLinesAreJsonInAJsonLog) {
  const auto path = std::filesystem::temp_directory_path() / ("geotraj_grpc_log_" + std::to_string(::getpid()));
  std::FILE* log = std::fopen(path.c_str(), "w+");
  ASSERT_NE(log, nullptr);
  server::ServerOptions options;
  options.log_format = "json";
  options.log_output = log;
  auto running = start(options);
  gpr_log(GPR_ERROR, "a line of gRPC core's %s", "own");
  server::stop_server(running, std::chrono::seconds(1));
  running = {};
  std::ifstream in(path);
  bool found = false;
  for (std::string line; std::getline(in, line);) {
    const auto json = nlohmann::json::parse(line);  // throws on a line that is not JSON
    if (json.value("msg", "") == "a line of gRPC core's own") {
      found = true;
      EXPECT_EQ(json.value("source", ""), "grpc");
      EXPECT_EQ(json.value("level", ""), "error");
    }
  }
  EXPECT_TRUE(found);
  std::fclose(log);
  std::filesystem::remove(path);
}

// ---- Connections -----------------------------------------------------------------------------

TEST(Connections, SilentConnectionsAreClosedAfterTheHandshakeTimeout) {
  server::ServerOptions options;
  options.connections.handshake_timeout_s = 0.5;
  auto running = start(options);
  const int fd = connect_loopback(running.port);
  ASSERT_GE(fd, 0);
  EXPECT_TRUE(closed_within(fd, std::chrono::seconds(5)));
  ::close(fd);
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Connections, AtTheCapSilentConnectionsMakeRoom) {
  server::ServerOptions options;
  options.connections.max_connections = 4;
  auto running = start(options);
  std::vector<int> silent;
  for (int i = 0; i < 4; ++i) silent.push_back(connect_loopback(running.port));
  std::this_thread::sleep_for(std::chrono::milliseconds(400));  // past the acceptor's grace
  EXPECT_TRUE(list_robots(*v1::TrajectoryService::NewStub(own_channel(running.port))).ok());
  for (int fd : silent) {
    EXPECT_TRUE(closed_within(fd, std::chrono::seconds(5)));
    ::close(fd);
  }
  EXPECT_GE(labelled(server::metrics_exposition(running),
                     "geotraj_connections_refused_total{listener=\"grpc\",reason=\"idle\"}"),
            1.0);
  server::stop_server(running, std::chrono::seconds(1));
}

TEST(Connections, BeyondTheCapNewConnectionsAreClosed) {
  server::ServerOptions options;
  options.connections.max_connections = 2;
  auto running = start(options);
  // Two clients with streams in flight hold both connections.
  std::vector<std::future<grpc::Status>> streams;
  std::vector<std::shared_ptr<grpc::Channel>> channels;
  for (int i = 0; i < 2; ++i) {
    channels.push_back(own_channel(running.port));
    auto stub = std::shared_ptr<v1::TrajectoryService::Stub>(v1::TrajectoryService::NewStub(channels.back()));
    streams.push_back(std::async(std::launch::async, [stub] {
      std::size_t samples = 0;
      auto ctx = short_context(30);
      return read_stream(*stub, real_time_request(2.0), samples, *ctx);
    }));
  }
  ASSERT_TRUE(eventually([&] { return series(server::metrics_exposition(running), "geotraj_active_streams") == 2; }));
  EXPECT_EQ(list_robots(*v1::TrajectoryService::NewStub(own_channel(running.port))).error_code(),
            grpc::StatusCode::UNAVAILABLE);
  EXPECT_GE(labelled(server::metrics_exposition(running),
                     "geotraj_connections_refused_total{listener=\"grpc\",reason=\"max_connections\"}"),
            1.0);
  for (auto& s : streams) EXPECT_TRUE(s.get().ok());
  server::stop_server(running, std::chrono::seconds(1));
}

// geotrajd with 256 descriptors in all (soft and hard): 400 silent connections do not stop
// it from accepting the next client, and it answers health throughout.
TEST(Descriptors, MoreConnectionsThanDescriptorsDoNotStopThePort) {
  Daemon daemon({"--address", "127.0.0.1:0", "--log-level", "warning"}, {}, 256);
  ASSERT_TRUE(daemon.started());
  const int port = port_of(daemon.line());
  ASSERT_GT(port, 0);
  std::vector<int> silent;
  for (int i = 0; i < 400; ++i) {
    const int fd = connect_loopback(port);
    if (fd >= 0) silent.push_back(fd);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  // At the cap a connection may arrive before the acceptor's next rescan (kRescanEvery) and
  // be closed: a prober asks again at its next period (here up to three times, 0.2 s apart),
  // and a client retries with backoff, as a real client waiting for the server does.
  const auto probed = [port] {
    for (int attempt = 0; attempt < 3; ++attempt) {
      if (health(port, "") == HealthStatus::SERVING) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    return false;
  };
  EXPECT_TRUE(probed());
  auto context = short_context(10);
  context->set_wait_for_ready(true);
  v1::PlanResponse response;
  const auto planned =
      v1::TrajectoryService::NewStub(own_channel(port))->PlanTrajectory(context.get(), demo_request('a'), &response);
  EXPECT_TRUE(planned.ok()) << planned.error_code() << ": " << planned.error_message();
  for (int fd : silent) ::close(fd);
  EXPECT_EQ(health(port, server::kReadinessService), HealthStatus::SERVING);
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(std::chrono::seconds(30)), 0);
}

// ---- Shutdown and exits ----------------------------------------------------------------------

TEST(Signals, ASecondSigtermStopsTheDrainAtOnce) {
  Daemon daemon({"--address", "127.0.0.1:0", "--log-level", "warning", "--drain-seconds", "60"});
  ASSERT_TRUE(daemon.started());
  const int port = port_of(daemon.line());
  ASSERT_GT(port, 0);
  auto stub = std::shared_ptr<v1::TrajectoryService::Stub>(v1::TrajectoryService::NewStub(own_channel(port)));
  auto stream = std::async(std::launch::async, [stub] {
    std::size_t samples = 0;
    auto ctx = short_context(60);
    return read_stream(*stub, real_time_request(30.0), samples, *ctx);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  daemon.signal(SIGTERM);
  EXPECT_THAT(daemon.line(std::chrono::seconds(5)), HasSubstr("draining"));
  EXPECT_FALSE(daemon.wait(std::chrono::milliseconds(500)).has_value()) << "the first SIGTERM drains";
  const auto second = std::chrono::steady_clock::now();
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(std::chrono::seconds(10)), 0);
  EXPECT_LT(std::chrono::steady_clock::now() - second, std::chrono::seconds(5));
  EXPECT_FALSE(stream.get().ok());  // cut: the motion had 30 s to go
}

TEST(ExitGuard, AnExitThatMainDidNotMakeIsAFailure) {
  for (const bool allowed : {false, true}) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      server::guard_exit();
      if (allowed) server::allow_exit();
      std::exit(0);  // as MUMPS's stand-in for MPI_ABORT does
    }
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), allowed ? 0 : server::kAbnormalExitStatus);
  }
}

}  // namespace
}  // namespace geotraj::testing
