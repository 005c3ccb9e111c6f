// LiveReactor's members (live_reactor.hpp): the read side, the paced write side and the
// write deadline of a live call.
#include "server/rpc/live_reactor.hpp"

#include <grpc/support/time.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <grpcpp/alarm.h>

#include "core/format.hpp"
#include "server/ops/runtime.hpp"
#include "server/ops/tsan.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server::live_detail {
namespace {

// How much later than the client's deadline the server may see it: gRPC sends the time left
// rounded up to a coarser unit the longer it is (the grpc-timeout header), measured as up to
// 10 ms below 10 s, 100 ms below 100 s; 1 s is allowed beyond.
double deadline_rounding(Clock::duration left) {
  const double s = std::chrono::duration<double>(left).count();
  return s < 10.0 ? 0.01 : s < 100.0 ? 0.1 : 1.0;
}

// A time on the steady clock as gRPC's monotonic time (for grpc::Alarm).
gpr_timespec monotonic(Clock::time_point due) {
  const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(due - Clock::now());
  return gpr_time_add(gpr_now(GPR_CLOCK_MONOTONIC),
                      gpr_time_from_nanos(std::max<std::int64_t>(0, left.count()), GPR_TIMESPAN));
}

// The longest a write may stay in flight before the client counts as not reading: its
// deadman time and this much more [s], so that a reading client on a loaded machine (or
// under the sanitizers) meets its own deadman first, never a cancel.
constexpr double kWriteGraceS = 1.0;

}  // namespace

LiveReactor::LiveReactor(Call call, grpc::CallbackServerContext& context, std::string_view method)
    : call_(std::move(call)), context_(&context), method_(method) {
  const auto left = context.deadline() - std::chrono::system_clock::now();
  if (left < std::chrono::hours(24 * 365)) {
    deadline_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(left);
  }
}

void LiveReactor::OnReadDone(bool ok) {
  handoff_acquire(this);
  bool first = false;
  {
    const std::lock_guard lock(mutex_);
    if (ok) {
      last_message_ = Clock::now();
      first = !first_seen_;
      first_seen_ = true;
      if (!first) command(in_);
    } else {
      reads_done_ = true;
    }
  }
  if (!ok) {
    // The client has half-closed (or gone): the deadman decides from here. Before the first
    // message nothing else runs, and the call ends here.
    if (!first_seen_) {
      End(invalid_argument(core::Violations{{"", "the stream ended before its first message"}}));
    }
    return;
  }
  if (first) {
    if (auto refused = first_message(in_)) {
      End(*refused);
      return;
    }
  }
  handoff_release(this);
  StartRead(&in_);
}

void LiveReactor::OnWriteDone(bool ok) {
  handoff_acquire(this);
  {
    const std::lock_guard lock(watch_mutex_);
    writing_ = false;
  }
  if (!ok) {
    EndLost();
    return;
  }
  call_.runtime().metrics().samples_streamed(static_cast<std::uint64_t>(batch_.samples_size()));
  sent_ += static_cast<std::uint64_t>(batch_.samples_size());
  if (final_written_) {
    const std::string reason = ending_ ? ending_->reason : "completed";
    call_.runtime().metrics().live_stopped(method_, reason);
    End(ending_ ? ending_->status : grpc::Status::OK, reason);
    return;
  }
  Pace();
}

void LiveReactor::OnCancel() {
  handoff_acquire(this);
  stop_.request_stop();
  const std::lock_guard lock(alarm_mutex_);
  cancelled_ = true;
  if (alarm_set_) alarm_->Cancel();
}

void LiveReactor::OnDone() {
  handoff_acquire(this);
  {
    std::unique_lock lock(watch_mutex_);
    done_ = true;
    // The write deadline's callback may be cancelling the call: the context (gRPC frees it
    // once this returns) lives until it has. OnDone never runs inline in TryCancel (a
    // reactor's OnDone is scheduled, not inlined), so this wait ends.
    watched_.wait(lock, [this] { return !watching_; });
    if (watch_set_) {
      // The write deadline's callback deletes the reactor (it runs soon: cancelled).
      watch_alarm_->Cancel();
      return;
    }
  }
  delete this;
}

void LiveReactor::start(double rate_hz, std::size_t batch, double deadman_s) {
  {
    const std::lock_guard lock(mutex_);
    period_ = 1.0 / rate_hz;
    batch_size_ = batch;
    deadman_s_ = deadman_s;
    start_ = Clock::now();
    last_message_ = start_;
    started_ = true;
  }
  {
    const std::lock_guard lock(watch_mutex_);
    write_bound_ = seconds(deadman_s + kWriteGraceS);
  }
  Pace();
}

void LiveReactor::End(const grpc::Status& status, const std::string& reason) {
  const grpc::Status bounded_status = bounded(status);
  if (!reason.empty()) context_->AddTrailingMetadata("geotraj-stop-reason", reason);
  if (runtime().draining()) {
    // The drain's log says how many arms it brought to rest and how many it cut. Once
    // started, only the write side ends the call, so final_written_ is its own.
    bool moving = false, rest = false;
    {
      const std::lock_guard lock(mutex_);
      moving = started_;
      if (moving) rest = final_written_ || at_rest();
    }
    if (moving) runtime().live_ended_in_drain(rest);
  }
  call_.finish(bounded_status, sent_);
  handoff_release(this);
  Finish(bounded_status);
}

void LiveReactor::EndLost() {
  std::optional<Ending> unread;
  {
    const std::lock_guard lock(mutex_);
    if (unread_) unread = ending_;
  }
  if (unread) {
    call_.runtime().metrics().live_stopped(method_, unread->reason);
    End(unread->status, unread->reason);
  } else {
    End(gone());
  }
}

void LiveReactor::Pace() {
  handoff_release(this);
  runtime().pacing().submit([this] {
    handoff_acquire(this);
    NextWrite();
  });
}

void LiveReactor::check_stops(Clock::time_point now) {
  if (ending_) return;
  if (now - last_message_ > seconds(deadman_s_)) {
    request_stop("deadman", grpc::Status(grpc::StatusCode::ABORTED,
                                         "no message from the client for " + core::number(deadman_s_, 6) +
                                             " s (the deadman time): the motion was stopped and brought to rest"));
  } else if (runtime().draining()) {
    request_stop("drain", grpc::Status(grpc::StatusCode::UNAVAILABLE,
                                       "the server is shutting down: the motion was brought to rest"));
  } else if (deadline_ - now < seconds(stopping_time() + 3.0 * period_ * static_cast<double>(batch_size_) + 0.05 +
                                        deadline_rounding(deadline_ - now))) {
    request_stop("deadline", grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED,
                                          "the call's deadline was near: the motion was brought to rest before it"));
  }
}

void LiveReactor::WaitUntil(Clock::time_point due) {
  {
    const std::lock_guard lock(alarm_mutex_);
    if (!cancelled_) {
      alarm_set_ = true;
      alarm_ = std::make_unique<grpc::Alarm>();  // the last one's callback may still be returning
      handoff_release(this);
      alarm_->Set(monotonic(due), [this](bool ok) {
        handoff_acquire(this);
        {
          const std::lock_guard wait(alarm_mutex_);
          alarm_set_ = false;
        }
        if (ok) {
          Pace();
        } else {
          EndLost();
        }
      });
      return;
    }
  }
  EndLost();
}

void LiveReactor::ArmWatch(Clock::time_point due) {
  watch_set_ = true;
  watch_alarm_ = std::make_unique<grpc::Alarm>();  // the last one's callback may be running (this one)
  handoff_release(this);
  watch_alarm_->Set(monotonic(due), [this](bool ok) { OnWatch(ok); });
}

void LiveReactor::OnWatch(bool ok) {
  handoff_acquire(this);
  bool stalled = false;
  Clock::duration bound{};
  {
    const std::lock_guard lock(watch_mutex_);
    watch_set_ = false;
    bound = write_bound_;
    if (!done_ && ok && writing_) {
      const auto due = write_began_ + write_bound_;
      if (Clock::now() < due) {
        ArmWatch(due);  // another write since this one was set
      } else {
        stalled = true;
        watching_ = true;  // OnDone waits until the call is cancelled
      }
    }
    if (!stalled && !done_) return;
  }
  if (stalled) {
    // The client does not read: it is ended as one that sends nothing (the motion stopped;
    // its set points cannot reach the robot). The write in flight fails, and OnWriteDone
    // ends the call with this status.
    {
      const std::lock_guard lock(mutex_);
      unread_ = true;
      request_stop("unread",
                   grpc::Status(grpc::StatusCode::ABORTED,
                                "the client read no set point for " +
                                    core::number(std::chrono::duration<double>(bound).count(), 6) +
                                    " s (the deadman time): the motion was stopped and the call ended"));
    }
    handoff_release(this);
    context_->TryCancel();
    // OnDone (now or later) deletes the reactor: nothing of it is touched past the unlock.
    const std::lock_guard lock(watch_mutex_);
    watching_ = false;
    watched_.notify_all();
    return;
  }
  delete this;  // OnDone has run and left it to this callback
}

void LiveReactor::NextWrite() {
  bool cancelled = false;
  {
    const std::lock_guard lock(alarm_mutex_);
    cancelled = cancelled_;
  }
  if (cancelled) {
    EndLost();
    return;
  }
  std::optional<Clock::time_point> wait;
  {
    const std::lock_guard lock(mutex_);
    const auto now = Clock::now();
    check_stops(now);
    batch_.Clear();
    while (static_cast<std::size_t>(batch_.samples_size()) < batch_size_) {
      const auto due = start_ + seconds(static_cast<double>(k_ + first_cycle()) * period_);
      if (due > now) {
        if (batch_.samples_size() == 0) wait = due;
        break;
      }
      bool final = false;
      produce(*batch_.add_samples(), final);
      ++k_;
      if (final) {
        final_written_ = true;
        break;
      }
    }
    if (!wait) status(*batch_.mutable_live());
  }
  if (wait) {
    WaitUntil(*wait);
    return;
  }
  grpc::ByteBuffer& out = bytes_;
  bool own = false;
  out.Clear();
  (void)grpc::SerializationTraits<v1::SampleBatch>::Serialize(batch_, &out, &own);
  {
    const std::lock_guard lock(watch_mutex_);
    writing_ = true;
    write_began_ = Clock::now();
    if (!watch_set_ && !watching_) ArmWatch(write_began_ + write_bound_);
  }
  handoff_release(this);
  StartWrite(&bytes_);
}

}  // namespace geotraj::server::live_detail
