// Metrics exposition (series, counts under concurrency, escaping, promtool) and the HTTP
// exporter that serves it, spoken to over raw sockets.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>

#include "server/ops/http_exporter.hpp"
#include "server/ops/metrics.hpp"
#include "tests/server/support/raw_sockets.hpp"

namespace geotraj::testing {
namespace {

using server::HttpExporter;
using server::Metrics;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

// ---------------------------------------------------------------------------------------
// Metrics

// The value of the sample line `series` (name with labels, exactly as printed), or -1.
double sample(const std::string& exposition, const std::string& series) {
  std::istringstream lines(exposition);
  for (std::string line; std::getline(lines, line);) {
    if (line.size() > series.size() && line.compare(0, series.size(), series) == 0 && line[series.size()] == ' ') {
      return std::stod(line.substr(series.size() + 1));
    }
  }
  return -1;
}

TEST(Metrics, FreshExpositionHasTheUnlabelledSeriesAndEveryHeader) {
  const Metrics metrics;
  const std::string text = metrics.exposition();
  for (const char* family : {"geotraj_rpc_calls_total", "geotraj_rpc_duration_seconds", "geotraj_rpc_rejected_total",
                             "geotraj_active_streams", "geotraj_active_unary_calls", "geotraj_samples_streamed_total",
                             "geotraj_optimization_duration_seconds", "geotraj_build_info",
                             "process_start_time_seconds"}) {
    EXPECT_THAT(text, HasSubstr(std::string("# HELP ") + family + " ")) << family;
    EXPECT_THAT(text, HasSubstr(std::string("# TYPE ") + family + " ")) << family;
  }
  EXPECT_THAT(text, HasSubstr("# TYPE geotraj_rpc_duration_seconds histogram\n"));
  EXPECT_THAT(text, HasSubstr("# TYPE geotraj_rpc_calls_total counter\n"));
  EXPECT_EQ(sample(text, "geotraj_active_streams"), 0);
  EXPECT_EQ(sample(text, "geotraj_active_unary_calls"), 0);
  EXPECT_EQ(sample(text, "geotraj_samples_streamed_total"), 0);
  EXPECT_EQ(sample(text, "geotraj_build_info{version=\"" + std::string(server::kGeotrajVersion) + "\"}"), 1);
  const double start = sample(text, "process_start_time_seconds");
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  EXPECT_GT(start, now - 60);
  EXPECT_LE(start, now + 1);
  EXPECT_THAT(text, Not(HasSubstr("geotraj_rpc_calls_total{")));
  EXPECT_EQ(text.back(), '\n');
}

TEST(Metrics, RecordsCallsRejectionsSamplesAndOptimisations) {
  Metrics metrics;
  metrics.call_started("PlanTrajectory", false);
  metrics.call_started("StreamSamples", true);
  metrics.call_started("StreamSamples", true);
  {
    const std::string text = metrics.exposition();
    EXPECT_EQ(sample(text, "geotraj_active_streams"), 2);
    EXPECT_EQ(sample(text, "geotraj_active_unary_calls"), 1);
  }
  metrics.call_finished("PlanTrajectory", false, 0, 0.003);
  metrics.call_finished("StreamSamples", true, 3, 0.2);
  metrics.call_finished("StreamSamples", true, 99, 100.0);  // out of range: UNKNOWN; beyond the last bucket
  metrics.rejected("StreamSamples", "capacity");
  metrics.rejected("StreamSamples", "capacity");
  metrics.rejected("PlanTrajectory", "unauthenticated");
  metrics.samples_streamed(1000);
  metrics.samples_streamed(24);
  metrics.optimization("tangent_scales", 1.5);

  const std::string text = metrics.exposition();
  EXPECT_EQ(sample(text, "geotraj_active_streams"), 0);
  EXPECT_EQ(sample(text, "geotraj_active_unary_calls"), 0);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_calls_total{method="PlanTrajectory",code="OK"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_calls_total{method="StreamSamples",code="INVALID_ARGUMENT"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_calls_total{method="StreamSamples",code="UNKNOWN"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_calls_total{method="StreamSamples",code="OK"})"), -1);  // never seen
  // Buckets are cumulative: 0.003 s is in le=0.005 but not in le=0.0025.
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="PlanTrajectory",le="0.0025"})"), 0);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="PlanTrajectory",le="0.005"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="PlanTrajectory",le="+Inf"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="StreamSamples",le="0.0005"})"), 0);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="StreamSamples",le="0.25"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="StreamSamples",le="60"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="StreamSamples",le="+Inf"})"), 2);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_count{method="StreamSamples"})"), 2);
  EXPECT_DOUBLE_EQ(sample(text, R"(geotraj_rpc_duration_seconds_sum{method="StreamSamples"})"), 100.2);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_rejected_total{method="StreamSamples",reason="capacity"})"), 2);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_rejected_total{method="PlanTrajectory",reason="unauthenticated"})"), 1);
  EXPECT_EQ(sample(text, "geotraj_samples_streamed_total"), 1024);
  EXPECT_EQ(sample(text, R"(geotraj_optimization_duration_seconds_bucket{kind="tangent_scales",le="1"})"), 0);
  EXPECT_EQ(sample(text, R"(geotraj_optimization_duration_seconds_bucket{kind="tangent_scales",le="2.5"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_optimization_duration_seconds_count{kind="tangent_scales"})"), 1);
  EXPECT_EQ(sample(text, R"(geotraj_optimization_duration_seconds_sum{kind="tangent_scales"})"), 1.5);
}

TEST(Metrics, AValueOnABucketBoundIsInThatBucket) {
  Metrics metrics;
  metrics.call_started("ListRobots", false);
  metrics.call_finished("ListRobots", false, 0, 0.001);
  const std::string text = metrics.exposition();
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="ListRobots",le="0.0005"})"), 0);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="ListRobots",le="0.001"})"), 1);
}

TEST(Metrics, EscapesLabelValues) {
  Metrics metrics;
  metrics.rejected("Odd\"Method\\\nName", "limit");
  metrics.optimization("bad\xff", 0.01);  // invalid UTF-8 becomes U+FFFD
  const std::string text = metrics.exposition();
  EXPECT_THAT(text, HasSubstr(R"(geotraj_rpc_rejected_total{method="Odd\"Method\\\nName",reason="limit"} 1)"));
  EXPECT_THAT(text, HasSubstr("kind=\"bad\xEF\xBF\xBD\""));
}

TEST(Metrics, CountsAreExactUnderConcurrentUpdates) {
  Metrics metrics;
  constexpr int kThreads = 8;
  constexpr int kCalls = 5000;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&metrics, t] {
      const bool streaming = t % 2 == 0;
      const char* method = streaming ? "StreamSamples" : "PlanTrajectory";
      for (int i = 0; i < kCalls; ++i) {
        metrics.call_started(method, streaming);
        if (streaming) metrics.samples_streamed(3);
        if (i % 10 == 0) metrics.rejected(method, "capacity");
        if (i % 100 == 0) (void)metrics.exposition();  // readers run alongside writers
        metrics.call_finished(method, streaming, i % 2 == 0 ? 0 : 8, 0.001 * (i % 7));
      }
    });
  }
  for (auto& thread : threads) thread.join();
  const std::string text = metrics.exposition();
  const double per_method = kThreads / 2 * kCalls;
  EXPECT_EQ(sample(text, R"(geotraj_rpc_calls_total{method="StreamSamples",code="OK"})"), per_method / 2);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_calls_total{method="StreamSamples",code="RESOURCE_EXHAUSTED"})"),
            per_method / 2);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_calls_total{method="PlanTrajectory",code="OK"})"), per_method / 2);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_count{method="PlanTrajectory"})"), per_method);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_duration_seconds_bucket{method="PlanTrajectory",le="+Inf"})"), per_method);
  EXPECT_EQ(sample(text, R"(geotraj_rpc_rejected_total{method="StreamSamples",reason="capacity"})"), per_method / 10);
  EXPECT_EQ(sample(text, "geotraj_samples_streamed_total"), 3 * per_method);
  EXPECT_EQ(sample(text, "geotraj_active_streams"), 0);
  EXPECT_EQ(sample(text, "geotraj_active_unary_calls"), 0);
}

// A realistic exposition: every family with series, as promtool should see it.
std::string busy_exposition() {
  Metrics metrics;
  const char* methods[] = {"ConvertConstraints", "PlanTrajectory", "StreamSamples", "AnalyzePath", "ListRobots"};
  for (int i = 0; i < 50; ++i) {
    const char* method = methods[i % 5];
    const bool streaming = i % 5 == 2;
    metrics.call_started(method, streaming);
    metrics.call_finished(method, streaming, i % 17, 0.0001 * i * i);
  }
  metrics.call_started("StreamSamples", true);  // one still in flight
  for (const char* reason : {"capacity", "draining", "unauthenticated", "permission_denied", "limit"}) {
    metrics.rejected("PlanTrajectory", reason);
  }
  metrics.samples_streamed(123456);
  for (const char* kind : {"tangent_scales", "breakpoints", "time_optimal", "time_optimal_jerk"}) {
    metrics.optimization(kind, 0.42);
  }
  return metrics.exposition();
}

TEST(Metrics, PromtoolAcceptsTheExpositionWithoutWarnings) {
#ifndef GEOTRAJ_PROMTOOL
  GTEST_SKIP() << "promtool was not found at configure time (apt-get install prometheus)";
#else
  const auto dir = std::filesystem::temp_directory_path();
  const auto input = dir / ("geotraj_metrics_" + std::to_string(::getpid()) + ".txt");
  const auto output = dir / ("geotraj_promtool_" + std::to_string(::getpid()) + ".txt");
  std::ofstream(input) << busy_exposition();
  const std::string command = std::string("'") + GEOTRAJ_PROMTOOL + "' check metrics < '" + input.string() + "' > '" +
                              output.string() + "' 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream in(output);
  const std::string said((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::filesystem::remove(input);
  std::filesystem::remove(output);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << said;
  EXPECT_EQ(said, "");
#endif
}

// ---------------------------------------------------------------------------------------
// HttpExporter

void send_all(int fd, const std::string& data) {
  std::size_t sent = 0;
  while (sent < data.size()) {
    const ssize_t n = ::send(fd, data.data() + sent, data.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return;
    sent += static_cast<std::size_t>(n);
  }
}

// Everything the server sends until it closes (or 5 s pass; `closed` says which).
std::string read_all(int fd, bool* closed = nullptr) {
  std::string out;
  char buffer[4096];
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  if (closed != nullptr) *closed = false;
  while (std::chrono::steady_clock::now() < until) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) {
      if (closed != nullptr) *closed = true;
      break;
    }
    out.append(buffer, static_cast<std::size_t>(n));
  }
  return out;
}

std::string exchange(int port, const std::string& request) {
  const int fd = connect_loopback(port);
  if (fd < 0) return "connect failed";
  send_all(fd, request);
  std::string response = read_all(fd);
  ::close(fd);
  return response;
}

std::string body_of(const std::string& response) {
  const auto end = response.find("\r\n\r\n");
  return end == std::string::npos ? "" : response.substr(end + 4);
}

class Exporter : public ::testing::Test {
 protected:
  void SetUp() override {
    auto started = HttpExporter::start("127.0.0.1:0", [] { return std::string("geotraj_up 1\n"); });
    ASSERT_TRUE(started) << started.error();
    exporter_ = std::move(*started);
    ASSERT_GT(exporter_->port(), 0);
  }
  std::unique_ptr<HttpExporter> exporter_;
};

TEST_F(Exporter, ServesMetrics) {
  const std::string response = exchange(exporter_->port(), "GET /metrics HTTP/1.1\r\nHost: x\r\nAccept: */*\r\n\r\n");
  EXPECT_THAT(response, StartsWith("HTTP/1.1 200 OK\r\n"));
  EXPECT_THAT(response, HasSubstr("\r\nContent-Type: text/plain; version=0.0.4; charset=utf-8\r\n"));
  EXPECT_THAT(response, HasSubstr("\r\nContent-Length: 13\r\n"));
  EXPECT_EQ(body_of(response), "geotraj_up 1\n");
}

TEST_F(Exporter, ServesARealExpositionWithAQueryAndHttp10) {
  Metrics metrics;
  metrics.samples_streamed(7);
  auto started = HttpExporter::start("127.0.0.1:0", [&metrics] { return metrics.exposition(); });
  ASSERT_TRUE(started) << started.error();
  const std::string response = exchange((*started)->port(), "GET /metrics?x=1 HTTP/1.0\r\n\r\n");
  EXPECT_THAT(response, StartsWith("HTTP/1.1 200 OK\r\n"));
  EXPECT_EQ(body_of(response), metrics.exposition());
  EXPECT_THAT(body_of(response), HasSubstr("geotraj_samples_streamed_total 7\n"));
}

TEST_F(Exporter, ServesHealthz) {
  const std::string response = exchange(exporter_->port(), "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_THAT(response, StartsWith("HTTP/1.1 200 OK\r\n"));
  EXPECT_EQ(body_of(response), "ok");
}

TEST_F(Exporter, AnswersOtherPathsWith404) {
  EXPECT_THAT(exchange(exporter_->port(), "GET / HTTP/1.1\r\n\r\n"), StartsWith("HTTP/1.1 404 Not Found\r\n"));
  EXPECT_THAT(exchange(exporter_->port(), "GET /metricsx HTTP/1.1\r\n\r\n"), StartsWith("HTTP/1.1 404 "));
}

TEST_F(Exporter, AnswersOtherMethodsWith405) {
  const std::string response = exchange(exporter_->port(), "POST /metrics HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
  EXPECT_THAT(response, StartsWith("HTTP/1.1 405 Method Not Allowed\r\n"));
  EXPECT_THAT(response, HasSubstr("\r\nAllow: GET, HEAD\r\n"));
  EXPECT_THAT(exchange(exporter_->port(), "DELETE /healthz HTTP/1.1\r\n\r\n"), StartsWith("HTTP/1.1 405 "));
}

TEST_F(Exporter, AnswersHeadWithTheHeadersOnly) {
  const std::string response = exchange(exporter_->port(), "HEAD /metrics HTTP/1.1\r\n\r\n");
  EXPECT_THAT(response, StartsWith("HTTP/1.1 200 OK\r\n"));
  EXPECT_THAT(response, HasSubstr("\r\nContent-Length: 13\r\n"));
  EXPECT_EQ(body_of(response), "");
}

TEST_F(Exporter, AnswersMalformedRequestsWith400) {
  for (const char* request : {"GARBAGE\r\n\r\n", "GET /metrics\r\n\r\n", "GET /metrics HTTP/2.0\r\n\r\n",
                              "GET metrics HTTP/1.1\r\n\r\n", "GET  /metrics HTTP/1.1\r\n\r\n",
                              "GET /metrics HTTP/1.1\r\nno colon here\r\n\r\n",
                              "GET /metrics HTTP/1.1\r\nBad Name: x\r\n\r\n", "G(T /metrics HTTP/1.1\r\n\r\n",
                              "GET /metrics HTTP/1.1\r\nName : x\r\n\r\n", "GET /healthz HTTP/1.1\n\n",
                              // fuzz_http_head's finding: a tab before the method (cpp-httplib skipped it)
                              "\tHEAD /healthz?x=1 HTTP/1.0\r\n\r\n", " GET /metrics HTTP/1.1\r\n\r\n"}) {
    EXPECT_THAT(exchange(exporter_->port(), request), StartsWith("HTTP/1.1 400 Bad Request\r\n")) << request;
  }
}

TEST_F(Exporter, AnswersOversizedHeadersWith400AndCloses) {
  // More than 8 KiB without the end of the headers: refused without waiting for the rest.
  const std::string request = "GET /metrics HTTP/1.1\r\nX-Long: " + std::string(9000, 'a');
  const int fd = connect_loopback(exporter_->port());
  ASSERT_GE(fd, 0);
  send_all(fd, request);
  const std::string response = read_all(fd);  // returns when the server closes
  ::close(fd);
  EXPECT_THAT(response, StartsWith("HTTP/1.1 400 Bad Request\r\n"));
  // A complete block of just under the limit is served.
  const std::string fits = "GET /healthz HTTP/1.1\r\nX-Long: " + std::string(8000, 'a') + "\r\n\r\n";
  EXPECT_THAT(exchange(exporter_->port(), fits), StartsWith("HTTP/1.1 200 OK\r\n"));
}

// The limits below are chosen so that the behaviour under test is the only way to pass:
// with a 60 s timeout, an answer within exchange()'s 5 s can only come from multiplexing
// or eviction, never from the silent client's timeout.
server::HttpExporterOptions patient(std::size_t max_connections = 512) {
  server::HttpExporterOptions options;
  options.timeout = std::chrono::seconds(60);
  options.max_connections = max_connections;
  return options;
}

// 32 clients that send half a request line and then nothing: four times cpp-httplib's own
// thread pool, which they would hold for as long as they keep sending now and then.
TEST(ExporterLimits, SilentClientsDoNotBlockOthers) {
  auto started = HttpExporter::start("127.0.0.1:0", [] { return std::string("m\n"); }, patient());
  ASSERT_TRUE(started) << started.error();
  std::vector<int> silent;
  for (int i = 0; i < 32; ++i) {
    silent.push_back(connect_loopback((*started)->port()));
    ASSERT_GE(silent.back(), 0);
    send_all(silent.back(), "GET /met");
  }
  EXPECT_THAT(exchange((*started)->port(), "GET /healthz HTTP/1.1\r\n\r\n"), StartsWith("HTTP/1.1 200 OK\r\n"));
  for (int fd : silent) ::close(fd);
}

TEST(ExporterLimits, ClosesAStalledConnectionAfterTheTimeout) {
  server::HttpExporterOptions options;
  options.timeout = std::chrono::milliseconds(200);
  auto started = HttpExporter::start("127.0.0.1:0", [] { return std::string(); }, options);
  ASSERT_TRUE(started) << started.error();
  const int fd = connect_loopback((*started)->port());
  ASSERT_GE(fd, 0);
  const auto begin = std::chrono::steady_clock::now();
  bool closed = false;
  const std::string response = read_all(fd, &closed);  // EOF when the server gives up
  const auto waited = std::chrono::steady_clock::now() - begin;
  ::close(fd);
  EXPECT_EQ(response, "");
  EXPECT_TRUE(closed) << "still open 5 s after a 200 ms timeout";
  EXPECT_GE(waited, std::chrono::milliseconds(150)) << "closed before the timeout";  // deadlines never fire early
}

TEST(ExporterLimits, ServesOneConnectionAtATimeWhenCappedAtOne) {
  auto started = HttpExporter::start("127.0.0.1:0", [] { return std::string("m\n"); }, patient(1));
  ASSERT_TRUE(started) << started.error();
  const int silent = connect_loopback((*started)->port());
  ASSERT_GE(silent, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  // The new connection closes the silent one (the oldest) and is served (not after the 60 s).
  EXPECT_THAT(exchange((*started)->port(), "GET /metrics HTTP/1.1\r\n\r\n"), StartsWith("HTTP/1.1 200 OK\r\n"));
  bool closed = false;
  EXPECT_EQ(read_all(silent, &closed), "");
  EXPECT_TRUE(closed);
  ::close(silent);
}

// 64 clients trickling a byte every 100 ms, four times as many as the slots: scrapes are
// answered meanwhile (before, they waited in the backlog behind the trickling clients, up to
// 6-9 s with 200 clients, past Prometheus's 10 s scrape timeout for some).
TEST(ExporterLimits, TricklingClientsDoNotHoldOffScrapes) {
  // Trickling clients are never timed out here (60 s): only the cap makes room for scrapes.
  auto started = HttpExporter::start("127.0.0.1:0", [] { return std::string("m\n"); }, patient(16));
  ASSERT_TRUE(started) << started.error();
  const int port = (*started)->port();
  std::atomic<bool> done{false};
  std::thread trickle([&] {
    std::vector<int> fds;
    for (int i = 0; i < 64; ++i) fds.push_back(connect_loopback(port));
    const std::string request = "GET /metrics HTTP/1.1\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\r\n\r\n";
    for (std::size_t k = 0; !done.load() && k < request.size(); ++k) {
      for (int& fd : fds) {
        if (fd >= 0 && ::send(fd, &request[k], 1, MSG_NOSIGNAL) != 1) {  // closed by the server: reconnect
          ::close(fd);
          fd = connect_loopback(port);
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    for (int fd : fds) {
      if (fd >= 0) ::close(fd);
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  // A scrape connects, then sends: on a loaded machine its request can arrive after 16
  // tricklers that reconnected since, and a connection polled without a request is what
  // makes room for them (the exporter cannot tell it from a trickler). A scraper then asks
  // again, as Prometheus does at its next interval: each scrape is answered within 3 tries.
  double slowest = 0.0;
  int tries = 0;
  for (int i = 0; i < 10; ++i) {
    const auto begin = std::chrono::steady_clock::now();
    std::string answer;
    for (int attempt = 0; attempt < 3 && answer.empty(); ++attempt, ++tries) {
      answer = exchange(port, "GET /metrics HTTP/1.1\r\n\r\n");
    }
    EXPECT_THAT(answer, StartsWith("HTTP/1.1 200 OK\r\n")) << "scrape " << i;
    slowest = std::max(slowest, std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count());
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  done = true;
  trickle.join();
  std::printf("[ measured ] slowest of 10 scrapes among 64 trickling clients: %.1f ms (%d connections)\n",
              slowest * 1e3, tries);
}

TEST(ExporterLimits, StopDoesNotWaitForOpenConnections) {
  auto started = HttpExporter::start("127.0.0.1:0", [] { return std::string("m\n"); }, patient());
  ASSERT_TRUE(started) << started.error();
  HttpExporter& exporter = **started;
  const int idle = connect_loopback(exporter.port());
  ASSERT_GE(idle, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  // A stop that waited for the idle connection's 60 s timeout would not close it within the
  // 5 s that read_all waits.
  std::thread stopping([&exporter] { exporter.stop(); });
  bool closed = false;
  EXPECT_EQ(read_all(idle, &closed), "");
  EXPECT_TRUE(closed) << "stop() did not close the open connection";
  stopping.join();
  ::close(idle);
  exporter.stop();  // idempotent
  EXPECT_EQ(connect_loopback(exporter.port()), -1);  // the port is free again
}

TEST(ExporterStart, NamesTheAddressWhenThePortIsTaken) {
  auto first = HttpExporter::start("127.0.0.1:0", [] { return std::string(); });
  ASSERT_TRUE(first) << first.error();
  const std::string address = "127.0.0.1:" + std::to_string((*first)->port());
  auto second = HttpExporter::start(address, [] { return std::string(); });
  ASSERT_FALSE(second);
  EXPECT_EQ(second.error(), "cannot listen on metrics address \"" + address + "\": Address already in use");
}

TEST(ExporterStart, RejectsMalformedAddresses) {
  for (const char* address : {"", "9090", "127.0.0.1:", "127.0.0.1:http", "127.0.0.1:70000", "::1:9090", "[::1]9090"}) {
    auto started = HttpExporter::start(address, [] { return std::string(); });
    ASSERT_FALSE(started) << address;
    EXPECT_THAT(started.error(), HasSubstr(std::string("metrics address \"") + address + "\"")) << started.error();
  }
  auto unresolvable = HttpExporter::start("no-such-host.invalid:9090", [] { return std::string(); });
  ASSERT_FALSE(unresolvable);
  EXPECT_THAT(unresolvable.error(), StartsWith("cannot resolve metrics address \"no-such-host.invalid:9090\": "));
}

TEST(ExporterStart, ListensOnHostNamesAndIpv6) {
  auto by_name = HttpExporter::start("localhost:0", [] { return std::string(); });
  ASSERT_TRUE(by_name) << by_name.error();
  EXPECT_GT((*by_name)->port(), 0);
  auto any = HttpExporter::start(":0", [] { return std::string("x\n"); });
  ASSERT_TRUE(any) << any.error();
  // Every address includes IPv4 loopback (dual-stack [::] or 0.0.0.0).
  EXPECT_THAT(exchange((*any)->port(), "GET /healthz HTTP/1.1\r\n\r\n"), StartsWith("HTTP/1.1 200 OK\r\n"));
  auto v6 = HttpExporter::start("[::1]:0", [] { return std::string(); });
  if (!v6) GTEST_SKIP() << "no IPv6 loopback here: " << v6.error();
  EXPECT_GT((*v6)->port(), 0);
}

}  // namespace
}  // namespace geotraj::testing
