// The service under faults: a client that cancels mid-stream, a reader that stalls, passed
// deadlines (a real-time stream, a breakpoint optimisation), malformed bytes (a request that
// is not a protobuf message, TCP connections that do not speak HTTP/2), and SIGTERM to
// geotrajd while streams are in flight. After each, the server's gauges return to 0 and it
// still serves.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <future>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/support/byte_buffer.h>

#include "tests/server/support/daemon.hpp"
#include "tests/reliability/reliability.hpp"
#include "tests/server/support/raw_sockets.hpp"

namespace geotraj::testing {
namespace {

using ::testing::AnyOf;
using ::testing::HasSubstr;
using std::chrono::milliseconds;
using std::chrono::seconds;

std::chrono::system_clock::time_point in(std::chrono::milliseconds d) { return std::chrono::system_clock::now() + d; }

class FaultTest : public ServerTest {
 protected:
  double gauge(const std::string& name) { return metric(server::metrics_exposition(running_), name).value_or(-1.0); }

  // The active streams / unary calls gauge reaches 0 within `timeout`.
  bool back_to_idle(const std::string& name, std::chrono::steady_clock::duration timeout = seconds(5)) {
    return eventually([&] { return gauge(name) == 0.0; }, timeout);
  }

  // A plan that must succeed: the server still serves.
  void expect_serves() {
    v1::PlanResponse response;
    const auto status = plan(demo_request('a'), response);
    EXPECT_TRUE(status.ok()) << status.error_code() << " " << status.error_message();
    EXPECT_EQ(response.motion().sample_count(), 1001u);
  }
};

// (a) The client cancels after 1,000 of 360,001 samples: it sees CANCELLED, the server
// stops the stream (the gauge returns to 0) and counts it as cancelled.
TEST_F(FaultTest, ClientCancelsMidStream) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(3600.0);
  request.set_samples_per_batch(100);
  Latch latch(1);
  StreamReader reader(*stub_, request, in(seconds(60)), /*cancel_after=*/1000);
  reader.start([&latch] { latch.count_down(); });
  ASSERT_TRUE(latch.wait(seconds(60)));
  EXPECT_EQ(reader.status().error_code(), grpc::StatusCode::CANCELLED) << reader.status().error_message();
  EXPECT_GE(reader.received(), 1000u);
  EXPECT_LT(reader.received(), 360001u);
  EXPECT_TRUE(back_to_idle("geotraj_active_streams")) << server::metrics_exposition(running_);
  EXPECT_TRUE(eventually(
      [&] { return calls_total(server::metrics_exposition(running_), "StreamSamples", "CANCELLED") == 1.0; },
      seconds(5)));
  expect_serves();
}

// The same while a real-time stream waits for its next sample (an alarm is pending).
TEST_F(FaultTest, ClientCancelsARealTimeStreamWhileItWaits) {
  auto request = demo_request('a');
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  Latch latch(1);
  StreamReader reader(*stub_, request, in(seconds(60)), /*cancel_after=*/20);  // ~0.2 s in
  const auto started = std::chrono::steady_clock::now();
  reader.start([&latch] { latch.count_down(); });
  ASSERT_TRUE(latch.wait(seconds(30)));
  EXPECT_EQ(reader.status().error_code(), grpc::StatusCode::CANCELLED) << reader.status().error_message();
  EXPECT_LT(reader.received(), 1001u) << "the whole 10 s motion came";
  std::printf("[ figure   ] cancelled after %zu samples, %.3f s\n", reader.received(), seconds_since(started));
  EXPECT_TRUE(back_to_idle("geotraj_active_streams")) << server::metrics_exposition(running_);
  expect_serves();
}

// (b) A client starts 600,001 samples (~85 MB of messages) as fast as possible and reads
// nothing for 2 s. The server has one write in flight per stream and gRPC's flow control
// stops it once the windows are full: it neither buffers the motion nor computes ahead.
// Then the client reads everything, complete and in order.
TEST_F(FaultTest, StalledReaderDoesNotGrowServerMemory) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(600.0);
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  constexpr std::size_t kSamples = 600001;
  {  // warm up: one small stream, so that the measurement sees the stall, not first use
    grpc::Status status;
    EXPECT_EQ(stream_all(demo_request('a'), status).size(), 1001u);
  }
  const long long before = trimmed_rss_bytes();
  const double streamed_before = metric(server::metrics_exposition(running_), "geotraj_samples_streamed_total").value_or(0);

  auto context = ServerTest::context();
  auto stream = stub_->StreamSamples(context.get(), request);
  std::this_thread::sleep_for(seconds(2));
  const long long stalled = trimmed_rss_bytes();
  const double written =
      metric(server::metrics_exposition(running_), "geotraj_samples_streamed_total").value_or(0) - streamed_before;
  std::printf("[ figure   ] stalled reader: rss %.1f MB -> %.1f MB, %.0f of %zu samples written\n", megabytes(before),
              megabytes(stalled), written, kSamples);
  RecordProperty("stalled_rss_growth_kb", std::to_string((stalled - before) / 1024));
  RecordProperty("stalled_samples_written", std::to_string(static_cast<long long>(written)));
  // Bound: 16 MB. The whole motion serialized is ~85 MB (149 bytes a sample); what may be
  // held is what gRPC's flow-control windows let through (measured: 28,160 samples, ~4 MB,
  // RSS +4.1 to +4.5 MB in Release) on both ends of the in-process connection, plus one batch.
  // Under AddressSanitizer the resident set counts its redzones and quarantine (+22 MB
  // measured for the same 28,160 samples): only the samples written are checked there.
  if (!kAddressSanitizer) {
    EXPECT_LT(stalled - before, 16ll * 1024 * 1024)
        << "RSS grew from " << megabytes(before) << " MB to " << megabytes(stalled) << " MB";
  }
  EXPECT_LT(written, kSamples / 10.0) << "the server ran ahead of its reader";

  v1::SampleBatch batch;
  std::size_t received = 0;
  bool in_order = true;
  double last_t = -1.0;
  std::size_t bytes = 0;
  while (stream->Read(&batch)) {
    bytes += batch.ByteSizeLong();
    for (const auto& sample : batch.samples()) {
      in_order = in_order && sample.t() > last_t;
      last_t = sample.t();
      ++received;
    }
  }
  const auto status = stream->Finish();
  EXPECT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(received, kSamples);
  std::printf("[ figure   ] the whole motion: %.1f MB serialized, %.0f bytes a sample\n", megabytes(static_cast<long long>(bytes)),
              static_cast<double>(bytes) / static_cast<double>(std::max<std::size_t>(received, 1)));
  EXPECT_TRUE(in_order);
  EXPECT_TRUE(back_to_idle("geotraj_active_streams"));
}

// (c) A real-time stream of a 10 s motion with a 200 ms deadline ends DEADLINE_EXCEEDED
// at once (the pending alarm is cancelled), and the server lets go of it.
TEST_F(FaultTest, StreamDeadlinePasses) {
  auto request = demo_request('a');
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  Latch latch(1);
  StreamReader reader(*stub_, request, in(milliseconds(200)));
  const auto started = std::chrono::steady_clock::now();
  reader.start([&latch] { latch.count_down(); });
  ASSERT_TRUE(latch.wait(seconds(30)));
  const double elapsed = seconds_since(started);
  EXPECT_EQ(reader.status().error_code(), grpc::StatusCode::DEADLINE_EXCEEDED) << reader.status().error_message();
  EXPECT_GT(reader.received(), 0u);
  EXPECT_LT(reader.received(), 100u);  // ~0.2 s of a 100 Hz stream
  // The motion lasts 10 s: idle within 5 s of the deadline means the server let go of it.
  EXPECT_TRUE(back_to_idle("geotraj_active_streams", seconds(5))) << server::metrics_exposition(running_);
  const auto text = server::metrics_exposition(running_);
  // The server counts it as the client sees it (gRPC also cancels the call at the deadline).
  EXPECT_EQ(calls_total(text, "StreamSamples", "DEADLINE_EXCEEDED"), 1.0) << text;
  EXPECT_EQ(calls_total(text, "StreamSamples", "CANCELLED"), 0.0) << text;
  std::printf("[ figure   ] stream deadline: client status after %.3f s; server counted DEADLINE_EXCEEDED %g, "
              "CANCELLED %g\n",
              elapsed, calls_total(text, "StreamSamples", "DEADLINE_EXCEEDED"),
              calls_total(text, "StreamSamples", "CANCELLED"));
  expect_serves();
}

// A breakpoint optimisation (Appendix B, peak torsion) with a 100 ms deadline: the client
// has DEADLINE_EXCEEDED, and the server stops optimising promptly (its unary gauge is 0
// within 1 s of the deadline) instead of finishing work no one waits for.
TEST_F(FaultTest, OptimisationDeadlinePasses) {
  // Left alone, this optimisation runs 10 s (its budget here: measured in optimize_test);
  // the server must let go of it within 5 s of the 100 ms deadline, not at the end.
  auto request = example<v1::PlanRequest>("appendix_b_optimized.json");
  request.mutable_optimize()->set_time_budget_s(10.0);
  grpc::ClientContext context;
  context.set_deadline(in(milliseconds(100)));
  v1::PlanResponse response;
  const auto started = std::chrono::steady_clock::now();
  const auto status = stub_->PlanTrajectory(&context, request, &response);
  const double client_s = seconds_since(started);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED) << status.error_message();
  EXPECT_TRUE(back_to_idle("geotraj_active_unary_calls", seconds(5))) << server::metrics_exposition(running_);
  const double server_s = seconds_since(started);
  const auto text = server::metrics_exposition(running_);
  EXPECT_EQ(calls_total(text, "PlanTrajectory", "DEADLINE_EXCEEDED"), 1.0) << text;
  EXPECT_EQ(calls_total(text, "PlanTrajectory", "CANCELLED"), 0.0) << text;
  std::printf("[ figure   ] optimisation deadline: client status after %.3f s, server idle after %.3f s; server "
              "counted DEADLINE_EXCEEDED %g, CANCELLED %g\n",
              client_s, server_s, calls_total(text, "PlanTrajectory", "DEADLINE_EXCEEDED"),
              calls_total(text, "PlanTrajectory", "CANCELLED"));
  expect_serves();
}

// (d) Bytes that are not a PlanRequest, through the generic stub: INVALID_ARGUMENT naming
// the message type (the service takes its requests as bytes and parses them itself; gRPC's
// own callback handlers would answer UNIMPLEMENTED with an empty message), counted in the
// metrics; and the server still serves.
std::vector<std::pair<std::string, std::string>> garbage_messages() {
  return {
      {"truncated length-delimited field", std::string("\x0a\x64\x01\x02", 4)},         // path: 100 bytes, 2 given
      {"invalid wire type 7", std::string("\x0f\x01\x02\x03", 4)},                       // field 1, wire type 7
      {"unterminated varint", std::string("\x10\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff", 11)},
      {"end-group without start", std::string("\x0c", 1)},
  };
}

grpc::ByteBuffer buffer_of(const std::string& bytes) {
  grpc::Slice slice(bytes);
  return grpc::ByteBuffer(&slice, 1);
}

grpc::Status generic_plan(grpc::GenericStub& generic, const std::string& bytes, grpc::ByteBuffer& response) {
  grpc::ClientContext context;
  context.set_deadline(in(seconds(30)));
  const auto request = buffer_of(bytes);
  std::promise<grpc::Status> done;
  generic.UnaryCall(&context, "/geotraj.v1.TrajectoryService/PlanTrajectory", grpc::StubOptions(), &request,
                    &response, [&done](grpc::Status s) { done.set_value(std::move(s)); });
  return done.get_future().get();
}

TEST_F(FaultTest, GarbagePlanRequestIsRefused) {
  grpc::GenericStub generic(channel_);
  for (const auto& [what, bytes] : garbage_messages()) {
    grpc::ByteBuffer response;
    const auto status = generic_plan(generic, bytes, response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << what << ": " << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr("geotraj.v1.PlanRequest")) << what;
    std::printf("[ figure   ] garbage PlanRequest (%s): %d \"%s\"\n", what.c_str(), status.error_code(),
                status.error_message().c_str());
  }
  // Control: the same stub and method with the bytes of a valid request is served.
  grpc::ByteBuffer response;
  const auto status = generic_plan(generic, demo_request('a').SerializeAsString(), response);
  EXPECT_TRUE(status.ok()) << status.error_code() << " " << status.error_message();
  EXPECT_GT(response.Length(), 0u);
  expect_serves();
  const auto text = server::metrics_exposition(running_);
  EXPECT_EQ(calls_total(text, "PlanTrajectory", "INVALID_ARGUMENT"), 4.0);
  EXPECT_EQ(metric(text, "geotraj_active_unary_calls"), 0.0);
}

// The same for StreamSamples (a server-streaming method): one garbage message, then the
// end of the client's side; the call ends INVALID_ARGUMENT without a sample.
class GarbageStream final : public grpc::ClientBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
 public:
  GarbageStream(grpc::GenericStub& stub, const std::string& bytes) : request_(buffer_of(bytes)) {
    context_.set_deadline(in(seconds(30)));
    stub.PrepareBidiStreamingCall(&context_, "/geotraj.v1.TrajectoryService/StreamSamples", grpc::StubOptions(), this);
    StartWriteLast(&request_, grpc::WriteOptions());
    StartRead(&response_);
    StartCall();
  }
  void OnReadDone(bool ok) override {
    if (!ok) return;
    ++messages_;
    StartRead(&response_);
  }
  void OnDone(const grpc::Status& status) override { done_.set_value(status); }
  grpc::Status await() { return done_.get_future().get(); }
  int messages() const { return messages_; }

 private:
  grpc::ClientContext context_;
  grpc::ByteBuffer request_;
  grpc::ByteBuffer response_;
  int messages_ = 0;
  std::promise<grpc::Status> done_;
};

TEST_F(FaultTest, GarbageStreamRequestIsRefused) {
  grpc::GenericStub generic(channel_);
  for (const auto& [what, bytes] : garbage_messages()) {
    GarbageStream call(generic, bytes);
    const auto status = call.await();
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << what << ": " << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr("geotraj.v1.PlanRequest")) << what;
    EXPECT_EQ(call.messages(), 0) << what;
    std::printf("[ figure   ] garbage StreamSamples request (%s): %d \"%s\"\n", what.c_str(), status.error_code(),
                status.error_message().c_str());
  }
  EXPECT_TRUE(back_to_idle("geotraj_active_streams"));
  EXPECT_EQ(calls_total(server::metrics_exposition(running_), "StreamSamples", "INVALID_ARGUMENT"), 4.0);
  grpc::Status status;
  EXPECT_EQ(stream_all(demo_request('a'), status).size(), 1001u);
  EXPECT_TRUE(status.ok()) << status.error_message();
}

// Raw TCP to the gRPC port. Returns whether the server closed the connection within
// `timeout` after `bytes` were written (and, when `half_close`, our side shut for writing).
struct RawOutcome {
  bool connected = false;
  bool closed = false;
  std::size_t bytes_back = 0;  // what the server wrote before closing (e.g. SETTINGS, GOAWAY)
  double seconds = 0.0;
};

RawOutcome raw_exchange(int port, const std::string& bytes, bool half_close, std::chrono::milliseconds timeout) {
  RawOutcome out;
  const int fd = connect_loopback(port);
  if (fd < 0) return out;
  out.connected = true;
  const auto started = std::chrono::steady_clock::now();
  // MSG_NOSIGNAL: the server may close before everything is written (EPIPE, not SIGPIPE).
  for (std::size_t sent = 0; sent < bytes.size();) {
    const auto n = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;
    sent += static_cast<std::size_t>(n);
  }
  if (half_close) ::shutdown(fd, SHUT_WR);
  const auto until = started + timeout;
  char buf[4096];
  while (std::chrono::steady_clock::now() < until) {
    pollfd p{fd, POLLIN, 0};
    const auto left = std::chrono::duration_cast<milliseconds>(until - std::chrono::steady_clock::now()).count();
    if (::poll(&p, 1, static_cast<int>(std::max<long long>(left, 1))) <= 0) continue;
    const auto n = ::recv(fd, buf, sizeof buf, 0);
    if (n > 0) {
      out.bytes_back += static_cast<std::size_t>(n);
      continue;
    }
    if (n == 0 || (errno != EINTR && errno != EAGAIN)) {
      out.closed = true;
      break;
    }
  }
  out.seconds = seconds_since(started);
  ::close(fd);
  return out;
}

const std::string kPreface("PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n");

std::string random_bytes(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::string s(n, '\0');
  for (auto& c : s) c = static_cast<char>(rng() & 0xff);
  if (s[0] == 'P') s[0] = 'X';  // not even the preface's first byte
  return s;
}

TEST_F(FaultTest, NonHttp2BytesOnTheGrpcPortAreDropped) {
  struct Case {
    std::string what;
    std::string bytes;
    bool half_close;
  };
  const std::vector<Case> cases = {
      {"4 kB of random bytes", random_bytes(4096, 1), false},
      {"an HTTP/1.1 request", "GET /geotraj.v1.TrajectoryService/PlanTrajectory HTTP/1.1\r\nHost: localhost\r\n\r\n",
       false},
      {"a truncated HTTP/2 preface, then EOF", kPreface.substr(0, 10), true},
      {"the HTTP/2 preface, then random frames", kPreface + random_bytes(1024, 2), false},
      {"the HTTP/2 preface, then a frame longer than SETTINGS_MAX_FRAME_SIZE",
       kPreface + std::string("\xff\xff\xff\x00\x00\x00\x00\x00\x01", 9) + std::string(64, 'x'), false},
  };
  for (const auto& c : cases) {
    const auto outcome = raw_exchange(running_.port, c.bytes, c.half_close, seconds(10));
    ASSERT_TRUE(outcome.connected) << c.what;
    EXPECT_TRUE(outcome.closed) << c.what << ": the connection is still open after " << outcome.seconds << " s";
    std::printf("[ figure   ] %s: closed %d after %.3f s, %zu bytes back\n", c.what.c_str(), outcome.closed,
                outcome.seconds, outcome.bytes_back);
    expect_serves();
  }
}

// (e) geotrajd as a process, SIGTERM while streams are in flight.

class SigtermTest : public ::testing::Test {
 protected:
  // Starts geotrajd with `drain` and connects to it.
  void start(const std::string& drain) {
    daemon_ = std::make_unique<Daemon>(std::vector<std::string>{"--address", "127.0.0.1:0", "--drain-seconds", drain});
    ASSERT_TRUE(daemon_->started());
    const std::string serving = daemon_->line();
    ASSERT_THAT(serving, HasSubstr("geotrajd: serving geotraj.v1.TrajectoryService on 127.0.0.1:"));
    const int port = port_of(serving);
    ASSERT_GT(port, 0) << serving;
    channel_ = grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
    stub_ = v1::TrajectoryService::NewStub(channel_);
  }

  std::unique_ptr<Daemon> daemon_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::TrajectoryService::Stub> stub_;
};

// --drain-seconds 600: five real-time streams of 3 s, SIGTERM after 0.5 s. The streams
// finish with every sample, a new call meanwhile is refused with UNAVAILABLE, and the
// process exits 0 as soon as they are done (within two minutes of them on the most loaded
// machine, not after ten; the figure printed is the measured delay).
TEST_F(SigtermTest, StreamsInFlightFinishDuringTheDrain) {
  ASSERT_NO_FATAL_FAILURE(start("600"));
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(3.0);  // 301 samples at 100 Hz
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  constexpr int kStreams = 5;
  Latch latch(kStreams);
  std::vector<std::unique_ptr<StreamReader>> readers;
  for (int i = 0; i < kStreams; ++i) {
    readers.push_back(std::make_unique<StreamReader>(*stub_, request, in(seconds(60))));
    readers.back()->start([&latch] { latch.count_down(); });
  }
  // Every stream is admitted and running (its first samples arrived), then 0.5 s.
  ASSERT_TRUE(eventually(
      [&] { return std::all_of(readers.begin(), readers.end(), [](const auto& r) { return r->received() > 0; }); },
      seconds(30)));
  std::this_thread::sleep_for(milliseconds(500));
  daemon_->signal(SIGTERM);
  const auto signalled = std::chrono::steady_clock::now();
  EXPECT_THAT(daemon_->line(seconds(10)), HasSubstr("geotrajd: SIGTERM received, draining (up to 600 s)"));

  {  // a new call while draining (the listener is still open during the drain)
    grpc::ClientContext context;
    context.set_deadline(in(seconds(10)));
    v1::PlanResponse response;
    const auto status = stub_->PlanTrajectory(&context, demo_request('a'), &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAVAILABLE) << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr("shutting down"));
  }

  ASSERT_TRUE(latch.wait(seconds(120))) << "streams did not finish";
  auto last_done = std::chrono::steady_clock::time_point::min();
  for (const auto& r : readers) {
    EXPECT_TRUE(r->status().ok()) << r->status().error_code() << " " << r->status().error_message();
    EXPECT_EQ(r->received(), 301u);
    EXPECT_TRUE(r->in_order());
    last_done = std::max(last_done, r->finished_at());
  }
  // Far below the 600 s drain, far above any scheduling delay of a loaded machine.
  const auto code = daemon_->wait(seconds(120));
  ASSERT_TRUE(code.has_value()) << "geotrajd still runs 120 s after its streams finished (drain 600 s)";
  EXPECT_EQ(*code, 0);
  const double exit_after_streams = seconds_since(last_done);
  const double exit_after_signal = seconds_since(signalled);
  std::printf("[ figure   ] drain 600 s: exit %.3f s after SIGTERM, %.3f s after the last stream\n", exit_after_signal,
              exit_after_streams);
}

// --drain-seconds 0.3: a real-time stream of 60 s is cut when the drain time is over (non-OK
// status), and the process exits 0 (within 5 s of SIGTERM, not after the stream's minute).
TEST_F(SigtermTest, ShortDrainCancelsTheRest) {
  ASSERT_NO_FATAL_FAILURE(start("0.3"));
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(60.0);  // 6001 samples at 100 Hz
  request.set_pacing(v1::STREAM_PACING_REAL_TIME);
  Latch latch(1);
  StreamReader reader(*stub_, request, in(seconds(60)));
  reader.start([&latch] { latch.count_down(); });
  ASSERT_TRUE(eventually([&] { return reader.received() > 0; }, seconds(30)));
  std::this_thread::sleep_for(milliseconds(500));
  daemon_->signal(SIGTERM);
  const auto signalled = std::chrono::steady_clock::now();
  EXPECT_THAT(daemon_->line(seconds(10)), HasSubstr("geotrajd: SIGTERM received, draining (up to 0.3 s)"));
  ASSERT_TRUE(latch.wait(seconds(30)));
  EXPECT_THAT(reader.status().error_code(), AnyOf(grpc::StatusCode::CANCELLED, grpc::StatusCode::UNAVAILABLE))
      << reader.status().error_message();
  EXPECT_LT(reader.received(), 6001u);
  const auto code = daemon_->wait(seconds(5));
  ASSERT_TRUE(code.has_value()) << "geotrajd still runs 5 s after SIGTERM";
  EXPECT_EQ(*code, 0);
  const double exit_after_signal = seconds_since(signalled);
  std::printf("[ figure   ] drain 0.3 s: stream ended %d after %zu samples; exit %.3f s after SIGTERM\n",
              reader.status().error_code(), reader.received(), exit_after_signal);
}

}  // namespace
}  // namespace geotraj::testing
