// fuzz_live: the live calls. The first byte picks the call (even: Execute, odd: Jog), the rest
// is a run of messages, each a 2-byte little-endian length then that many bytes of a binary
// ExecuteRequest or JogRequest (at most kMaxLiveMessages; a message that does not parse ends
// the input). The first message opens the call, each later one is sent after a batch is
// read; the call is cancelled after kMaxStreamBatches batches past the last message
// (harness.hpp). Reaches the options' and commands' validation, the planning of a plan sent
// live, the robot of a jog, and the reactors' handling of any order of messages.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "harness.hpp"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  geotraj::fuzz::initialize();
  return 0;
}

namespace {

// The messages of an input, or false when one does not parse.
template <class Message>
bool messages(const std::uint8_t* data, std::size_t size, std::vector<Message>& out) {
  std::size_t at = 0;
  while (at + 2 <= size && out.size() < geotraj::fuzz::kMaxLiveMessages) {
    const std::size_t length = data[at] | (static_cast<std::size_t>(data[at + 1]) << 8);
    at += 2;
    if (length > size - at) return false;
    Message m;
    if (!m.ParseFromArray(data + at, static_cast<int>(length))) return false;
    out.push_back(std::move(m));
    at += length;
  }
  return !out.empty();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return -1;
  if ((data[0] & 1u) == 0) {
    std::vector<geotraj::v1::ExecuteRequest> run;
    if (!messages(data + 1, size - 1, run)) return -1;
    geotraj::fuzz::check_execute(run);
  } else {
    std::vector<geotraj::v1::JogRequest> run;
    if (!messages(data + 1, size - 1, run)) return -1;
    geotraj::fuzz::check_jog(run);
  }
  return 0;
}
