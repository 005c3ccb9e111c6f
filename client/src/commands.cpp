#include "commands.hpp"

#include <chrono>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>

#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "report.hpp"

namespace geotraj::cli {
namespace {

bool read_text(const std::string& input, std::string& text) {
  if (input == "-") {
    text.assign(std::istreambuf_iterator<char>(std::cin), std::istreambuf_iterator<char>());
    return true;
  }
  std::ifstream file(input, std::ios::binary);
  if (!file) return false;
  text.assign(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
  return true;
}

// Parses the request file; prints why it cannot and returns false.
template <class Request>
bool read_request(const std::string& input, Request& request) {
  const std::string name = input == "-" ? "standard input" : input;
  std::string text;
  if (!read_text(input, text)) {
    std::cerr << "geotraj: cannot read " << name << '\n';
    return false;
  }
  google::protobuf::util::JsonParseOptions parse;
  parse.ignore_unknown_fields = false;
  const auto status = google::protobuf::util::JsonStringToMessage(text, &request, parse);
  if (!status.ok()) {
    std::cerr << "geotraj: " << name << " is not a " << Request::descriptor()->full_name()
              << " in the proto JSON mapping: " << status.message() << '\n';
    return false;
  }
  return true;
}

void set_deadline(grpc::ClientContext& context, double timeout_s) {
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::microseconds(static_cast<long long>(timeout_s * 1e6)));
}

void print_json(const google::protobuf::Message& message) {
  google::protobuf::util::JsonPrintOptions print;
  print.add_whitespace = true;
  print.always_print_primitive_fields = true;
  std::string json;
  (void)google::protobuf::util::MessageToJsonString(message, &json, print);
  std::cout << json;
  if (json.empty() || json.back() != '\n') std::cout << '\n';
}

// Reads the request, makes the call, prints the response or the error.
template <class Request, class Response, class Call>
int run(const CallOptions& options, Call call) {
  Request request;
  if (!read_request(options.input, request)) return 2;
  grpc::ClientContext context;
  set_deadline(context, options.timeout_s);
  Response response;
  const grpc::Status status = call(context, request, response);
  if (!status.ok()) {
    print_error(status, std::cerr);
    return 1;
  }
  if (options.json) {
    print_json(response);
  } else {
    print_table(response, std::cout);
  }
  return 0;
}

}  // namespace

int run_convert(const Connection& connection, const CallOptions& options) {
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  return run<v1::ConvertRequest, v1::ConvertResponse>(options, [&](auto& context, auto& request, auto& response) {
    return stub->ConvertConstraints(&context, request, &response);
  });
}

int run_plan(const Connection& connection, const CallOptions& options) {
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  return run<v1::PlanRequest, v1::PlanResponse>(options, [&](auto& context, auto& request, auto& response) {
    return stub->PlanTrajectory(&context, request, &response);
  });
}

int run_analyze(const Connection& connection, const CallOptions& options) {
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  return run<v1::PlanRequest, v1::PathProfile>(options, [&](auto& context, auto& request, auto& response) {
    return stub->AnalyzePath(&context, request, &response);
  });
}

int run_health(const Connection& connection, const std::string& service, double timeout_s) {
  auto stub = grpc::health::v1::Health::NewStub(connection.channel);
  grpc::ClientContext context;
  set_deadline(context, timeout_s);
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(service);
  grpc::health::v1::HealthCheckResponse response;
  const grpc::Status status = stub->Check(&context, request, &response);
  if (!status.ok()) {
    print_error(status, std::cerr);
    return 1;
  }
  std::cout << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status()) << '\n';
  return response.status() == grpc::health::v1::HealthCheckResponse::SERVING ? 0 : 1;
}

}  // namespace geotraj::cli
