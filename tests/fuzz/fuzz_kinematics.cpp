// fuzz_kinematics: the first byte picks the call (even: ComputeForwardKinematics, odd:
// ComputeInverseKinematics), the rest is its binary request; one that parses goes through
// the real service (harness.hpp).
#include <cstddef>
#include <cstdint>

#include "harness.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  geotraj::fuzz::initialize();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return -1;
  const bool inverse = (data[0] & 1u) != 0;
  const auto* body = data + 1;
  const int length = static_cast<int>(size - 1);
  if (inverse) {
    geotraj::v1::InverseKinematicsRequest request;
    if (!request.ParseFromArray(body, length)) return -1;
    geotraj::fuzz::check_kinematics_request(request);
  } else {
    geotraj::v1::ForwardKinematicsRequest request;
    if (!request.ParseFromArray(body, length)) return -1;
    geotraj::fuzz::check_kinematics_request(request);
  }
  return 0;
}
