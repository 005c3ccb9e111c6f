// What Execute and Jog share, private to server/rpc: LiveReactor, the base of both reactors
// (its members: live_reactor.cpp), and the helpers of their messages. The calls: live.hpp.
//
// One reactor per call, two sides:
//   the read side   OnReadDone: the first message (parsed, validated, then the planning or the
//                   robot set up on a worker), then each control message applied to the
//                   motion under the reactor's mutex; every message resets the deadman timer.
//   the write side  NextWrite, from the worker that starts the motion, then from OnWriteDone
//                   and the pacing alarm: one write or one wait in flight at a time, so it is
//                   sequential; it makes the samples that are due (sample k at k / rate
//                   after the start, on the monotonic clock), checks the deadman, the drain
//                   and the deadline each batch, and alone calls Finish once the motion has
//                   come to rest (or the client is gone).
// gRPC operations (StartRead, StartWrite, Finish) are never started under the mutex: a
// reaction may run inline on the thread that starts an operation. Memory per call: the plan
// (bounded by --max-stream-samples), the motion's workspace and one batch.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <string_view>

#include <grpcpp/alarm.h>
#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/proto_buffer_reader.h>
#include <grpcpp/support/proto_buffer_writer.h>
#include <grpcpp/support/server_callback.h>

#include "core/error.hpp"
#include "geotraj/v1/geotraj.grpc.pb.h"
#include "server/ops/runtime.hpp"
#include "server/ops/tsan.hpp"
#include "server/wire/live.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server::live_detail {

using Clock = std::chrono::steady_clock;

// [s] as the clock's duration, within [0, a year] (no overflow for any double).
inline Clock::duration seconds(double s) {
  const double bounded = std::isfinite(s) ? std::clamp(s, 0.0, 3.2e7) : (s > 0.0 ? 3.2e7 : 0.0);
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(bounded));
}

// The message in `bytes`: false when they are not one in the protobuf wire format.
template <class Message>
bool parse(const grpc::ByteBuffer& bytes, Message& message) {
  grpc::ByteBuffer copy(bytes);  // shares the slices; Deserialize consumes its buffer
  return grpc::SerializationTraits<Message>::Deserialize(&copy, &message).ok();
}

// The status of a message that did not parse.
template <class Message>
grpc::Status not_parsed() {
  return invalid_argument(core::Violations{
      {"", "the message is not a " + Message::descriptor()->full_name() + " in the protobuf wire format"}});
}

// A control message's violations, named from the message's root.
inline grpc::Status bad_command(const core::Violations& violations) { return invalid_argument(violations); }

// Why a live call ends: the trailer's reason and the status.
struct Ending {
  std::string reason;
  grpc::Status status;
};

// The reactor of one live call (the comment at the top): Execute and Jog implement its hooks.
class LiveReactor : public grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
 public:
  LiveReactor(Call call, grpc::CallbackServerContext& context, std::string_view method);

  /// Reads the first message of an admitted call, or ends a refused one.
  void begin() {
    if (call_.refusal()) {
      End(*call_.refusal());
      return;
    }
    handoff_release(this);
    StartRead(&in_);
  }

  void OnReadDone(bool ok) override;
  void OnWriteDone(bool ok) override;
  void OnCancel() override;
  void OnDone() override;

 protected:
  // --- for the calls (the mutex is held in every hook) ---

  /// The first message: nullopt when accepted (the call's work then runs on a worker,
  /// which calls start()), else the status to end with. Called without the mutex.
  virtual std::optional<grpc::Status> first_message(const grpc::ByteBuffer& bytes) = 0;
  /// A later message.
  virtual void command(const grpc::ByteBuffer& bytes) = 0;
  /// Brings the motion to rest (a stop of any cause).
  virtual void stop_motion() = 0;
  /// The next set point into `out`; `final` when it is the last one (at rest).
  virtual void produce(v1::Sample& out, bool& final) = 0;
  /// The batch's status.
  virtual void status(v1::LiveStatus& out) = 0;
  /// A stop from now would take at most this long [s].
  virtual double stopping_time() const = 0;
  /// The motion is at rest (or there is none yet).
  virtual bool at_rest() const = 0;
  /// The cycle of the first set point: 0 when it is the start (Execute), 1 when it is the
  /// end of the first cycle (Jog); sample k is sent at (k + first_cycle()) / rate.
  virtual std::size_t first_cycle() const { return 0; }

  /// Starts the write side (from the worker that made the motion), `rate_hz` set points per
  /// second, `batch` per SampleBatch.
  void start(double rate_hz, std::size_t batch, double deadman_s);

  /// Ends the call from the worker (before start: planning errors, cancellation).
  void fail(const grpc::Status& status) { End(status); }

  /// Prices the call at its cycle rate (Call::price_live): true when it fits.
  bool priced(double rate_hz) {
    if (auto refused = call_.price_live(rate_hz)) {
      refused_ = std::move(refused);
      return false;
    }
    return true;
  }
  /// The refusal of the last priced() that returned false.
  const grpc::Status& price_refusal() const { return *refused_; }

  /// Stops the motion for `reason` with the final status `status` (the first cause wins).
  void request_stop(std::string reason, grpc::Status status) {
    if (ending_) return;
    ending_ = Ending{std::move(reason), std::move(status)};
    stop_motion();
  }

  /// The control message in `bytes`, or nullopt once the call is stopped as "invalid" because
  /// they are not one.
  template <class Message>
  std::optional<Message> parsed_command(const grpc::ByteBuffer& bytes) {
    Message message;
    if (parse(bytes, message)) return message;
    request_stop("invalid", not_parsed<Message>());
    return std::nullopt;
  }

  std::stop_token stop_token() const { return stop_.get_token(); }
  // The status of a call whose client is gone: its deadline passed, or it was cancelled.
  grpc::Status gone() const {
    if (deadline_ <= Clock::now()) {
      return grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED, "the deadline passed during the motion");
    }
    return grpc::Status(grpc::StatusCode::CANCELLED, "the call was cancelled");
  }
  Runtime& runtime() const { return call_.runtime(); }
  std::mutex mutex_;  // the motion and everything both sides touch

 private:
  // Records and finishes the call (with the stop reason in the trailers when given).
  void End(const grpc::Status& status, const std::string& reason = "");

  // The client is gone, or the write deadline cancelled the call (a client that does not
  // read: ended with that reason and status).
  void EndLost();

  // The next step of the write side goes to the pacing threads: samples are never made on
  // gRPC's threads, so health checks and other calls do not wait behind them. The posted
  // step holds the write side's turn (no write or wait is in flight meanwhile), so the
  // reactor cannot finish under it.
  void Pace();

  // The stops the write side decides each batch: the deadman, a drain, a near deadline.
  void check_stops(Clock::time_point now);

  // Waits for the next sample's time; the alarm's callback (on gRPC's thread) only posts
  // the next step. Each wait has its own alarm: a grpc::Alarm must not be set again while
  // its callback may still run, and the pacing thread sets the next one at once.
  void WaitUntil(Clock::time_point due);

  // The write deadline: a write in flight longer than write_bound_ is a client that does
  // not read. watch_mutex_ is held.
  void ArmWatch(Clock::time_point due);

  // The write deadline's alarm: re-armed for a later write, or it cancels a stalled call.
  void OnWatch(bool ok);

  // One step of the write side: the batch that is due, or a wait for it.
  void NextWrite();

  Call call_;
  grpc::CallbackServerContext* context_;
  std::string method_;
  Clock::time_point deadline_ = Clock::time_point::max();
  std::stop_source stop_;
  grpc::ByteBuffer in_;
  std::optional<grpc::Status> refused_;  // by priced()
  // Both sides, under mutex_.
  bool first_seen_ = false;
  bool reads_done_ = false;
  bool started_ = false;
  bool unread_ = false;  // the write deadline ended the call
  Clock::time_point last_message_;
  std::optional<Ending> ending_;
  // The write side.
  Clock::time_point start_;
  double period_ = 0.01;
  double deadman_s_ = kDefaultDeadmanS;
  std::size_t batch_size_ = 1;
  std::size_t k_ = 0;
  bool final_written_ = false;
  std::uint64_t sent_ = 0;
  v1::SampleBatch batch_;
  grpc::ByteBuffer bytes_;
  std::mutex alarm_mutex_;
  bool cancelled_ = false;
  bool alarm_set_ = false;
  std::unique_ptr<grpc::Alarm> alarm_;
  // The write deadline, under watch_mutex_ (never held while a gRPC operation starts, bar
  // the watch's own alarm).
  std::mutex watch_mutex_;
  bool writing_ = false;
  Clock::time_point write_began_;
  Clock::duration write_bound_ = seconds(kDefaultDeadmanS);
  bool watch_set_ = false;  // its alarm is set and its callback has not run
  bool watching_ = false;   // its callback is cancelling a stalled call (OnDone waits)
  std::condition_variable watched_;  // watching_ became false
  bool done_ = false;       // OnDone has run
  std::unique_ptr<grpc::Alarm> watch_alarm_;
};

}  // namespace geotraj::server::live_detail
