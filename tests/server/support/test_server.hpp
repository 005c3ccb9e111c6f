// The real service on a loopback ephemeral port, and helpers to talk to it.
#pragma once

#include <chrono>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <gtest/gtest.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "google/rpc/error_details.pb.h"
#include "google/rpc/status.pb.h"
#include "server/server.hpp"
#include "tests/support/build_paths.hpp"

namespace geotraj::testing {

/// A started server on 127.0.0.1:<ephemeral>, a plaintext channel and a stub to it.
class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    server::ServerOptions options;
    options.address = "127.0.0.1:0";
    options.log_level = "warning";  // no line per call in the test output
    auto started = server::start_server(options);
    ASSERT_TRUE(started) << started.error();
    running_ = std::move(*started);
    ASSERT_GT(running_.port, 0);
    address_ = "127.0.0.1:" + std::to_string(running_.port);
    channel_ = grpc::CreateChannel(address_, grpc::InsecureChannelCredentials());
    stub_ = v1::TrajectoryService::NewStub(channel_);
  }

  void TearDown() override { server::stop_server(running_, std::chrono::seconds(1)); }

  /// A context whose deadline keeps a broken test from hanging.
  static std::unique_ptr<grpc::ClientContext> context() {
    auto c = std::make_unique<grpc::ClientContext>();
    // Generous: the robot tests plan thousands of IK samples, slow under the sanitizers.
    c->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
    return c;
  }

  /// Every sample of a stream, in order, and its final status in `status`.
  std::vector<v1::Sample> stream_all(const v1::PlanRequest& request, grpc::Status& status) {
    auto ctx = context();
    auto reader = stub_->StreamSamples(ctx.get(), request);
    std::vector<v1::Sample> samples;
    v1::SampleBatch batch;
    while (reader->Read(&batch)) samples.insert(samples.end(), batch.samples().begin(), batch.samples().end());
    status = reader->Finish();
    return samples;
  }

  /// The built-in robot model `name`, as ListRobots returns it (a test failure when absent).
  v1::RobotModel robot_model(const std::string& name) {
    v1::ListRobotsResponse response;
    const auto status = stub_->ListRobots(context().get(), v1::ListRobotsRequest{}, &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    for (const auto& m : response.robots()) {
      if (m.name() == name) return m;
    }
    ADD_FAILURE() << "ListRobots has no model " << name;
    return {};
  }

  grpc::Status convert(const v1::ConvertRequest& request, v1::ConvertResponse& response) {
    return stub_->ConvertConstraints(context().get(), request, &response);
  }
  grpc::Status plan(const v1::PlanRequest& request, v1::PlanResponse& response) {
    return stub_->PlanTrajectory(context().get(), request, &response);
  }
  /// PlanTrajectory that must succeed.
  v1::PlanResponse plan_ok(const v1::PlanRequest& request) {
    v1::PlanResponse response;
    const auto status = plan(request, response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return response;
  }
  grpc::Status analyze(const v1::PlanRequest& request, v1::PathProfile& profile) {
    return stub_->AnalyzePath(context().get(), request, &profile);
  }

  server::RunningServer running_;
  std::string address_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::TrajectoryService::Stub> stub_;
};

/// A message from its proto JSON mapping; fails the test on a parse error.
template <class Message>
Message from_json(const std::string& json) {
  Message m;
  const auto status = google::protobuf::util::JsonStringToMessage(json, &m);
  EXPECT_TRUE(status.ok()) << status.message() << "\n" << json;
  return m;
}

/// The text of an example request file in client/grpcurl/.
inline std::string example_text(const std::string& name) {
  std::ifstream file(std::string(build_paths::examples_dir()) + "/" + name);
  EXPECT_TRUE(file.good()) << "cannot open example " << name;
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

template <class Message>
Message example(const std::string& name) {
  return from_json<Message>(example_text(name));
}

/// The thesis demonstration (Table 7.8 with its erratum, Table 7.18), path 'a', 'b' or 'c',
/// as the example files give it (the default reading, 7.2.8's kappa' = tau' = 0 at frames 2
/// and 3).
inline v1::PlanRequest demo_example(char path) {
  return example<v1::PlanRequest>(std::string("plan_demo_path_") + path + ".json");
}

/// The same paths as Table 7.18 prints them (no derivatives given) with lowest-degree
/// segments: the tests of the optimisers, the timing and the service's machinery were
/// measured on that curve; the readings have tests of their own.
inline v1::PlanRequest demo_request(char path) {
  auto request = demo_example(path);
  request.mutable_path()->set_unspecified(v1::UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE);
  for (auto& f : *request.mutable_path()->mutable_frames()) {
    f.clear_curvature_derivative();
    f.clear_torsion_derivative();
  }
  return request;
}

/// The field violations of a status's google.rpc.BadRequest detail, as (field, description).
struct Violation {
  std::string field;
  std::string description;
};
inline std::vector<Violation> bad_request_violations(const grpc::Status& status) {
  std::vector<Violation> out;
  google::rpc::Status details;
  EXPECT_TRUE(details.ParseFromString(status.error_details())) << "no google.rpc.Status in the details";
  EXPECT_EQ(details.code(), static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT));
  EXPECT_EQ(details.message(), status.error_message());
  for (const auto& any : details.details()) {
    google::rpc::BadRequest bad_request;
    if (!any.UnpackTo(&bad_request)) continue;
    for (const auto& v : bad_request.field_violations()) out.push_back({v.field(), v.description()});
  }
  return out;
}

/// The unmet preconditions of a FAILED_PRECONDITION status: its google.rpc.Status detail
/// (grpc-status-details-bin) with google.rpc.PreconditionFailure violations.
inline std::vector<google::rpc::PreconditionFailure::Violation> precondition_violations(const grpc::Status& status) {
  std::vector<google::rpc::PreconditionFailure::Violation> out;
  google::rpc::Status details;
  EXPECT_TRUE(details.ParseFromString(status.error_details())) << "no google.rpc.Status in the details";
  EXPECT_EQ(details.code(), static_cast<int>(grpc::StatusCode::FAILED_PRECONDITION));
  EXPECT_EQ(details.message(), status.error_message());
  for (const auto& any : details.details()) {
    google::rpc::PreconditionFailure failure;
    if (!any.UnpackTo(&failure)) continue;
    out.insert(out.end(), failure.violations().begin(), failure.violations().end());
  }
  return out;
}

/// The description of the violation of `field`, or "" when there is none.
inline std::string violation_of(const std::vector<Violation>& violations, const std::string& field) {
  for (const auto& v : violations) {
    if (v.field == field) return v.description;
  }
  return "";
}

/// Lists the violations for a failure message.
inline std::string describe(const std::vector<Violation>& violations) {
  std::string s;
  for (const auto& v : violations) s += "  " + v.field + ": " + v.description + "\n";
  return s;
}

}  // namespace geotraj::testing
