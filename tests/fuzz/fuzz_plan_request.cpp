// fuzz_plan_request: bytes as a binary geotraj.v1.PlanRequest; one that parses goes through
// PlanTrajectory, AnalyzePath and StreamSamples of the real service (harness.hpp).
#include <cstddef>
#include <cstdint>

#include "harness.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  geotraj::fuzz::initialize();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  geotraj::v1::PlanRequest request;
  if (!request.ParseFromArray(data, static_cast<int>(size))) return -1;  // not a request: not kept in the corpus
  geotraj::fuzz::check_plan_request(request);
  return 0;
}
