// Helpers of the reliability tests: a server started with chosen options (on the fixture of
// tests/server/support/test_server.hpp), a callback-API stream reader that checks order and counts
// without a thread per stream, the process's resident memory, and metric values.
#pragma once

#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/support/client_callback.h>

#include "tests/server/support/test_server.hpp"
#include "tests/support/sanitizers.hpp"

namespace geotraj::testing {

/// The server of ServerTest, started by the test with the options it chooses (limits, log
/// level) instead of the defaults; stopped by ServerTest::TearDown.
class ConfiguredServerTest : public ServerTest {
 protected:
  void SetUp() override {}

  /// Starts the server on 127.0.0.1:<ephemeral>, with a channel and a stub to it.
  void start(server::ServerOptions options) {
    options.address = "127.0.0.1:0";
    auto started = server::start_server(options);
    ASSERT_TRUE(started) << started.error();
    running_ = std::move(*started);
    address_ = "127.0.0.1:" + std::to_string(running_.port);
    channel_ = grpc::CreateChannel(address_, grpc::InsecureChannelCredentials());
    stub_ = v1::TrajectoryService::NewStub(channel_);
  }

  /// Server options whose log keeps to warnings: the load tests make thousands of calls.
  static server::ServerOptions quiet_options() {
    server::ServerOptions options;
    options.log_level = "warning";
    return options;
  }

  /// A further channel with its own TCP connection (a distinct channel argument keeps gRPC
  /// from sharing the subchannel of `channel_`).
  std::shared_ptr<grpc::Channel> own_channel(int index) const {
    grpc::ChannelArguments args;
    args.SetInt("geotraj.test.connection", index);
    return grpc::CreateCustomChannel(address_, grpc::InsecureChannelCredentials(), args);
  }
};

/// One StreamSamples call through the callback API: reads every batch, checks that the
/// sample times increase, counts the samples and calls `done` with the final status.
class StreamReader final : public grpc::ClientReadReactor<v1::SampleBatch> {
 public:
  /// `cancel_after`: TryCancel once this many samples have arrived (0: never).
  StreamReader(v1::TrajectoryService::Stub& stub, const v1::PlanRequest& request,
               std::chrono::system_clock::time_point deadline, std::size_t cancel_after = 0)
      : request_(request), cancel_after_(cancel_after) {
    context_.set_deadline(deadline);
    stub.async()->StreamSamples(&context_, &request_, this);
  }

  /// Starts the call; `done` runs on a gRPC thread when it has ended.
  void start(std::function<void()> done) {
    done_ = std::move(done);
    StartRead(&batch_);
    StartCall();
  }

  void OnReadDone(bool ok) override {
    if (!ok) return;  // the stream has ended; OnDone follows
    for (const auto& sample : batch_.samples()) {
      if (!(sample.t() > last_t_) && received_ > 0) in_order_ = false;
      last_t_ = sample.t();
      ++received_;
    }
    if (cancel_after_ > 0 && received_ >= cancel_after_ && !cancelled_) {
      cancelled_ = true;
      context_.TryCancel();
    }
    StartRead(&batch_);
  }

  void OnDone(const grpc::Status& status) override {
    status_ = status;
    finished_at_ = std::chrono::steady_clock::now();
    done_();  // last: the owner may destroy this reader once every stream is done
  }

  const grpc::Status& status() const { return status_; }
  std::size_t received() const { return received_.load(); }
  bool in_order() const { return in_order_; }
  double last_t() const { return last_t_; }
  std::chrono::steady_clock::time_point finished_at() const { return finished_at_; }

 private:
  grpc::ClientContext context_;
  v1::PlanRequest request_;
  v1::SampleBatch batch_;
  std::function<void()> done_;
  grpc::Status status_;
  std::atomic<std::size_t> received_{0};  // read by the test while the stream runs
  std::size_t cancel_after_;
  bool cancelled_ = false;
  bool in_order_ = true;
  double last_t_ = 0.0;
  std::chrono::steady_clock::time_point finished_at_;
};

/// Counts finished calls; wait() blocks until `expected` have finished or the timeout passed.
class Latch {
 public:
  explicit Latch(int expected) : left_(expected) {}
  void count_down() {
    std::lock_guard lock(mutex_);
    if (--left_ == 0) cv_.notify_all();
  }
  bool wait(std::chrono::steady_clock::duration timeout) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [this] { return left_ <= 0; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  int left_;
};

/// The resident set size of this process [bytes] (/proc/self/statm, second field).
inline long long rss_bytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return -1;
  long long size = 0, resident = 0;
  const int n = std::fscanf(f, "%lld %lld", &size, &resident);
  std::fclose(f);
  return n == 2 ? resident * static_cast<long long>(::sysconf(_SC_PAGESIZE)) : -1;
}

/// The resident set size after glibc's allocator has returned its free pages to the system
/// (malloc_trim): what is still allocated, without the free memory the allocator's
/// per-thread arenas happen to hold at that moment (which varies by ~10 MB between rounds).
inline long long trimmed_rss_bytes() {
  ::malloc_trim(0);
  return rss_bytes();
}

/// The bytes glibc's allocator has handed out and not been given back (mallinfo2: in use in
/// every arena, plus the blocks it mapped on its own): what a leak makes grow, without the
/// thread stacks and free pages that move the resident set by several MB from one moment to
/// the next on a loaded machine.
inline long long heap_in_use_bytes() {
  const struct mallinfo2 info = ::mallinfo2();
  return static_cast<long long>(info.uordblks + info.hblkhd);
}

// kAddressSanitizer (tests/support/sanitizers.hpp): its quarantine keeps freed memory (up to
// 256 MB), so the resident set says nothing about leaks there (LeakSanitizer checks them at
// exit).

inline double megabytes(long long bytes) { return static_cast<double>(bytes) / (1024.0 * 1024.0); }

/// The value of the sample `series` (a metric name with its labels, as exposed, e.g.
/// `geotraj_rpc_calls_total{method="StreamSamples",code="OK"}`), or nullopt when absent.
inline std::optional<double> metric(const std::string& exposition, const std::string& series) {
  std::istringstream lines(exposition);
  for (std::string line; std::getline(lines, line);) {
    if (line.size() > series.size() && line.compare(0, series.size(), series) == 0 && line[series.size()] == ' ') {
      return std::strtod(line.c_str() + series.size() + 1, nullptr);
    }
  }
  return std::nullopt;
}

/// The count of finished calls of `method` that ended with `code` (a canonical code name).
inline double calls_total(const std::string& exposition, const std::string& method, const std::string& code) {
  return metric(exposition, "geotraj_rpc_calls_total{method=\"" + method + "\",code=\"" + code + "\"}").value_or(0.0);
}

/// Polls `condition` every 10 ms until it holds (true) or `timeout` has passed (false).
inline bool eventually(const std::function<bool()>& condition, std::chrono::steady_clock::duration timeout) {
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (!condition()) {
    if (std::chrono::steady_clock::now() >= until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

// How late each set point of a stream arrives [ms]: its arrival less its time t, measured
// from the earliest such offset of the stream (the set point that came soonest after its
// time defines "on time"), so every value is >= 0 and a late first set point does not make
// the others look early.
class Lateness {
 public:
  void arrived(double t, std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) {
    if (offsets_ms_.empty()) {
      first_arrival_ = now;
      first_t_ = t;
    }
    offsets_ms_.push_back(std::chrono::duration<double, std::milli>(now - first_arrival_).count() -
                          1e3 * (t - first_t_));
  }
  std::vector<double> ms() const {
    if (offsets_ms_.empty()) return {};
    const double earliest = *std::min_element(offsets_ms_.begin(), offsets_ms_.end());
    std::vector<double> late;
    late.reserve(offsets_ms_.size());
    for (const double o : offsets_ms_) late.push_back(o - earliest);
    return late;
  }

 private:
  std::vector<double> offsets_ms_;
  std::chrono::steady_clock::time_point first_arrival_;
  double first_t_ = 0.0;
};

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace geotraj::testing
