// The structured logger (JSON and text lines, escaping, levels, atomic lines) and request ids.
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <nlohmann/json.hpp>

#include "server/ops/log.hpp"
#include "tests/server/support/file_capture.hpp"

namespace geotraj::testing {
namespace {

using server::LogFormat;
using server::Logger;
using server::LogLevel;
using ::testing::HasSubstr;
using ::testing::MatchesRegex;

using Capture = FileCapture;

// POSIX ERE, as gmock's MatchesRegex takes it (no \d). (std::regex is avoided: GCC 12 warns
// inside it at -O1 with sanitizers, which -Werror turns into errors.)
const char* kTimestamp = "[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}[.][0-9]{3}Z";

TEST(Logger, JsonLinesCarryTheEnvelopeAndTheFields) {
  Capture out;
  const Logger logger(LogFormat::kJson, LogLevel::kInfo, out.file());
  logger.log(LogLevel::kInfo, "call",
             {{"request_id", std::string("abc")},
              {"samples", std::int64_t{-42}},
              {"duration_ms", 1.25},
              {"ok", true},
              {"nan", std::numeric_limits<double>::quiet_NaN()},
              {"inf", std::numeric_limits<double>::infinity()},
              {"msg", std::string("shadow")}});
  const auto lines = out.lines();
  ASSERT_EQ(lines.size(), 1u);
  const auto json = nlohmann::json::parse(lines[0]);
  EXPECT_THAT(json.at("ts").get<std::string>(), MatchesRegex(kTimestamp));
  EXPECT_EQ(json.at("level"), "info");
  EXPECT_EQ(json.at("msg"), "call");
  EXPECT_EQ(json.at("request_id"), "abc");
  EXPECT_EQ(json.at("samples"), -42);
  EXPECT_EQ(json.at("duration_ms"), 1.25);
  EXPECT_EQ(json.at("ok"), true);
  EXPECT_TRUE(json.at("nan").is_null());
  EXPECT_TRUE(json.at("inf").is_null());
  EXPECT_EQ(json.at("_msg"), "shadow");  // a field cannot replace the message
  // The envelope comes first, in this order.
  EXPECT_THAT(lines[0], MatchesRegex(R"(\{"ts":"[^"]+","level":"info","msg":"call",.*\})"));
}

TEST(Logger, JsonEscapesQuotesNewlinesAndControlCharacters) {
  Capture out;
  const Logger logger(LogFormat::kJson, LogLevel::kDebug, out.file());
  const std::string nasty = std::string("a\"b\\c\nd\re\tf") + '\x01' + '\x1f' + '\x7f' + std::string(1, '\0') + "g";
  const std::string utf8 = "Gelenk \xC3\xBC \xE2\x82\xAC \xF0\x9F\xA4\x96";  // ü € 🤖
  logger.log(LogLevel::kWarning, nasty, {{"text", nasty}, {"utf8", utf8}, {"bad", std::string("x\xff\xc3y")}, {"k\"ey", std::int64_t{1}}});
  const auto lines = out.lines();
  ASSERT_EQ(lines.size(), 1u);  // newlines inside values do not split the line
  // Control characters (below U+0020) are escaped; DEL is a plain character in JSON.
  EXPECT_THAT(lines[0], HasSubstr(std::string(R"("msg":"a\"b\\c\nd\re\tf\u0001\u001f)") + '\x7f' + R"(\u0000g")"));
  EXPECT_THAT(lines[0], HasSubstr("\"utf8\":\"" + utf8 + "\""));  // UTF-8 passes through unescaped
  const auto json = nlohmann::json::parse(lines[0]);
  EXPECT_EQ(json.at("level"), "warning");
  EXPECT_EQ(json.at("msg").get<std::string>(), nasty);
  EXPECT_EQ(json.at("text").get<std::string>(), nasty);
  EXPECT_EQ(json.at("utf8").get<std::string>(), utf8);
  EXPECT_EQ(json.at("bad").get<std::string>(), "x\xEF\xBF\xBD\xEF\xBF\xBDy");  // invalid bytes: U+FFFD
  EXPECT_EQ(json.at("k\"ey"), 1);
}

TEST(Logger, FiltersByLevel) {
  Capture out;
  const Logger logger(LogFormat::kJson, LogLevel::kWarning, out.file());
  EXPECT_FALSE(logger.enabled(LogLevel::kDebug));
  EXPECT_FALSE(logger.enabled(LogLevel::kInfo));
  EXPECT_TRUE(logger.enabled(LogLevel::kWarning));
  EXPECT_TRUE(logger.enabled(LogLevel::kError));
  logger.log(LogLevel::kDebug, "d");
  logger.log(LogLevel::kInfo, "i");
  logger.log(LogLevel::kWarning, "w");
  logger.log(LogLevel::kError, "e");
  const auto lines = out.lines();
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(nlohmann::json::parse(lines[0]).at("msg"), "w");
  EXPECT_EQ(nlohmann::json::parse(lines[1]).at("level"), "error");
}

TEST(Logger, TextLinesQuoteWhatNeedsIt) {
  Capture out;
  const Logger logger(LogFormat::kText, LogLevel::kDebug, out.file());
  logger.log(LogLevel::kInfo, "server listening",
             {{"address", std::string("127.0.0.1:50051")},
              {"note", std::string("quoted value")},
              {"empty", std::string()},
              {"quote", std::string("say \"hi\"\n")},
              {"n", std::int64_t{7}},
              {"x", 0.5},
              {"tls", false}});
  logger.log(LogLevel::kDebug, "two\nlines");
  const auto lines = out.lines();
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_THAT(lines[0], MatchesRegex(std::string(kTimestamp) +
                                     R"( INFO server listening address=127\.0\.0\.1:50051 note="quoted value" )"
                                     R"(empty="" quote="say \\"hi\\"\\n" n=7 x=0\.5 tls=false)"));
  EXPECT_THAT(lines[1], MatchesRegex(std::string(kTimestamp) + R"( DEBUG two\\nlines)"));
}

TEST(Logger, LinesFromManyThreadsDoNotInterleave) {
  Capture out;
  const Logger logger(LogFormat::kJson, LogLevel::kInfo, out.file());
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&logger, t] {
      for (int i = 0; i < 500; ++i) {
        logger.log(LogLevel::kInfo, "event", {{"thread", std::int64_t{t}}, {"padding", std::string(300, 'p')}});
      }
    });
  }
  for (auto& thread : threads) thread.join();
  const auto lines = out.lines();
  ASSERT_EQ(lines.size(), 2000u);
  for (const auto& line : lines) ASSERT_TRUE(nlohmann::json::accept(line)) << line;
}

TEST(Logger, IsMovable) {
  Capture out;
  Logger first(LogFormat::kText, LogLevel::kError, out.file());
  const Logger moved(std::move(first));
  EXPECT_FALSE(moved.enabled(LogLevel::kWarning));
  moved.log(LogLevel::kError, "boom");
  EXPECT_THAT(out.text(), HasSubstr(" ERROR boom\n"));
}

TEST(LogParse, FormatsAndLevels) {
  EXPECT_EQ(server::parse_log_format("text"), LogFormat::kText);
  EXPECT_EQ(server::parse_log_format("json"), LogFormat::kJson);
  ASSERT_FALSE(server::parse_log_format("xml"));
  EXPECT_EQ(server::parse_log_format("xml").error(), "unknown log format \"xml\" (expected text or json)");
  EXPECT_EQ(server::parse_log_level("debug"), LogLevel::kDebug);
  EXPECT_EQ(server::parse_log_level("info"), LogLevel::kInfo);
  EXPECT_EQ(server::parse_log_level("warning"), LogLevel::kWarning);
  EXPECT_EQ(server::parse_log_level("error"), LogLevel::kError);
  ASSERT_FALSE(server::parse_log_level("verbose"));
  EXPECT_EQ(server::parse_log_level("verbose").error(),
            "unknown log level \"verbose\" (expected debug, info, warning or error)");
}

TEST(RequestId, NewIdsAreSixteenHexCharactersAndDistinct) {
  std::set<std::string> seen;
  std::mutex mutex;
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 1000; ++i) {
        const std::string id = server::new_request_id();
        const std::lock_guard lock(mutex);
        seen.insert(id);
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(seen.size(), 4000u);
  for (const auto& id : seen) {
    ASSERT_THAT(id, MatchesRegex("[0-9a-f]{16}"));
    ASSERT_TRUE(server::valid_request_id(id));
  }
}

TEST(RequestId, ValidatesClientIds) {
  EXPECT_TRUE(server::valid_request_id("a"));
  EXPECT_TRUE(server::valid_request_id("Req-1.2_3"));
  EXPECT_TRUE(server::valid_request_id(std::string(64, 'x')));
  EXPECT_FALSE(server::valid_request_id(""));
  EXPECT_FALSE(server::valid_request_id(std::string(65, 'x')));
  EXPECT_FALSE(server::valid_request_id("has space"));
  EXPECT_FALSE(server::valid_request_id("quote\""));
  EXPECT_FALSE(server::valid_request_id("line\nbreak"));
  EXPECT_FALSE(server::valid_request_id("\xC3\xBC"));
}

}  // namespace
}  // namespace geotraj::testing
