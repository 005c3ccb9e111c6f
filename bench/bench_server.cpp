// End-to-end calls over loopback TCP: a geotraj server started in this process on
// 127.0.0.1 (ephemeral port) and a client stub on a real channel, so every call pays for
// serialisation, HTTP/2, the thread hand-offs and the core work. One call at a time.
// The JSON API over loopback HTTP likewise (BM_Web*).
// Run: build/bench/bench_server --benchmark_repetitions=5
#include <benchmark/benchmark.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iostream>
#include <vector>

#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "server/ops/http_exporter.hpp"
#include "server/ops/metrics.hpp"
#include "server/server.hpp"

#include <google/protobuf/util/json_util.h>
// Last: httplib.h brings <resolv.h>, whose `_res` macro breaks Eigen if included before it.
#include <httplib.h>

namespace {

using namespace geotraj;

void set(v1::Vec3* v, double x, double y, double z) {
  v->set_x(x);
  v->set_y(y);
  v->set_z(z);
}

// The thesis's demonstration path C (Tables 7.8 and 7.18), as a client would send it.
v1::PlanRequest demo_request() {
  v1::PlanRequest req;
  auto* path = req.mutable_path();
  path->set_derivative_convention(v1::DERIVATIVE_CONVENTION_PER_PARAMETER);
  const double rows[4][9] = {{0.106, 0, 0.975, 1, 0, 0, 0, -1, 0},
                             {0.4, 0.15, 0.5, 0, -1, 0, 0, 0, -1},
                             {0.5, -0.3, 0.525, 1, 0, 0, 0, 1, 0},
                             {0.2, -0.5, 0.6, 0, -1, 0, 0, 0, -1}};
  for (const auto& r : rows) {
    auto* f = path->add_frames();
    set(f->mutable_position(), r[0], r[1], r[2]);
    set(f->mutable_tangent(), r[3], r[4], r[5]);
    set(f->mutable_normal(), r[6], r[7], r[8]);
    f->set_tangent_scale(0.25);
  }
  path->mutable_frames(1)->set_curvature(20);
  path->mutable_frames(1)->set_torsion(-50);
  path->mutable_frames(2)->set_curvature(10);
  path->mutable_frames(2)->set_torsion(-100);
  path->mutable_frames(2)->set_cusp(true);
  return req;
}

// A random-walk path of n frames, 0.1 m apart, as in bench_core's BM_BuildManyFrames.
v1::PlanRequest many_frames_request(int n) {
  v1::PlanRequest req;
  auto* path = req.mutable_path();
  for (int i = 0; i < n; ++i) {
    auto* f = path->add_frames();
    const double a = 0.3 * std::sin(0.7 * i);
    set(f->mutable_position(), 0.1 * i, 0.05 * std::sin(0.3 * i), 0.0);
    set(f->mutable_tangent(), std::cos(a), std::sin(a), 0.0);
    set(f->mutable_normal(), -std::sin(a), std::cos(a), 0.0);
    f->set_tangent_scale(0.1);
  }
  return req;
}

class Loopback {
 public:
  Loopback() {
    server::ServerOptions options;
    options.address = "127.0.0.1:0";
    options.log_level = "warning";  // no line per call: the benchmark measures the service
    options.web_address = "127.0.0.1:0";  // the JSON API too (BM_Web*)
    auto running = server::start_server(options);
    if (!running) {
      std::cerr << "bench_server: " << running.error() << '\n';
      std::exit(1);
    }
    running_ = std::move(*running);
    channel_ = grpc::CreateChannel("127.0.0.1:" + std::to_string(running_.port), grpc::InsecureChannelCredentials());
    stub_ = v1::TrajectoryService::NewStub(channel_);
  }
  ~Loopback() { server::stop_server(running_, std::chrono::milliseconds(100)); }
  v1::TrajectoryService::Stub& stub() { return *stub_; }
  int web_port() const { return running_.web_port; }

 private:
  server::RunningServer running_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::TrajectoryService::Stub> stub_;
};

Loopback& loopback() {
  static Loopback instance;
  return instance;
}

// Runs one call per iteration and reports the latency distribution: median, 99th
// percentile and worst call, in microseconds (counters p50_us, p99_us, max_us).
template <class Call>
void run_calls(benchmark::State& state, Call call) {
  std::vector<double> latency_us;
  latency_us.reserve(4096);
  for (auto _ : state) {
    grpc::ClientContext context;
    const auto t0 = std::chrono::steady_clock::now();
    const grpc::Status status = call(context);
    latency_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    if (!status.ok()) {
      state.SkipWithError(status.error_message().c_str());
      break;
    }
  }
  if (latency_us.empty()) return;
  std::sort(latency_us.begin(), latency_us.end());
  const auto at = [&](double q) { return latency_us[static_cast<std::size_t>(q * (latency_us.size() - 1))]; };
  state.counters["p50_us"] = at(0.5);
  state.counters["p99_us"] = at(0.99);
  state.counters["max_us"] = latency_us.back();
}

void BM_PlanTrajectoryDemo(benchmark::State& state) {
  const auto request = demo_request();
  run_calls(state, [&](grpc::ClientContext& ctx) {
    v1::PlanResponse response;
    return loopback().stub().PlanTrajectory(&ctx, request, &response);
  });
}
BENCHMARK(BM_PlanTrajectoryDemo)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_ConvertConstraintsDemo(benchmark::State& state) {
  v1::ConvertRequest request;
  *request.mutable_path() = demo_request().path();
  run_calls(state, [&](grpc::ClientContext& ctx) {
    v1::ConvertResponse response;
    return loopback().stub().ConvertConstraints(&ctx, request, &response);
  });
}
BENCHMARK(BM_ConvertConstraintsDemo)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_AnalyzePathDemo(benchmark::State& state) {
  auto request = demo_request();
  request.set_analysis_points(static_cast<std::uint32_t>(state.range(0)));
  run_calls(state, [&](grpc::ClientContext& ctx) {
    v1::PathProfile response;
    return loopback().stub().AnalyzePath(&ctx, request, &response);
  });
}
BENCHMARK(BM_AnalyzePathDemo)->Arg(101)->Arg(1001)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_PlanTrajectoryManyFrames(benchmark::State& state) {
  const auto request = many_frames_request(static_cast<int>(state.range(0)));
  run_calls(state, [&](grpc::ClientContext& ctx) {
    v1::PlanResponse response;
    return loopback().stub().PlanTrajectory(&ctx, request, &response);
  });
  state.SetComplexityN(state.range(0));
}
BENCHMARK(BM_PlanTrajectoryManyFrames)->RangeMultiplier(10)->Range(10, 1000)->Unit(benchmark::kMillisecond)->UseRealTime()->Complexity(benchmark::oN);

// StreamSamples: the demo path C for 60 s at 1 kHz (60,001 samples), read to the end;
// samples per second over loopback, batch size swept.
void BM_StreamSamplesDemo(benchmark::State& state) {
  auto request = demo_request();
  request.mutable_motion()->set_duration_s(60.0);
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  request.set_samples_per_batch(static_cast<std::uint32_t>(state.range(0)));
  std::int64_t samples = 0;
  for (auto _ : state) {
    grpc::ClientContext context;
    auto reader = loopback().stub().StreamSamples(&context, request);
    v1::SampleBatch batch;
    while (reader->Read(&batch)) samples += batch.samples_size();
    const grpc::Status status = reader->Finish();
    if (!status.ok()) {
      state.SkipWithError(status.error_message().c_str());
      break;
    }
  }
  state.SetItemsProcessed(samples);
}
BENCHMARK(BM_StreamSamplesDemo)->Arg(64)->Arg(256)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime();

// Reads a joint-space stream of `joints` joints to the end; false (and the benchmark skipped)
// when the call fails or a sample lacks its joints.
bool read_joint_stream(benchmark::State& state, const v1::PlanRequest& request, int joints, std::int64_t& samples) {
  grpc::ClientContext context;
  auto reader = loopback().stub().StreamSamples(&context, request);
  v1::SampleBatch batch;
  bool complete = true;
  while (reader->Read(&batch)) {
    samples += batch.samples_size();
    complete = complete && batch.samples(0).joints_size() == joints &&
               batch.samples(batch.samples_size() - 1).joint_accelerations_size() == joints;
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) {
    state.SkipWithError(status.error_message().c_str());
    return false;
  }
  if (!complete) {
    state.SkipWithError("a sample arrived without its joints");
    return false;
  }
  return true;
}

// StreamSamples with a robot: the demo path C followed by the PA-10 for 600 s at 1 kHz
// (600,001 samples, within every limit), read to the end. Each sample costs the IK twice
// (the whole motion is checked before the first sample is sent, then tracked again while
// streaming), the Jacobian solves for the joint velocities and accelerations, and 21 more
// doubles on the wire. Samples per second over loopback, batch size swept.
void BM_StreamSamplesJointSpace(benchmark::State& state) {
  auto request = demo_request();
  request.mutable_motion()->set_duration_s(600.0);
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  request.mutable_robot()->set_name("pa10");
  request.set_samples_per_batch(static_cast<std::uint32_t>(state.range(0)));
  std::int64_t samples = 0;
  for (auto _ : state) {
    if (!read_joint_stream(state, request, 7, samples)) break;
  }
  state.SetItemsProcessed(samples);
}
BENCHMARK(BM_StreamSamplesJointSpace)->Arg(256)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime();

// The same rate for a joint move (thesis 6.2.2.1: no IK; forward kinematics and the
// Jacobian for the tool's state): the PA-10 over 600 s at 1 kHz.
void BM_StreamSamplesJointMove(benchmark::State& state) {
  v1::PlanRequest request;
  for (double q : {0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8}) request.mutable_joint_move()->add_goal(q);
  request.mutable_robot()->set_name("pa10");
  request.mutable_motion()->set_duration_s(600.0);
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  request.set_samples_per_batch(static_cast<std::uint32_t>(state.range(0)));
  std::int64_t samples = 0;
  for (auto _ : state) {
    if (!read_joint_stream(state, request, 7, samples)) break;
  }
  state.SetItemsProcessed(samples);
}
BENCHMARK(BM_StreamSamplesJointMove)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime();

// ---------------------------------------------------------------------------------------
// The metrics endpoint: a scrape of a busy server's exposition (every RPC finished with
// several codes, optimisations, connections), answered in memory (HttpRoutes: the RFC 9112
// checks, cpp-httplib's parser, router and writer) and over loopback TCP (HttpExporter:
// connect, request, answer, close).

server::Metrics& busy_metrics() {
  static server::Metrics metrics;
  static const bool filled = [] {
    server::Metrics& m = metrics;
    for (const char* method : {"PlanTrajectory", "AnalyzePath", "ConvertConstraints", "StreamSamples", "ListRobots"}) {
      for (int code : {0, 1, 3, 4, 8, 9}) {
        m.call_started(method, false);
        m.call_finished(method, false, code, 0.01 * (code + 1));
      }
    }
    m.optimization("tangent_scales", 0.003);
    m.optimization("breakpoints", 2.0);
    m.samples_streamed(123456);
    return true;
  }();
  (void)filled;
  return metrics;
}

void BM_MetricsAnswer(benchmark::State& state) {
  server::HttpRoutes routes([] { return busy_metrics().exposition(); });
  const std::string head = "GET /metrics HTTP/1.1\r\nHost: geotraj:9090\r\nUser-Agent: Prometheus/2.45.0\r\n"
                           "Accept: text/plain;version=0.0.4;q=1,*/*;q=0.1\r\n\r\n";
  std::size_t bytes = 0;
  for (auto _ : state) {
    const std::string response = routes.answer(head);
    bytes = response.size();
    benchmark::DoNotOptimize(response.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_MetricsAnswer)->Unit(benchmark::kMicrosecond);

// The exposition alone, to tell the endpoint's share from the metrics' own.
void BM_MetricsExposition(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(busy_metrics().exposition());
}
BENCHMARK(BM_MetricsExposition)->Unit(benchmark::kMicrosecond);

void BM_MetricsScrape(benchmark::State& state) {
  auto started = server::HttpExporter::start("127.0.0.1:0", [] { return busy_metrics().exposition(); });
  if (!started) {
    state.SkipWithError(started.error().c_str());
    return;
  }
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>((*started)->port()));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const std::string request = "GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n";
  char buffer[65536];
  for (auto _ : state) {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0 ||
        ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(request.size())) {
      ::close(fd);
      state.SkipWithError("cannot send the scrape");
      return;
    }
    while (::recv(fd, buffer, sizeof buffer, 0) > 0) {  // until the exporter closes
    }
    ::close(fd);
  }
}
BENCHMARK(BM_MetricsScrape)->Unit(benchmark::kMicrosecond)->UseRealTime();

// The JSON API over loopback HTTP (one keep-alive connection, as the page holds): what an
// edit in the page costs before it is drawn. JSON both ways, cpp-httplib, then the same
// in-process gRPC call.
void run_web_calls(benchmark::State& state, const char* route, const std::string& body) {
  httplib::Client client("127.0.0.1", loopback().web_port());
  client.set_keep_alive(true);
  client.set_tcp_nodelay(true);  // as browsers do
  std::vector<double> latency_us;
  std::size_t bytes = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto res = client.Post(route, body, "application/json");
    latency_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    if (!res || res->status != 200) {
      state.SkipWithError(res ? res->body.c_str() : "no answer");
      break;
    }
    bytes += res->body.size();
  }
  if (latency_us.empty()) return;
  std::sort(latency_us.begin(), latency_us.end());
  const auto at = [&](double q) { return latency_us[static_cast<std::size_t>(q * (latency_us.size() - 1))]; };
  state.counters["p50_us"] = at(0.5);
  state.counters["p99_us"] = at(0.99);
  state.counters["answer_bytes"] = static_cast<double>(bytes) / static_cast<double>(latency_us.size());
}

std::string json_of(const google::protobuf::Message& message) {
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(message, &out);
  return out;
}

void BM_WebPlanDemo(benchmark::State& state) { run_web_calls(state, "/v1/plan", json_of(demo_request())); }
BENCHMARK(BM_WebPlanDemo)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_WebAnalyzeDemo(benchmark::State& state) {
  auto request = demo_request();
  request.set_analysis_points(static_cast<std::uint32_t>(state.range(0)));
  run_web_calls(state, "/v1/analyze", json_of(request));
}
BENCHMARK(BM_WebAnalyzeDemo)->Arg(101)->Arg(1001)->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
