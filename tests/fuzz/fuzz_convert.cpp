// fuzz_convert: bytes as a binary geotraj.v1.ConvertRequest; one that parses goes through
// ConvertConstraints of the real service (harness.hpp).
#include <cstddef>
#include <cstdint>

#include "harness.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  geotraj::fuzz::initialize();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  geotraj::v1::ConvertRequest request;
  if (!request.ParseFromArray(data, static_cast<int>(size))) return -1;
  geotraj::fuzz::check_convert_request(request);
  return 0;
}
