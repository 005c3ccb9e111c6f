// Helpers of the tests of the service as operators run it (production_test.cpp,
// hostile_test.cpp): servers started with options, stubs and health checks to a port,
// metrics series, polling.
#pragma once

#include <chrono>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {

using HealthStatus = grpc::health::v1::HealthCheckResponse;

inline std::unique_ptr<grpc::ClientContext> short_context(double seconds = 60.0) {
  auto c = std::make_unique<grpc::ClientContext>();
  c->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(static_cast<int>(seconds * 1e3)));
  return c;
}

inline server::RunningServer start(server::ServerOptions options) {
  if (options.address == "127.0.0.1:50051") options.address = "127.0.0.1:0";
  if (options.log_output == nullptr) options.log_level = "warning";  // no line per call in the test output
  auto started = server::start_server(options);
  EXPECT_TRUE(started) << started.error();
  return started ? std::move(*started) : server::RunningServer{};
}

inline std::unique_ptr<v1::TrajectoryService::Stub> stub_to(int port,
                                                     std::shared_ptr<grpc::ChannelCredentials> creds = nullptr,
                                                     const grpc::ChannelArguments& args = {}) {
  return v1::TrajectoryService::NewStub(grpc::CreateCustomChannel(
      "127.0.0.1:" + std::to_string(port), creds ? creds : grpc::InsecureChannelCredentials(), args));
}

inline HealthStatus::ServingStatus health(int port, const std::string& service) {
  auto stub = grpc::health::v1::Health::NewStub(
      grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials()));
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(service);
  HealthStatus response;
  const auto status = stub->Check(short_context(10).get(), request, &response);
  if (!status.ok()) return HealthStatus::UNKNOWN;
  return response.status();
}

inline grpc::Status list_robots(v1::TrajectoryService::Stub& stub, const std::string& token = "") {
  auto ctx = short_context();
  if (!token.empty()) ctx->AddMetadata("authorization", "Bearer " + token);
  v1::ListRobotsResponse response;
  return stub.ListRobots(ctx.get(), {}, &response);
}

// A short motion along path A streamed at the cycle rate (real time), `seconds` long.
inline v1::PlanRequest real_time_request(double seconds) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(seconds);
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  return request;
}

// Reads a whole stream; returns its status and counts the samples.
inline grpc::Status read_stream(v1::TrajectoryService::Stub& stub, const v1::PlanRequest& request, std::size_t& samples,
                         grpc::ClientContext& context) {
  auto reader = stub.StreamSamples(&context, request);
  v1::SampleBatch batch;
  samples = 0;
  while (reader->Read(&batch)) samples += static_cast<std::size_t>(batch.samples_size());
  return reader->Finish();
}

// The value of one series in a Prometheus exposition (0 when absent).
inline double series(const std::string& exposition, const std::string& name) {
  std::istringstream lines(exposition);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(name + " ", 0) == 0) return std::stod(line.substr(name.size() + 1));
  }
  return 0.0;
}

// Polls until `done` or `limit` has passed (a bound on waiting, never a margin asserted).
template <typename Done>
bool eventually(Done done, std::chrono::seconds limit = std::chrono::seconds(10)) {
  const auto until = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < until) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return done();
}

}  // namespace geotraj::testing
