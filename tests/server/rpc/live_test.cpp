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
#include <vector>

#include <grpc/grpc.h>

#include <gmock/gmock.h>

#include "tests/server/support/file_capture.hpp"
#include "tests/server/support/live_client.hpp"
#include "tests/server/support/production_support.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

using Stream = grpc::ClientReaderWriter<v1::ExecuteRequest, v1::SampleBatch>;
using JogStream = grpc::ClientReaderWriter<v1::JogRequest, v1::SampleBatch>;

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

// The acceleration reserve leaves room in the accelerations only: a path whose pace a speed
// limit sets (maxSpeed 0.15 m/s on the Panda's path C) is executed at that speed at 100 %
// (with a reserve that scaled the whole timing it ran at sqrt(0.9) of it, 0.142 m/s).
TEST_F(Live, TheReserveKeepsTheSpeedALimitSets) {
  auto first = panda_plan();
  first.mutable_plan()->mutable_motion()->set_max_speed(0.15);
  first.mutable_plan()->mutable_motion()->set_cycle_rate_hz(250.0);
  const auto run = execute(first, nullptr, true, 120.0);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "completed");
  // The path's samples (after the approach, step 1): their peak speed is the limit.
  double peak = 0.0;
  for (const auto& sample : run.samples) {
    if (sample.step() == 1) peak = std::max(peak, sample.speed());
  }
  EXPECT_NEAR(peak, 0.15, 0.15 * 2e-3);
  EXPECT_LE(peak, 0.15 * (1.0 + 1e-6));
  // The reserve changed the timing (the path and its approach, timed by the limits): the
  // first batch says so, once.
  EXPECT_EQ(run.first.acceleration_reserve(), 0.1);
  EXPECT_THAT(run.first.reserve_note(), HasSubstr("keep 10 % of every acceleration and jerk limit"));
  EXPECT_THAT(run.first.reserve_note(), HasSubstr("motion.accelerationScale x 0.9"));
  EXPECT_EQ(run.last.acceleration_reserve(), 0.0);
  EXPECT_TRUE(run.last.reserve_note().empty());
}

// A plan with a durationS (at the robot's pose: no approach) keeps its timing: the reserve
// changes nothing, and the first batch says none.
TEST_F(Live, APlanWithADurationIsNotReserved) {
  v1::ExecuteRequest first;
  *first.mutable_plan() = example<v1::PlanRequest>("linear_move_ur5.json");
  first.mutable_options()->set_deadman_s(2.0);
  const auto run = execute(first);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "completed");
  EXPECT_EQ(run.first.acceleration_reserve(), 0.0);
  EXPECT_TRUE(run.first.reserve_note().empty());
  EXPECT_NEAR(run.samples.back().plan_time(), 2.0, 1e-12);
}

// A path's Cartesian limits hold on the path, not on the joint move of its approach (whose
// plan does not keep them): with maxAcceleration 5 m/s^2 the Panda's path C plans within
// every limit, and Execute runs it (it was refused: "the plan uses 225.3 % of the tool
// tangential acceleration limit", measured on the approach's 12.9 m/s^2). A stop on the path
// keeps the tool's tangential acceleration within the limit, by differences of the speed.
TEST_F(Live, APathsCartesianLimitsHoldOnThePathNotOnItsJointApproach) {
  auto first = panda_plan();
  first.mutable_plan()->mutable_motion()->set_max_acceleration(5.0);
  bool sent = false;
  const auto run = execute(first, [&](Stream& stream, const LiveRun& r) {
    const auto& last = r.samples.back();
    if (!sent && last.step() == 1 && last.speed() > 0.3) {
      sent = true;
      v1::ExecuteRequest stop;
      stop.mutable_stop();
      stream.Write(stop);
    }
  });
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  ASSERT_TRUE(sent) << "the path never reached 0.3 m/s";
  EXPECT_EQ(run.reason, "stopped");
  expect_final_at_rest(run);
  double peak = 0.0;
  for (std::size_t k = 1; k < run.samples.size(); ++k) {
    const auto& a = run.samples[k - 1];
    const auto& b = run.samples[k];
    if (a.step() != 1 || b.step() != 1) continue;
    peak = std::max(peak, std::abs(b.speed() - a.speed()) / (b.t() - a.t()));
  }
  EXPECT_GT(peak, 1.0) << "the path accelerates";
  EXPECT_LE(peak, 5.0 * (1.0 + 1e-3));
}
// A path without a robot or Cartesian limits has no limited quantity: Execute runs it, its
// speed changes ramping over LiveOptions::ramp_s, and says so (the server crashed naming the
// binding row of an empty table).
TEST_F(Live, APathWithNothingLimitedIsExecuted) {
  v1::ExecuteRequest first;
  *first.mutable_plan() = example<v1::PlanRequest>("plan_demo_path_a.json");
  first.mutable_plan()->mutable_motion()->set_duration_s(1.0);
  first.mutable_options()->set_deadman_s(2.0);
  const auto run = execute(first);
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "completed");
  EXPECT_THAT(run.last.binding(), HasSubstr("no limit"));
  EXPECT_NEAR(run.samples.back().plan_time(), 1.0, 1e-12);
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
  std::vector<v1::LiveState> states;
  PauseResume script(/*pause_at=*/1.2, /*hold_s=*/0.3, /*override_at=*/0.6, /*override_percent=*/50.0);
  const auto run = execute(panda_plan(), [&](Stream& stream, const LiveRun& r) {
    states.push_back(r.last.state());
    script(stream, r);
  });
  const double paused_at = script.paused_at();
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "completed");
  EXPECT_TRUE(script.resumed());
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
  // The PA-10's joint move (planned in milliseconds, and well within a second under
  // ThreadSanitizer on a loaded machine) at a tenth of its speed lasts about 23 s: the 6 s
  // deadline falls mid-motion, long after the first set points.
  v1::ExecuteRequest first;
  *first.mutable_plan() = example<v1::PlanRequest>("joint_move_pa10.json");
  first.mutable_plan()->mutable_motion()->set_cycle_rate_hz(250.0);
  first.mutable_options()->set_speed_override(10.0);
  const auto run = execute(first, nullptr, true, /*deadline_s=*/6.0);
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
  // Both planned and moving (the Execute plans path C with its approach first: seconds under
  // the sanitizers on a loaded machine).
  ASSERT_TRUE(eventually([&] { return streaming.load() == 2; }, std::chrono::seconds(50)));
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

using LogCapture = FileCapture;

// A Jog of panda_joint1 at 0.5 rad/s with `acceleration` [rad/s^2] on that joint: a stop
// from speed takes about 0.5 / acceleration seconds.
v1::JogRequest slow_braking_jog(double acceleration) {
  auto first = panda_jog(30.0);
  auto* limits = first.mutable_start()->mutable_robot()->add_joint_limits();
  limits->set_joint("panda_joint1");
  limits->set_max_acceleration(acceleration);
  return first;
}

v1::JogRequest joint1_velocity(double velocity) {
  v1::JogRequest c;
  auto* v = c.mutable_joints()->mutable_velocities();
  for (int j = 0; j < 7; ++j) v->Add(j == 0 ? velocity : 0.0);
  return c;
}

// The drain's log line: how many arms it brought to rest and how many it cut.
TEST(LiveDrain, TheLogSaysHowManyArmsCameToRestAndHowManyWereCut) {
  for (const bool second_signal : {false, true}) {
    SCOPED_TRACE(second_signal ? "a second stop signal" : "a drain long enough to stop");
    LogCapture log;
    server::ServerOptions options;
    options.log_output = log.file();
    options.log_level = "warning";  // the drain's line is a warning when it cut an arm, else info
    if (!second_signal) options.log_level = "info";
    auto running = start(options);
    auto stub = stub_to(running.port);
    std::atomic<int> moving{0};
    std::vector<std::future<LiveRun>> jogs;
    for (int i = 0; i < 2; ++i) {
      jogs.push_back(std::async(std::launch::async, [&] {
        auto context = short_context(60);
        return run_live<v1::JogRequest>(stub->Jog(context.get()), *context, slow_braking_jog(0.25),
                                        [&, counted = false](JogStream& stream, const LiveRun&) mutable {
                                          if (!std::exchange(counted, true)) {
                                            stream.Write(joint1_velocity(0.5));
                                            ++moving;
                                          }
                                        });
      }));
    }
    ASSERT_TRUE(eventually([&] { return moving.load() == 2; }));
    std::this_thread::sleep_for(std::chrono::milliseconds(800));  // at about 0.2 rad/s: a stop of ~0.8 s
    std::stop_source now;
    if (second_signal) now.request_stop();
    server::stop_server(running, std::chrono::seconds(30), std::chrono::milliseconds(0), now.get_token());
    int at_rest = 0;
    for (auto& jog : jogs) {
      const LiveRun r = jog.get();
      if (r.reason == "drain") ++at_rest;
    }
    const std::string text = log.text();
    if (second_signal) {
      EXPECT_EQ(at_rest, 0);
      EXPECT_THAT(text, HasSubstr("live motions cut before they came to rest"));
      EXPECT_THAT(text, HasSubstr("live_at_rest=0 live_cut=2"));
    } else {
      EXPECT_EQ(at_rest, 2);
      EXPECT_THAT(text, HasSubstr("every live motion brought to rest"));
      EXPECT_THAT(text, HasSubstr("live_at_rest=2 live_cut=0"));
    }
  }
}

// Live calls are priced by their cycle rate: --max-live-rate-hz bounds the set points per
// second of all of them, and each takes one --max-streams slot per 1000 Hz.
class LiveAdmission : public ::testing::Test {
 protected:
  void serve(server::ServiceLimits limits) {
    server::ServerOptions options;
    options.limits = limits;
    running_ = start(options);
    stub_ = stub_to(running_.port);
  }
  void TearDown() override { server::stop_server(running_, std::chrono::seconds(5)); }

  // A Jog at `rate_hz` that stops at its first batch: how it ended.
  grpc::Status jog_once(double rate_hz) {
    auto first = panda_jog();
    first.mutable_start()->set_cycle_rate_hz(rate_hz);
    auto context = short_context(30);
    return run_live<v1::JogRequest>(stub_->Jog(context.get()), *context, first, [](JogStream& stream, const LiveRun&) {
             v1::JogRequest stop;
             stop.mutable_stop();
             stream.Write(stop);
           }).status;
  }

  // A Jog at `rate_hz` held open (its batches read on a thread) until release().
  struct Held {
    std::unique_ptr<grpc::ClientContext> context;
    std::unique_ptr<JogStream> stream;
    std::thread reader;
    std::atomic<bool> first{false};
    grpc::Status status;
  };
  std::unique_ptr<Held> hold(double rate_hz) {
    auto held = std::make_unique<Held>();
    held->context = short_context(60);
    held->stream = stub_->Jog(held->context.get());
    auto first = panda_jog(30.0);
    first.mutable_start()->set_cycle_rate_hz(rate_hz);
    held->stream->Write(first);
    Held* h = held.get();
    held->reader = std::thread([h] {
      v1::SampleBatch batch;
      while (h->stream->Read(&batch)) h->first = true;
    });
    EXPECT_TRUE(eventually([h] { return h->first.load(); })) << "the held jog at " << rate_hz << " Hz streams";
    return held;
  }
  void release(Held& held) {
    v1::JogRequest stop;
    stop.mutable_stop();
    held.stream->Write(stop);
    held.stream->WritesDone();
    held.reader.join();
    held.status = held.stream->Finish();
    EXPECT_TRUE(held.status.ok()) << held.status.error_message();
  }

  server::RunningServer running_;
  std::unique_ptr<v1::TrajectoryService::Stub> stub_;
};

TEST_F(LiveAdmission, AFastJogIsRefusedWhenTheRateBudgetIsFullWhileASlowOneFits) {
  server::ServiceLimits limits;
  limits.max_live_rate_hz = 12'000.0;
  serve(limits);
  auto fast = hold(10'000.0);
  const auto refused = jog_once(10'000.0);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("--max-live-rate-hz"));
  EXPECT_THAT(refused.error_message(), HasSubstr("10000 set points per second"));
  const auto slow = jog_once(100.0);
  EXPECT_TRUE(slow.ok()) << slow.error_message();
  release(*fast);
  // Its rate is given back when it ends.
  const auto again = jog_once(10'000.0);
  EXPECT_TRUE(again.ok()) << again.error_message();
  const auto exposition = server::metrics_exposition(running_);
  EXPECT_EQ(series(exposition, R"(geotraj_rpc_rejected_total{method="Jog",reason="live_rate"})"), 1);
}

TEST_F(LiveAdmission, AFastJogTakesAStreamSlotPerKilohertz) {
  server::ServiceLimits limits;
  limits.max_streams = 12;
  serve(limits);
  auto fast = hold(10'000.0);  // 10 of the 12 slots
  const auto refused = jog_once(2'500.0);  // 3 slots
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("--max-streams"));
  EXPECT_THAT(refused.error_message(), HasSubstr("takes 3 of the server's 12 stream slots"));
  const auto fits = jog_once(2'000.0);  // 2 slots
  EXPECT_TRUE(fits.ok()) << fits.error_message();
  // An Execute at 10 kHz is priced the same, before it is planned.
  auto execute = panda_plan();
  execute.mutable_plan()->mutable_motion()->set_cycle_rate_hz(10'000.0);
  auto context = short_context(30);
  const auto run = run_live<v1::ExecuteRequest>(stub_->Execute(context.get()), *context, execute, nullptr);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(run.status.error_message(), HasSubstr("--max-streams"));
  release(*fast);
  const auto again = jog_once(10'000.0);
  EXPECT_TRUE(again.ok()) << again.error_message();
}

// A plan's size is checked before it is planned when its request gives the duration, and
// before the live pass when the planner sets it.
TEST_F(LiveAdmission, APlanWithTooManySamplesIsRefusedBeforeItIsPlanned) {
  server::ServiceLimits limits;
  limits.max_live_samples = 2'000;
  serve(limits);
  auto first = panda_plan();
  first.mutable_plan()->mutable_motion()->set_duration_s(100.0);
  first.mutable_plan()->mutable_motion()->set_cycle_rate_hz(1000.0);
  // A path the planner would refuse: the size is checked first, without planning.
  first.mutable_plan()->mutable_path()->mutable_frames(0)->set_tangent_scale(-1.0);
  auto context = short_context(30);
  auto run = run_live<v1::ExecuteRequest>(stub_->Execute(context.get()), *context, first, nullptr);
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto violations = bad_request_violations(run.status);
  EXPECT_THAT(violation_of(violations, "plan.motion.durationS"), HasSubstr("100001 samples"));
  EXPECT_THAT(violation_of(violations, "plan.motion.durationS"), HasSubstr("--max-live-samples"));
  EXPECT_TRUE(run.samples.empty());

  // The time-optimal duration (durationS 0) is known once planned: refused before the live pass.
  auto timed = panda_plan();
  timed.mutable_plan()->mutable_motion()->set_duration_s(0.0);
  timed.mutable_plan()->mutable_motion()->set_cycle_rate_hz(1000.0);
  auto timed_context = short_context(30);
  run = run_live<v1::ExecuteRequest>(stub_->Execute(timed_context.get()), *timed_context, timed, nullptr);
  // (The robot's approach makes the plan a sequence: the violation is on plan.sequence.)
  EXPECT_EQ(run.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << run.status.error_message();
  EXPECT_THAT(describe(bad_request_violations(run.status)), HasSubstr("at most 2000 per call (geotrajd --max-live-samples)"));
  EXPECT_TRUE(run.samples.empty());

  // Within the cap: served.
  auto small = panda_plan();
  small.mutable_plan()->mutable_motion()->set_cycle_rate_hz(100.0);
  auto small_context = short_context(60);
  run = run_live<v1::ExecuteRequest>(stub_->Execute(small_context.get()), *small_context, small,
                                     [](Stream& stream, const LiveRun&) {
                                       v1::ExecuteRequest stop;
                                       stop.mutable_stop();
                                       stream.Write(stop);
                                     });
  EXPECT_TRUE(run.status.ok()) << run.status.error_message();
}

// A client that sends heartbeats but never reads is ended as one that sends nothing: its
// write stays in flight past the deadman time, the motion is stopped and the call cancelled.
TEST(LiveWriteDeadline, AClientThatNeverReadsIsEnded) {
  auto running = start(server::ServerOptions{});
  grpc::ChannelArguments args;  // a small receive window, so that the server's writes stall soon
  args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  args.SetInt(GRPC_ARG_HTTP2_STREAM_LOOKAHEAD_BYTES, 1024);
  auto stub = stub_to(running.port, nullptr, args);
  auto context = short_context(60);
  auto stream = stub->Jog(context.get());
  // A deadman time of 1 s: heartbeats every 50 ms keep it fed even on a loaded machine under
  // a sanitizer, so that what ends the call is the unread writes and not a late heartbeat.
  auto first = panda_jog(1.0);
  first.mutable_start()->set_cycle_rate_hz(10'000.0);
  ASSERT_TRUE(stream->Write(first));
  ASSERT_TRUE(stream->Write(joint1_velocity(0.2)));
  // Heartbeats every 50 ms for at most 30 s, never a read.
  bool ended = false;
  for (int i = 0; i < 600 && !ended; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    v1::JogRequest beat;
    beat.mutable_heartbeat();
    ended = !stream->Write(beat);
    if (!ended) {
      ended = series(server::metrics_exposition(running), R"(geotraj_live_stops_total{method="Jog",reason="unread"})") == 1;
    }
  }
  EXPECT_TRUE(ended) << "the call went on for 30 s without a read";
  context->TryCancel();
  (void)stream->Finish();
  EXPECT_TRUE(eventually([&] {
    return series(server::metrics_exposition(running), R"(geotraj_live_stops_total{method="Jog",reason="unread"})") == 1 &&
           series(server::metrics_exposition(running), "geotraj_active_streams") == 0;
  })) << server::metrics_exposition(running);
  const auto exposition = server::metrics_exposition(running);
  EXPECT_EQ(series(exposition, R"(geotraj_rpc_calls_total{method="Jog",code="ABORTED"})"), 1);
  server::stop_server(running, std::chrono::seconds(1));
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
