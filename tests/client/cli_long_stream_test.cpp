// `geotraj stream` of a real-time motion longer than the CLI's 60 s unary deadline: without
// --timeout a stream has no deadline, so the motion arrives whole (61 s; label slow).
#include <sys/wait.h>

#include <cstdio>
#include <string>

#include <gmock/gmock.h>

#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

class CliLongStream : public ServerTest {};

TEST_F(CliLongStream, AStreamLongerThanAMinuteIsNotCut) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(61.0);
  request.mutable_motion()->set_cycle_rate_hz(2.0);  // 123 samples over 61 s
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  std::string json;
  ASSERT_TRUE(google::protobuf::util::MessageToJsonString(request, &json).ok());
  const std::string path = ::testing::TempDir() + "/geotraj_long_stream.json";
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fputs(json.c_str(), f);
  std::fclose(f);
  const std::string command = std::string("'") + build_paths::cli() + "' --server " + address_ + " stream " + path + " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  int lines = 0;
  std::string last;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe)) {
    ++lines;
    last = buffer;
  }
  const int status = ::pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << last;
  EXPECT_EQ(lines, 1 + 123) << "header and every sample; last line: " << last;
  EXPECT_THAT(last, ::testing::StartsWith("61,"));
  std::remove(path.c_str());
}

}  // namespace
}  // namespace geotraj::testing
