// The live calls (Execute, Jog) on gRPC's callback API. See live.hpp and docs/live.md.
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
#include "server/rpc/live.hpp"

#include <grpc/support/time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <memory>
#include <optional>
#include <string>

#include <grpcpp/alarm.h>
#include <grpcpp/support/proto_buffer_reader.h>
#include <grpcpp/support/proto_buffer_writer.h>

#include "core/format.hpp"
#include "geotraj/v1/geotraj.grpc.pb.h"
#include "core/live/execution.hpp"
#include "core/live/jog.hpp"
#include "server/ops/tsan.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/live.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server {
namespace {

using Clock = std::chrono::steady_clock;

// [s] as the clock's duration, within [0, a year] (no overflow for any double).
Clock::duration seconds(double s) {
  const double bounded = std::isfinite(s) ? std::clamp(s, 0.0, 3.2e7) : (s > 0.0 ? 3.2e7 : 0.0);
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(bounded));
}

template <class Message>
bool parse(const grpc::ByteBuffer& bytes, Message& message) {
  grpc::ByteBuffer copy(bytes);  // shares the slices; Deserialize consumes its buffer
  return grpc::SerializationTraits<Message>::Deserialize(&copy, &message).ok();
}

template <class Message>
grpc::Status not_parsed() {
  return invalid_argument(core::Violations{
      {"", "the message is not a " + Message::descriptor()->full_name() + " in the protobuf wire format"}});
}

// A control message's violations, named from the message's root.
grpc::Status bad_command(const core::Violations& violations) { return invalid_argument(violations); }

// How much later than the client's deadline the server may see it: gRPC sends the time left
// rounded up to a coarser unit the longer it is (the grpc-timeout header), measured as up to
// 10 ms below 10 s, 100 ms below 100 s; 1 s is allowed beyond.
double deadline_rounding(Clock::duration left) {
  const double s = std::chrono::duration<double>(left).count();
  return s < 10.0 ? 0.01 : s < 100.0 ? 0.1 : 1.0;
}

// Why a live call ends: the trailer's reason and the status.
struct Ending {
  std::string reason;
  grpc::Status status;
};

// The largest Jog cycle rate JogStart accepts [Hz] (server/wire/live.cpp).
constexpr double kMaxJogRateHz = 10'000.0;

// The samples one Execute plan may have: --max-live-samples, or --max-stream-samples when lower.
std::uint64_t live_sample_cap(const ServiceLimits& limits) {
  return std::min(limits.max_live_samples, limits.max_stream_samples);
}
std::string live_sample_flag(const ServiceLimits& limits) {
  return limits.max_live_samples <= limits.max_stream_samples ? "geotrajd --max-live-samples"
                                                              : "geotrajd --max-stream-samples";
}

grpc::Status too_many_samples(double samples, double duration_s, double rate_hz, const ServiceLimits& limits) {
  return invalid_argument(core::Violations{
      {"plan.motion.durationS", "the motion has " + core::number(samples) + " samples (" + core::number(duration_s, 6) +
                                    " s at " + core::number(rate_hz) + " Hz); Execute runs at most " +
                                    std::to_string(live_sample_cap(limits)) + " per call (" + live_sample_flag(limits) +
                                    "): shorten it or lower cycleRateHz"}});
}

// The motion's timing as the request gives it: the first step's for a sequence.
const v1::MotionSpec& requested_motion(const v1::PlanRequest& plan) {
  if (plan.sequence_size() > 0 && plan.sequence(0).has_motion()) return plan.sequence(0).motion();
  return plan.motion();
}

// The cycle rate the request asks for (100 Hz when not given), when it is one a plan may
// have; otherwise the planning refuses it, and the plan's rate is priced then.
std::optional<double> requested_rate(const v1::PlanRequest& plan) {
  const auto& m = requested_motion(plan);
  const double rate = m.has_cycle_rate_hz() ? m.cycle_rate_hz() : core::MotionSpec{}.cycle_rate_hz;
  if (!(rate >= kMinLiveRateHz && rate <= core::kMaxCycleRateHz)) return std::nullopt;
  return rate;
}

// A plan whose request gives its duration (a path, a joint move or a line with durationS
// and no time-optimal timing asked for; not a sequence, whose steps may be blended into one
// timing) with more samples than a live call may have: refused before it is planned.
// nullopt when it fits or the planner sets the duration.
std::optional<grpc::Status> requested_samples(const v1::PlanRequest& plan, const ServiceLimits& limits) {
  const auto& timing = plan.optimize().timing();
  if (plan.sequence_size() > 0 || timing.time_optimal() || timing.jerk_limited()) return std::nullopt;
  const double duration = plan.motion().duration_s();
  const auto rate = requested_rate(plan);
  if (!rate || !(duration > 0.0) || !std::isfinite(duration)) return std::nullopt;
  const double samples = std::floor(duration * *rate) + 1.0;
  if (samples <= static_cast<double>(live_sample_cap(limits))) return std::nullopt;
  return too_many_samples(samples, duration, *rate, limits);
}

// The same for the planned motion (the planner may have chosen its duration).
std::optional<grpc::Status> planned_samples(const core::Trajectory& trajectory, const ServiceLimits& limits) {
  const auto count = core::sample_count(trajectory);
  if (count <= live_sample_cap(limits)) return std::nullopt;
  return too_many_samples(static_cast<double>(count), core::duration(trajectory),
                          core::motion_spec(trajectory).cycle_rate_hz, limits);
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

class LiveReactor : public grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer> {
 public:
  LiveReactor(Call call, grpc::CallbackServerContext& context, std::string_view method)
      : call_(std::move(call)), context_(&context), method_(method) {
    const auto left = context.deadline() - std::chrono::system_clock::now();
    if (left < std::chrono::hours(24 * 365)) {
      deadline_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(left);
    }
  }

  /// Reads the first message of an admitted call, or ends a refused one.
  void begin() {
    if (call_.refusal()) {
      End(*call_.refusal());
      return;
    }
    handoff_release(this);
    StartRead(&in_);
  }

  void OnReadDone(bool ok) override {
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

  void OnWriteDone(bool ok) override {
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

  void OnCancel() override {
    handoff_acquire(this);
    stop_.request_stop();
    const std::lock_guard lock(alarm_mutex_);
    cancelled_ = true;
    if (alarm_set_) alarm_->Cancel();
  }

  void OnDone() override {
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
  void start(double rate_hz, std::size_t batch, double deadman_s) {
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

  void End(const grpc::Status& status, const std::string& reason = "") {
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

  // The client is gone, or the write deadline cancelled the call (a client that does not
  // read: ended with that reason and status).
  void EndLost() {
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

  // The next step of the write side goes to the pacing threads: samples are never made on
  // gRPC's threads, so health checks and other calls do not wait behind them. The posted
  // step holds the write side's turn (no write or wait is in flight meanwhile), so the
  // reactor cannot finish under it.
  void Pace() {
    handoff_release(this);
    runtime().pacing().submit([this] {
      handoff_acquire(this);
      NextWrite();
    });
  }

  // The stops the write side decides each batch: the deadman, a drain, a near deadline.
  void check_stops(Clock::time_point now) {
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

  // Waits for the next sample's time; the alarm's callback (on gRPC's thread) only posts
  // the next step. Each wait has its own alarm: a grpc::Alarm must not be set again while
  // its callback may still run, and the pacing thread sets the next one at once.
  void WaitUntil(Clock::time_point due) {
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

  // The write deadline: a write in flight longer than write_bound_ is a client that does
  // not read. watch_mutex_ is held.
  void ArmWatch(Clock::time_point due) {
    watch_set_ = true;
    watch_alarm_ = std::make_unique<grpc::Alarm>();  // the last one's callback may be running (this one)
    handoff_release(this);
    watch_alarm_->Set(monotonic(due), [this](bool ok) { OnWatch(ok); });
  }

  void OnWatch(bool ok) {
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

  void NextWrite() {
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

// --- Execute --------------------------------------------------------------------------------

class ExecuteReactor final : public LiveReactor {
 public:
  ExecuteReactor(Call call, grpc::CallbackServerContext& context, ExecutePlanning planning)
      : LiveReactor(std::move(call), context, "Execute"), planning_(std::move(planning)) {}

 private:
  std::optional<grpc::Status> first_message(const grpc::ByteBuffer& bytes) override {
    auto request = std::make_shared<v1::ExecuteRequest>();
    if (!parse(bytes, *request)) return not_parsed<v1::ExecuteRequest>();
    if (!request->has_plan()) {
      return invalid_argument(core::Violations{
          {"plan", "the first message must hold the plan (later ones the control messages)"}});
    }
    auto settings = execute_settings(request->options());
    if (!settings) return invalid_argument(settings.error());
    settings_ = *settings;
    // Refused before any planning when the request times the motion itself: too many
    // samples, or a cycle rate beyond the live budget.
    if (auto too_long = requested_samples(request->plan(), runtime().limits())) return too_long;
    if (const auto rate = requested_rate(request->plan()); rate && !priced(*rate)) return price_refusal();
    {
      const std::lock_guard lock(mutex_);
      override_ = settings_.speed_override;
    }
    runtime().workers().submit(
        [this, request] {
          auto planned = planning_(request->plan(), settings_.reserve, stop_token());
          if (!planned) {
            fail(planned.error());
            return;
          }
          plan_ = std::make_unique<planner::Plan>(std::move(*planned));
          const planner::Robot* robot = plan_->robot.get();
          const core::RobotModel* model = robot ? &robot->model : nullptr;
          // The cycle rate of the plan (of its first step: a sequence's
          // steps share one cycle rate).
          const core::MotionSpec& motion = core::motion_spec(*plan_->trajectory);
          if (!(motion.cycle_rate_hz >= kMinLiveRateHz)) {
            fail(invalid_argument(core::Violations{
                {"plan.motion.cycleRateHz", "Execute streams at least " + core::number(kMinLiveRateHz) +
                                                " set point per second, got " + core::number(motion.cycle_rate_hz) + " Hz"}}));
            return;
          }
          // The plan's own size and rate (a duration or rate the planner chose), before the
          // live pass's work.
          if (auto too_long = planned_samples(*plan_->trajectory, runtime().limits())) {
            fail(*too_long);
            return;
          }
          if (!priced(motion.cycle_rate_hz)) {
            fail(price_refusal());
            return;
          }
          core::LiveOptions options;
          options.stop = stop_token();  // a cancelled call (or its deadline) ends the pass
          auto live = core::LiveExecution::start(*plan_->trajectory, model, robot ? robot->seed : core::JointVector(),
                                                 core::live_limits(model), motion.cycle_rate_hz, options);
          if (!live && stop_token().stop_requested()) {
            fail(gone());
            return;
          }
          if (!live) {
            std::string message;
            for (const auto& v : live.error()) message += (message.empty() ? "" : "; ") + v.description;
            fail(grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, message));
            return;
          }
          {
            const std::lock_guard lock(mutex_);
            live_.emplace(std::move(*live));
            const core::FactorBounds worst = live_->bounds(1.0);
            const auto& rows = live_->rows();
            worst_ = worst;
            binding_ = worst.acceleration_from_ramp
                           ? "no limit (no limited quantity moves): speed changes ramp over " +
                                 core::number(core::LiveOptions{}.ramp_s) + " s"
                           : rows[worst.acceleration_row].name + " acceleration";
            if (!worst.jerk_from_ramp) binding_ += ", " + rows[worst.jerk_row].name + " jerk";
            live_->set_override(override_);
            if (paused_) live_->pause();
            if (stopped_) live_->stop();
          }
          start(motion.cycle_rate_hz, live_batch_size(settings_.samples_per_batch, motion.cycle_rate_hz),
                settings_.deadman_s);
        },
        WorkerPool::Priority::kUrgent);
    return std::nullopt;
  }

  void command(const grpc::ByteBuffer& bytes) override {
    v1::ExecuteRequest request;
    if (!parse(bytes, request)) {
      request_stop("invalid", not_parsed<v1::ExecuteRequest>());
      return;
    }
    switch (request.command_case()) {
      case v1::ExecuteRequest::kSpeedOverride: {
        auto fraction = speed_override(request.speed_override());
        if (!fraction) {
          request_stop("invalid", bad_command(fraction.error()));
          return;
        }
        override_ = *fraction;
        if (live_) live_->set_override(override_);
        break;
      }
      case v1::ExecuteRequest::kPause:
        paused_ = true;
        if (live_) live_->pause();
        break;
      case v1::ExecuteRequest::kResume:
        paused_ = false;
        if (live_) live_->resume();
        break;
      case v1::ExecuteRequest::kStop: request_stop("stopped", grpc::Status::OK); break;
      case v1::ExecuteRequest::kHeartbeat: break;
      case v1::ExecuteRequest::kPlan:
        request_stop("invalid", bad_command({{"plan", "only the first message holds the plan"}}));
        break;
      case v1::ExecuteRequest::COMMAND_NOT_SET:
        request_stop("invalid", bad_command({{"", "a control message must hold one of speedOverride, pause, resume, "
                                                  "stop and heartbeat"}}));
        break;
    }
  }

  void stop_motion() override {
    stopped_ = true;
    if (live_) live_->stop();
  }

  void produce(v1::Sample& out, bool& final) override {
    if (!live_->next(sample_)) {  // not reached: the final sample ends the writes
      final = true;
      return;
    }
    to_proto(sample_, out);
    final = sample_.state == core::LiveState::kStopped || sample_.state == core::LiveState::kCompleted;
  }

  void status(v1::LiveStatus& out) override {
    out.set_state(to_proto(live_->state()));
    out.set_speed_override(100.0 * live_->override_fraction());
    const core::StopPrediction stop = live_->stopping();
    out.set_stopping_time_s(stop.time_s);
    out.set_stopping_plan_time_s(stop.plan_time_s);
    out.set_factor_acceleration_limit(worst_.acceleration);
    out.set_factor_jerk_limit(worst_.jerk);
    out.set_binding(binding_);
    out.set_plan_duration_s(live_->plan_duration());
    if (!reserve_told_) {  // once: the first batch (each batch starts cleared)
      reserve_told_ = true;
      out.set_acceleration_reserve(plan_->reserve);
      out.set_reserve_note(plan_->reserve_note);
    }
  }

  double stopping_time() const override { return live_ ? live_->stopping().time_s : 0.0; }
  bool at_rest() const override {
    if (!live_) return true;
    const core::LiveState state = live_->state();
    return state == core::LiveState::kPaused || state == core::LiveState::kStopped ||
           state == core::LiveState::kCompleted;
  }

  ExecutePlanning planning_;
  ExecuteSettings settings_;
  std::unique_ptr<planner::Plan> plan_;  // stable: the live motion refers to it
  std::optional<core::LiveExecution> live_;
  core::LiveSample sample_;
  core::FactorBounds worst_;
  std::string binding_;
  bool reserve_told_ = false;  // the first batch's status carried the reserve
  // Commands that came before the motion was ready.
  double override_ = 1.0;
  bool paused_ = false;
  bool stopped_ = false;
};

// --- Jog ------------------------------------------------------------------------------------

class JogReactor final : public LiveReactor {
 public:
  JogReactor(Call call, grpc::CallbackServerContext& context, const RobotCatalog& robots)
      : LiveReactor(std::move(call), context, "Jog"), robots_(&robots) {}

 private:
  std::optional<grpc::Status> first_message(const grpc::ByteBuffer& bytes) override {
    auto request = std::make_shared<v1::JogRequest>();
    if (!parse(bytes, *request)) return not_parsed<v1::JogRequest>();
    if (!request->has_start()) {
      return invalid_argument(core::Violations{
          {"start", "the first message must hold `start` (the robot and the options; later ones the commands)"}});
    }
    // Priced at the rate asked for before any work (a rate out of range is refused by the
    // settings below, then).
    const double asked = request->start().has_cycle_rate_hz() ? request->start().cycle_rate_hz() : 100.0;
    if (asked >= kMinLiveRateHz && asked <= kMaxJogRateHz && !priced(asked)) return price_refusal();
    runtime().workers().submit(
        [this, request] {
          JogSettings settings = jog_settings(request->start());
          auto jog = planner::admit(std::move(settings.jog), *robots_);
          if (!jog) {
            fail(invalid_argument(jog.error()));
            return;
          }
          if (!priced(jog->options.cycle_rate_hz)) {
            fail(price_refusal());
            return;
          }
          jog_ = std::make_unique<planner::Jog>(std::move(*jog));
          {
            const std::lock_guard lock(mutex_);
            jogger_.emplace(jog_->robot.model, jog_->robot.seed, jog_->options);
            if (stopped_) jogger_->stop();
          }
          const double rate = jog_->options.cycle_rate_hz;
          start(rate, live_batch_size(settings.samples_per_batch, rate), settings.deadman_s);
        },
        WorkerPool::Priority::kUrgent);
    return std::nullopt;
  }

  void command(const grpc::ByteBuffer& bytes) override {
    v1::JogRequest request;
    if (!parse(bytes, request)) {
      request_stop("invalid", not_parsed<v1::JogRequest>());
      return;
    }
    switch (request.command_case()) {
      case v1::JogRequest::kJoints:
      case v1::JogRequest::kTwist: {
        if (!jogger_) {  // before the robot is known, its joint count is not
          pending_ = request;
          return;
        }
        apply(request);
        break;
      }
      case v1::JogRequest::kStop: request_stop("stopped", grpc::Status::OK); break;
      case v1::JogRequest::kHeartbeat: break;
      case v1::JogRequest::kStart:
        request_stop("invalid", bad_command({{"start", "only the first message holds `start`"}}));
        break;
      case v1::JogRequest::COMMAND_NOT_SET:
        request_stop("invalid", bad_command({{"", "a message must hold one of joints, twist, stop and heartbeat"}}));
        break;
    }
  }

  void apply(const v1::JogRequest& request) {
    auto command = jog_command(request, jog_->robot.model.dof());
    if (!command) {
      request_stop("invalid", bad_command(command.error()));
      return;
    }
    if (!stopped_) jogger_->command(*command);
  }

  void stop_motion() override {
    stopped_ = true;
    if (jogger_) jogger_->stop();
  }

  void produce(v1::Sample& out, bool& final) override {
    if (pending_) {  // a command that came before the robot was set up
      const v1::JogRequest request = std::move(*pending_);
      pending_.reset();
      apply(request);
    }
    jogger_->next(sample_);
    to_proto(sample_, out);
    final = stopped_ && jogger_->at_rest();
  }

  void status(v1::LiveStatus& out) override {
    out.set_state(stopped_ ? (jogger_->at_rest() ? v1::LIVE_STATE_STOPPED : v1::LIVE_STATE_STOPPING)
                           : v1::LIVE_STATE_JOGGING);
    for (std::size_t j = 0; j < jog_->robot.model.dof(); ++j) {
      if (sample_.limited.test(j)) out.add_limited_joints(static_cast<std::uint32_t>(j));
    }
  }

  double stopping_time() const override { return jogger_ ? jogger_->stopping_time() : 0.0; }
  bool at_rest() const override { return !jogger_ || jogger_->at_rest(); }
  std::size_t first_cycle() const override { return 1; }

  const RobotCatalog* robots_;
  std::unique_ptr<planner::Jog> jog_;  // the robot and options, from the first message
  std::optional<core::Jogger> jogger_;
  core::JogSample sample_;
  std::optional<v1::JogRequest> pending_;
  bool stopped_ = false;
};

}  // namespace

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* execute_call(grpc::CallbackServerContext& context,
                                                                          Runtime& runtime, ExecutePlanning planning) {
  auto* reactor = new ExecuteReactor(Call(runtime, context, Method::kExecute), context, std::move(planning));
  reactor->begin();
  return reactor;
}

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* jog_call(grpc::CallbackServerContext& context,
                                                                      Runtime& runtime, const RobotCatalog& robots) {
  auto* reactor = new JogReactor(Call(runtime, context, Method::kJog), context, robots);
  reactor->begin();
  return reactor;
}

}  // namespace geotraj::server
