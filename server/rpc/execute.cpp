// Execute: a plan executed live under the client's speed override, pause, resume and stop
// (ExecuteReactor on LiveReactor), and execute_call (live.hpp).
#include "server/rpc/live.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/format.hpp"
#include "core/live/execution.hpp"
#include "geotraj/v1/geotraj.grpc.pb.h"
#include "server/ops/runtime.hpp"
#include "server/rpc/live_reactor.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/live.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server {

using namespace live_detail;

namespace {

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
          const core::RobotModel* model = robot ? &robot->model.model() : nullptr;
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
    const auto parsed = parsed_command<v1::ExecuteRequest>(bytes);
    if (!parsed) return;
    const v1::ExecuteRequest& request = *parsed;
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

}  // namespace

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* execute_call(grpc::CallbackServerContext& context,
                                                                          Runtime& runtime, ExecutePlanning planning) {
  auto* reactor = new ExecuteReactor(Call(runtime, context, Method::kExecute), context, std::move(planning));
  reactor->begin();
  return reactor;
}

}  // namespace geotraj::server
