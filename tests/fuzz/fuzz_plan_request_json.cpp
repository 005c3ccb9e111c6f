// fuzz_plan_request_json: bytes as the proto3 JSON of a geotraj.v1.PlanRequest (the form of
// client/grpcurl/*.json and of the CLI's request files), parsed strictly like grpcurl's
// server-side counterpart; one that parses goes through the same checks as
// fuzz_plan_request (harness.hpp).
#include <cstddef>
#include <cstdint>
#include <string>

#include <google/protobuf/util/json_util.h>

#include "harness.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  geotraj::fuzz::initialize();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  geotraj::v1::PlanRequest request;
  if (!google::protobuf::util::JsonStringToMessage(text, &request).ok()) return -1;
  geotraj::fuzz::check_plan_request(request);
  return 0;
}
