// Execute and Jog end to end through the service (a C++ client on loopback): how each call
// ends (status, trailer reason, a final sample at rest), the deadman, bad first and later
// messages, a plan that may break the limits, a drain while motions run, deadlines, and the
// `move` token scope. Limits by finite differences are checked by the Python and Node
// clients (tests/interop) and the core tests (tests/core/live).
#include <atomic>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <optional>
#include <thread>
#include <utility>

#include <gmock/gmock.h>

#include "tests/server/support/production_support.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

using Stream = grpc::ClientReaderWriter<v1::ExecuteRequest, v1::SampleBatch>;
using JogStream = grpc::ClientReaderWriter<v1::JogRequest, v1::SampleBatch>;

// What a live call streamed and how it ended.
struct LiveRun {
  grpc::Status status;
  std::string reason;  // the trailer geotraj-stop-reason
  std::vector<v1::Sample> samples;
  v1::LiveStatus last;
};

std::string trailer(const grpc::ClientContext& context, const std::string& key) {
  const auto& trailers = context.GetServerTrailingMetadata();
  const auto found = trailers.find(key);
  return found == trailers.end() ? "" : std::string(found->second.data(), found->second.size());
}

// Runs a live call: writes `first`, then on each batch calls `on_batch` (which may write);
// a heartbeat follows every batch unless `heartbeats` is false.
template <class Request>
LiveRun run_live(std::unique_ptr<grpc::ClientReaderWriter<Request, v1::SampleBatch>> stream, grpc::ClientContext& context,
                 const Request& first,
                 const std::function<void(grpc::ClientReaderWriter<Request, v1::SampleBatch>&, const LiveRun&)>& on_batch,
                 bool heartbeats = true) {
  LiveRun run;
  stream->Write(first);
  v1::SampleBatch batch;
  while (stream->Read(&batch)) {
    for (const auto& s : batch.samples()) run.samples.push_back(s);
    run.last = batch.live();
    if (on_batch) on_batch(*stream, run);
    if (heartbeats) {
      Request beat;
      beat.mutable_heartbeat();
      stream->Write(beat);
    }
  }
  stream->WritesDone();
  run.status = stream->Finish();
  run.reason = trailer(context, "geotraj-stop-reason");
  return run;
}

v1::ExecuteRequest panda_plan(double deadman_s = 2.0) {
  v1::ExecuteRequest first;
  *first.mutable_plan() = example<v1::PlanRequest>("plan_panda_path_c.json");
  first.mutable_options()->set_deadman_s(deadman_s);
  return first;
}

v1::JogRequest panda_jog(double deadman_s = 2.0) {
  v1::JogRequest first;
  first.mutable_start()->mutable_robot()->set_name("panda");
  first.mutable_start()->set_cycle_rate_hz(250.0);
  first.mutable_start()->set_deadman_s(deadman_s);
  return first;
}

void expect_final_at_rest(const LiveRun& run) {
  ASSERT_FALSE(run.samples.empty());
  const auto& last = run.samples.back();
  for (int j = 0; j < last.joint_velocities_size(); ++j) {
    EXPECT_EQ(last.joint_velocities(j), 0.0) << "joint " << j;
    EXPECT_EQ(last.joint_accelerations(j), 0.0) << "joint " << j;
  }
}

class Live : public ::testing::Test {
 protected:
  void SetUp() override {
    running_ = start(server::ServerOptions{});
    stub_ = stub_to(running_.port);
  }
  void TearDown() override { server::stop_server(running_, std::chrono::seconds(5)); }

  LiveRun execute(const v1::ExecuteRequest& first,
                  const std::function<void(Stream&, const LiveRun&)>& on_batch = nullptr, bool heartbeats = true,
                  double deadline_s = 60.0) {
    auto context = short_context(deadline_s);
    return run_live<v1::ExecuteRequest>(stub_->Execute(context.get()), *context, first, on_batch, heartbeats);
  }
  LiveRun jog(const v1::JogRequest& first, const std::function<void(JogStream&, const LiveRun&)>& on_batch = nullptr,
              bool heartbeats = true, double deadline_s = 60.0) {
    auto context = short_context(deadline_s);
    return run_live<v1::JogRequest>(stub_->Jog(context.get()), *context, first, on_batch, heartbeats);
  }

  server::RunningServer running_;
  std::unique_ptr<v1::TrajectoryService::Stub> stub_;
};

TEST_F(Live, AnExecutedPlanCompletesAtItsEnd) {
  const auto run = execute(panda_plan());
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "completed");
  EXPECT_EQ(run.last.state(), v1::LIVE_STATE_COMPLETED);
  expect_final_at_rest(run);
  // At full speed the live motion is the plan: one sample per cycle, plan time = time.
  EXPECT_NEAR(run.samples.back().plan_time(), run.last.plan_duration_s(), 1e-12);
  for (std::size_t k = 0; k + 1 < run.samples.size(); ++k) {
    EXPECT_NEAR(run.samples[k].plan_time(), run.samples[k].t(), 1e-9) << k;
    EXPECT_EQ(run.samples[k].speed_factor(), 1.0) << k;
  }
  EXPECT_GT(run.last.factor_acceleration_limit(), 0.0);
  EXPECT_THAT(run.last.binding(), HasSubstr("joint"));
}

TEST_F(Live, AStopEndsOnThePathAtRest) {
  bool sent = false;
  double stop_bound = 0.0, stop_time = 0.0;
  const auto run = execute(panda_plan(), [&](Stream& stream, const LiveRun& r) {
    if (!sent && r.samples.back().t() >= 0.8) {
      sent = true;
      stop_bound = r.last.stopping_time_s();
      stop_time = r.samples.back().t();
      v1::ExecuteRequest stop;
      stop.mutable_stop();
      stream.Write(stop);
    }
  });
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "stopped");
  EXPECT_EQ(run.last.state(), v1::LIVE_STATE_STOPPED);
  expect_final_at_rest(run);
  EXPECT_LT(run.samples.back().plan_time(), run.last.plan_duration_s());
  // Within the bound reported before the stop, plus the batches in flight (10 ms each).
  EXPECT_LE(run.samples.back().t() - stop_time, stop_bound + 0.05);
  const auto exposition = server::metrics_exposition(running_);
  EXPECT_EQ(series(exposition, R"(geotraj_live_stops_total{method="Execute",reason="stopped"})"), 1);
}

TEST_F(Live, OverridePauseAndResume) {
  int step = 0;
  double paused_at = 0.0;
  std::vector<v1::LiveState> states;
  const auto run = execute(panda_plan(), [&](Stream& stream, const LiveRun& r) {
    states.push_back(r.last.state());
    const double t = r.samples.back().t();
    v1::ExecuteRequest c;
    if (step == 0 && t >= 0.6) {
      c.set_speed_override(50.0);
    } else if (step == 1 && t >= 1.2) {
      c.mutable_pause();
    } else if (step == 2 && r.last.state() == v1::LIVE_STATE_PAUSED) {
      paused_at = t;
      ++step;
      return;
    } else if (step == 3 && t >= paused_at + 0.3) {
      c.mutable_resume();
    } else {
      return;
    }
    ++step;
    stream.Write(c);
  });
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "completed");
  EXPECT_EQ(step, 4);
  EXPECT_THAT(states, ::testing::IsSupersetOf({v1::LIVE_STATE_RUNNING, v1::LIVE_STATE_PAUSING, v1::LIVE_STATE_PAUSED}));
  // Held while paused: one pose, at rest.
  const v1::Sample* held = nullptr;
  for (const auto& s : run.samples) {
    if (s.t() < paused_at || s.t() > paused_at + 0.25) continue;
    if (held == nullptr) held = &s;
    EXPECT_EQ(s.plan_time(), held->plan_time());
    EXPECT_EQ(s.speed_factor(), 0.0);
  }
  EXPECT_NE(held, nullptr);
  // Plan time never goes back, and the whole plan was run.
  for (std::size_t k = 1; k < run.samples.size(); ++k) EXPECT_GE(run.samples[k].plan_time(), run.samples[k - 1].plan_time());
  EXPECT_NEAR(run.samples.back().plan_time(), run.last.plan_duration_s(), 1e-12);
}

TEST_F(Live, TheDeadmanStopsAMotionWithNoMessages) {
  // Timed from the first batch: planning before the motion (slow under the sanitizers) is
  // not the deadman's business.
  std::optional<std::chrono::steady_clock::time_point> started;
  const auto run = execute(
      panda_plan(0.2), [&](Stream&, const LiveRun&) { started = started.value_or(std::chrono::steady_clock::now()); },
      /*heartbeats=*/false);
  ASSERT_TRUE(started.has_value());
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - *started).count();
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_THAT(run.status.error_message(), HasSubstr("deadman"));
  EXPECT_EQ(run.reason, "deadman");
  expect_final_at_rest(run);
  EXPECT_LT(run.samples.back().plan_time(), run.last.plan_duration_s());
  EXPECT_LT(took, 3.0);
}

TEST_F(Live, BadMessagesNameTheirField) {
  v1::ExecuteRequest no_plan;
  no_plan.set_speed_override(50.0);
  auto run = execute(no_plan);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(describe(bad_request_violations(run.status)), HasSubstr("plan"));
  EXPECT_TRUE(run.samples.empty());

  auto bad_options = panda_plan();
  bad_options.mutable_options()->set_deadman_s(-1.0);
  bad_options.mutable_options()->set_speed_override(120.0);
  run = execute(bad_options);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto violations = bad_request_violations(run.status);
  EXPECT_NE(violation_of(violations, "options.deadmanS"), "");
  EXPECT_NE(violation_of(violations, "options.speedOverride"), "");

  auto bad_plan = panda_plan();
  bad_plan.mutable_plan()->mutable_motion()->set_cycle_rate_hz(-5.0);
  run = execute(bad_plan);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(run.status), "plan.motion.cycleRateHz"), "");

  auto report_only = panda_plan();
  report_only.mutable_plan()->mutable_robot()->set_report_only(true);
  run = execute(report_only);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(run.status), "plan.robot.reportOnly"), "");

  // A bad control message mid-motion: brought to rest, then the error.
  bool sent = false;
  run = execute(panda_plan(), [&](Stream& stream, const LiveRun& r) {
    if (!sent && r.samples.back().t() > 0.3) {
      sent = true;
      v1::ExecuteRequest c;
      c.set_speed_override(150.0);
      stream.Write(c);
    }
  });
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(run.status), "speedOverride"), "");
  EXPECT_EQ(run.reason, "invalid");
  expect_final_at_rest(run);
}

TEST_F(Live, ADeadlineBringsTheMotionToRestBeforeIt) {
  // The PA-10's joint move (planned in milliseconds even under the sanitizers) at half speed
  // lasts about 4.6 s: the 1.5 s deadline falls mid-motion.
  v1::ExecuteRequest first;
  *first.mutable_plan() = example<v1::PlanRequest>("joint_move_pa10.json");
  first.mutable_plan()->mutable_motion()->set_cycle_rate_hz(250.0);
  first.mutable_options()->set_speed_override(50.0);
  const auto run = execute(first, nullptr, true, /*deadline_s=*/1.5);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  EXPECT_EQ(run.reason, "deadline");
  expect_final_at_rest(run);
}

TEST_F(Live, AJogMovesThenStopsAtRest) {
  bool sent = false;
  int commands = 0;
  const auto run = jog(panda_jog(), [&](JogStream& stream, const LiveRun& r) {
    const double t = r.samples.back().t();
    v1::JogRequest c;
    if (commands < 2) {  // at the first two batches, however many samples they hold
      ++commands;
      auto* v = c.mutable_joints()->mutable_velocities();
      for (int j = 0; j < 7; ++j) v->Add(j == 0 ? 0.5 : 0.0);
      stream.Write(c);
    } else if (!sent && t >= 0.5) {
      sent = true;
      c.mutable_stop();
      stream.Write(c);
    }
  });
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "stopped");
  EXPECT_EQ(run.last.state(), v1::LIVE_STATE_STOPPED);
  expect_final_at_rest(run);
  EXPECT_GT(std::abs(run.samples.back().joints(0) - run.samples.front().joints(0)), 0.01);
  EXPECT_EQ(run.samples.front().joints_size(), 7);
}

TEST_F(Live, JogErrorsNameTheirField) {
  v1::JogRequest no_start;
  no_start.mutable_heartbeat();
  auto run = jog(no_start);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(run.status), "start"), "");

  auto slow = panda_jog();  // a rate that would put the next set point past any clock
  slow.mutable_start()->set_cycle_rate_hz(1.8e-307);
  run = jog(slow);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(run.status), "start.cycleRateHz"), "");

  auto unknown = panda_jog();
  unknown.mutable_start()->mutable_robot()->set_name("no-such-arm");
  run = jog(unknown);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(run.status), "start.robot.name"), "");

  bool sent = false;
  run = jog(panda_jog(), [&](JogStream& stream, const LiveRun&) {
    if (sent) return;
    sent = true;
    v1::JogRequest c;
    c.mutable_joints()->add_velocities(0.5);  // one value for seven joints
    stream.Write(c);
  });
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(run.status), "joints.velocities"), "");
  expect_final_at_rest(run);
}

// SIGTERM's path: stop_server drains; live motions are brought to rest (UNAVAILABLE, reason
// drain) within the drain time, then the server stops.
TEST(LiveDrain, LiveCallsComeToRestBeforeTheServerStops) {
  auto running = start(server::ServerOptions{});
  auto stub = stub_to(running.port);
  std::atomic<int> streaming{0};
  auto executing = std::async(std::launch::async, [&] {
    auto context = short_context(60);
    return run_live<v1::ExecuteRequest>(stub->Execute(context.get()), *context, panda_plan(),
                                        [&, counted = false](Stream&, const LiveRun&) mutable {
                                          // Once, at the first batch (which may hold several samples).
                                          if (!std::exchange(counted, true)) ++streaming;
                                        });
  });
  auto jogging = std::async(std::launch::async, [&] {
    auto context = short_context(60);
    return run_live<v1::JogRequest>(stub->Jog(context.get()), *context, panda_jog(),
                                    [&, counted = false](JogStream& stream, const LiveRun&) mutable {
                                      if (!std::exchange(counted, true)) {
                                        ++streaming;
                                        v1::JogRequest c;
                                        auto* v = c.mutable_joints()->mutable_velocities();
                                        for (int j = 0; j < 7; ++j) v->Add(j == 1 ? -0.3 : 0.0);
                                        stream.Write(c);
                                      }
                                    });
  });
  ASSERT_TRUE(eventually([&] { return streaming.load() == 2; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto began = std::chrono::steady_clock::now();
  server::stop_server(running, std::chrono::seconds(10));
  EXPECT_LT(std::chrono::steady_clock::now() - began, std::chrono::seconds(5));
  for (auto* run : {&executing, &jogging}) {
    const LiveRun r = run->get();
    EXPECT_EQ(r.status.error_code(), grpc::StatusCode::UNAVAILABLE) << r.status.error_message();
    EXPECT_EQ(r.reason, "drain");
    expect_final_at_rest(r);
  }
}

// Execute and Jog drive a robot: they need the `move` scope.
TEST(LiveTokens, MoveNeedsItsOwnScope) {
  const auto dir = std::filesystem::temp_directory_path() / ("geotraj_live_tokens_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "tokens") << "cell-token-0123456789abc plan,stream\n"
                                << "robot-token-0123456789ab move\n";
  server::ServerOptions options;
  options.auth_tokens_file = (dir / "tokens").string();
  auto running = start(options);
  auto stub = stub_to(running.port);
  for (const auto* token : {"cell-token-0123456789abc", "robot-token-0123456789ab"}) {
    auto context = short_context(30);
    context->AddMetadata("authorization", std::string("Bearer ") + token);
    const auto run = run_live<v1::ExecuteRequest>(stub->Execute(context.get()), *context, panda_plan(),
                                                  [](Stream& stream, const LiveRun&) {
                                                    v1::ExecuteRequest stop;
                                                    stop.mutable_stop();
                                                    stream.Write(stop);
                                                  });
    if (std::string(token).rfind("cell", 0) == 0) {
      EXPECT_EQ(run.status.error_code(), grpc::StatusCode::PERMISSION_DENIED);
      EXPECT_THAT(run.status.error_message(), HasSubstr("scope `move`"));
    } else {
      EXPECT_TRUE(run.status.ok()) << run.status.error_message();
    }
  }
  server::stop_server(running, std::chrono::seconds(1));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace geotraj::testing
