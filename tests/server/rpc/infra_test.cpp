// What operators and generic tools rely on: the health service, server reflection (what
// `grpcurl -plaintext HOST:PORT list` uses), and start-up errors.
#include <cstdint>
#include <string>
#include <vector>

#include <gmock/gmock.h>

#include <google/protobuf/descriptor.pb.h>
#include <google/protobuf/unknown_field_set.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/support/byte_buffer.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "server/rpc/health.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

class InfraTest : public ServerTest {
 protected:
  grpc::Status check_health(const std::string& service, HealthCheckResponse& response) {
    HealthCheckRequest request;
    request.set_service(service);
    return grpc::health::v1::Health::NewStub(channel_)->Check(context().get(), request, &response);
  }

  // One request and its answer on grpc.reflection.v1alpha.ServerReflection (the version
  // gRPC 1.51 serves). Debian ships neither reflection.proto nor the reflection client, so
  // the messages are encoded by their field numbers, which the protocol fixes:
  // ServerReflectionRequest { file_containing_symbol = 4; list_services = 7 } and
  // ServerReflectionResponse { file_descriptor_response = 4 { repeated bytes
  // file_descriptor_proto = 1 }; list_services_response = 6 { repeated ServiceResponse
  // service = 1 { name = 1 } }; error_response = 7 }.
  std::string reflect(int request_field, const std::string& value) {
    google::protobuf::UnknownFieldSet request;
    request.AddLengthDelimited(request_field, value);
    std::string bytes;
    EXPECT_TRUE(request.SerializeToString(&bytes));

    grpc::CompletionQueue cq;
    grpc::GenericStub stub(channel_);
    auto ctx = context();
    auto call = stub.PrepareCall(ctx.get(), "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", &cq);
    const auto step = [&cq](int tag) {
      void* got = nullptr;
      bool ok = false;
      EXPECT_TRUE(cq.Next(&got, &ok));
      EXPECT_EQ(got, reinterpret_cast<void*>(static_cast<std::intptr_t>(tag)));
      return ok;
    };
    const auto tag = [](int t) { return reinterpret_cast<void*>(static_cast<std::intptr_t>(t)); };
    call->StartCall(tag(1));
    EXPECT_TRUE(step(1));
    grpc::Slice slice(bytes);
    grpc::ByteBuffer out(&slice, 1);
    call->Write(out, tag(2));
    EXPECT_TRUE(step(2));
    grpc::ByteBuffer in;
    call->Read(&in, tag(3));
    EXPECT_TRUE(step(3)) << "no reflection response";
    call->WritesDone(tag(4));
    EXPECT_TRUE(step(4));
    grpc::Status status;
    call->Finish(&status, tag(5));
    EXPECT_TRUE(step(5));
    EXPECT_TRUE(status.ok()) << status.error_message();
    cq.Shutdown();
    void* ignored_tag;
    bool ignored_ok;
    while (cq.Next(&ignored_tag, &ignored_ok)) {
    }

    std::vector<grpc::Slice> slices;
    EXPECT_TRUE(in.Dump(&slices).ok());
    std::string answer;
    for (const auto& s : slices) answer.append(reinterpret_cast<const char*>(s.begin()), s.size());
    return answer;
  }

  // The length-delimited values of field `number` in an encoded message.
  static std::vector<std::string> fields(const std::string& message, int number) {
    google::protobuf::UnknownFieldSet set;
    EXPECT_TRUE(set.ParseFromString(message));
    std::vector<std::string> out;
    for (int i = 0; i < set.field_count(); ++i) {
      const auto& f = set.field(i);
      if (f.number() == number && f.type() == google::protobuf::UnknownField::TYPE_LENGTH_DELIMITED) {
        out.push_back(f.length_delimited());
      }
    }
    return out;
  }
};

TEST_F(InfraTest, HealthIsServing) {
  for (const std::string service : {"", "geotraj.v1.TrajectoryService"}) {
    HealthCheckResponse response;
    const auto status = check_health(service, response);
    ASSERT_TRUE(status.ok()) << "service \"" << service << "\": " << status.error_message();
    EXPECT_EQ(response.status(), HealthCheckResponse::SERVING) << "service \"" << service << "\"";
  }
  HealthCheckResponse response;
  EXPECT_EQ(check_health("no.such.Service", response).error_code(), grpc::StatusCode::NOT_FOUND);
}

TEST_F(InfraTest, HealthIsNotServingAfterStop) {
  HealthCheckResponse response;
  ASSERT_TRUE(check_health("", response).ok());
  running_.health->set_all(false);  // what stop_server does first
  ASSERT_TRUE(check_health("geotraj.v1.TrajectoryService", response).ok());
  EXPECT_EQ(response.status(), HealthCheckResponse::NOT_SERVING);
}

TEST_F(InfraTest, ReflectionListsTheServices) {
  const std::string answer = reflect(/*list_services=*/7, "*");
  const auto list = fields(answer, /*list_services_response=*/6);
  ASSERT_EQ(list.size(), 1u) << "no list_services_response";
  std::vector<std::string> names;
  for (const auto& service : fields(list[0], 1)) {
    for (const auto& name : fields(service, 1)) names.push_back(name);
  }
  EXPECT_THAT(names, ::testing::Contains("geotraj.v1.TrajectoryService"));
  EXPECT_THAT(names, ::testing::Contains("grpc.health.v1.Health"));
  EXPECT_THAT(names, ::testing::Contains("grpc.reflection.v1alpha.ServerReflection"));
}

// grpcurl describes methods and messages from the file descriptors that reflection sends.
TEST_F(InfraTest, ReflectionDescribesTheService) {
  const std::string answer = reflect(/*file_containing_symbol=*/4, "geotraj.v1.TrajectoryService");
  EXPECT_TRUE(fields(answer, /*error_response=*/7).empty());
  const auto files = fields(answer, /*file_descriptor_response=*/4);
  ASSERT_EQ(files.size(), 1u);
  bool found = false;
  for (const auto& bytes : fields(files[0], 1)) {
    google::protobuf::FileDescriptorProto file;
    ASSERT_TRUE(file.ParseFromString(bytes));
    if (file.name() != "geotraj/v1/geotraj.proto") continue;
    ASSERT_EQ(file.service_size(), 1);
    std::vector<std::string> methods;
    for (const auto& m : file.service(0).method()) methods.push_back(m.name());
    EXPECT_THAT(methods, ::testing::ElementsAre("ConvertConstraints", "PlanTrajectory", "StreamSamples",
                                                "AnalyzePath", "ListRobots", "ComputeForwardKinematics",
                                                "ComputeInverseKinematics", "Execute", "Jog"));
    found = true;
  }
  EXPECT_TRUE(found) << "geotraj/v1/geotraj.proto not among the files sent";
}

// Error details and the health protocol are describable too, so that grpcurl can print a
// google.rpc.BadRequest and call grpc.health.v1.Health without .proto files.
TEST_F(InfraTest, ReflectionDescribesErrorDetailsAndHealth) {
  for (const std::string symbol : {"google.rpc.BadRequest", "google.rpc.Status", "grpc.health.v1.Health"}) {
    const std::string answer = reflect(/*file_containing_symbol=*/4, symbol);
    EXPECT_TRUE(fields(answer, /*error_response=*/7).empty()) << symbol;
    EXPECT_EQ(fields(answer, /*file_descriptor_response=*/4).size(), 1u) << symbol;
  }
}

TEST(StartServer, ReportsAnAddressItCannotUse) {
  server::ServerOptions options;
  options.address = "256.0.0.1:0";  // not an IPv4 address
  const auto started = server::start_server(options);
  ASSERT_FALSE(started);
  EXPECT_THAT(started.error(), ::testing::HasSubstr("256.0.0.1:0"));
}

}  // namespace
}  // namespace geotraj::testing
