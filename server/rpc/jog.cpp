// Jog: joint and Cartesian jogging on a robot (JogReactor on LiveReactor), and jog_call
// (live.hpp).
#include "server/rpc/live.hpp"

#include <memory>
#include <mutex>
#include <optional>

#include "core/live/jog.hpp"
#include "geotraj/v1/geotraj.grpc.pb.h"
#include "server/ops/runtime.hpp"
#include "server/rpc/live_reactor.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/live.hpp"
#include "server/wire/status.hpp"

namespace geotraj::server {

using namespace live_detail;

namespace {

// The largest Jog cycle rate JogStart accepts [Hz] (server/wire/live.cpp).
constexpr double kMaxJogRateHz = 10'000.0;

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
    const auto parsed = parsed_command<v1::JogRequest>(bytes);
    if (!parsed) return;
    const v1::JogRequest& request = *parsed;
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
    auto command = jog_command(request, jog_->robot.model->dof());
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
    for (std::size_t j = 0; j < jog_->robot.model->dof(); ++j) {
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

grpc::ServerBidiReactor<grpc::ByteBuffer, grpc::ByteBuffer>* jog_call(grpc::CallbackServerContext& context,
                                                                      Runtime& runtime, const RobotCatalog& robots) {
  auto* reactor = new JogReactor(Call(runtime, context, Method::kJog), context, robots);
  reactor->begin();
  return reactor;
}

}  // namespace geotraj::server
