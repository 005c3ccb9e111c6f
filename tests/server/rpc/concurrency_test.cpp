// Every RPC at once, many at a time, from many clients, some cancelled midway: the server
// stays up and answers every call with the code it should. Optimisations of every kind run
// concurrently, the redundancy optimiser on Ceres among them (Ipopt's MUMPS is not
// thread-safe: optim serialises it). Run under ASan and UBSan (make sanitize) and
// ThreadSanitizer (make tsan) in CI.
#include <atomic>
#include <future>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include <gmock/gmock.h>

#include "planner/robots.hpp"
#include "tests/support/sanitizers.hpp"
#include "tests/server/support/production_support.hpp"

namespace geotraj::testing {
namespace {

// The time-optimal PA-10 plan along path C (durationS 0: the sweep; jerkLimited: the NLP).
v1::PlanRequest pa10_fastest(bool jerk_limited) {
  auto request = example<v1::PlanRequest>("plan_pa10_path_c.json");
  request.mutable_motion()->set_duration_s(0.0);
  request.mutable_robot()->set_report_only(false);
  if (jerk_limited) request.mutable_optimize()->mutable_timing()->set_jerk_limited(true);
  if (jerk_limited) request.mutable_optimize()->set_time_budget_s(1.0);
  return request;
}

// Lowest degree (Ipopt, serialised) or the default smoothest reading (NLopt's SLSQP, reentrant).
v1::PlanRequest tangent_scales(bool smoothest = false) {
  auto request = smoothest ? demo_example('a') : demo_request('a');
  request.mutable_optimize()->mutable_tangent_scales()->set_objective(v1::TANGENT_SCALE_OBJECTIVE_BENDING_ENERGY);
  return request;
}

v1::PlanRequest breakpoints() {
  auto request = example<v1::PlanRequest>("appendix_b_optimized.json");
  request.mutable_optimize()->set_time_budget_s(0.3);
  return request;
}

class Concurrency : public ::testing::Test {
 protected:
  void SetUp() override {
    server::ServerOptions options;
    options.limits.max_unary_calls = 1000;
    running_ = start(options);
    ASSERT_GT(running_.port, 0);
  }
  void TearDown() override { server::stop_server(running_, std::chrono::seconds(5)); }

  // One call of kind `k`; `cancel_after` > 0 cancels it after that long; `smoothest`: the
  // tangent-scale kind under the default reading. Returns its code.
  grpc::StatusCode call(v1::TrajectoryService::Stub& stub, int k, std::chrono::milliseconds cancel_after,
                        bool smoothest = false) {
    auto ctx = short_context(120);
    std::optional<std::jthread> canceller;
    if (cancel_after.count() > 0) {
      canceller.emplace([&ctx, cancel_after](std::stop_token stop) {
        const auto until = std::chrono::steady_clock::now() + cancel_after;
        while (!stop.stop_requested() && std::chrono::steady_clock::now() < until) {
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
        ctx->TryCancel();
      });
    }
    grpc::Status status;
    v1::PlanResponse plan;
    switch (k) {
      case 0: status = stub.PlanTrajectory(ctx.get(), demo_request('b'), &plan); break;
      case 1: status = stub.PlanTrajectory(ctx.get(), tangent_scales(smoothest), &plan); break;
      case 2: status = stub.PlanTrajectory(ctx.get(), breakpoints(), &plan); break;
      case 3: status = stub.PlanTrajectory(ctx.get(), pa10_fastest(false), &plan); break;
      case 4: status = stub.PlanTrajectory(ctx.get(), pa10_fastest(true), &plan); break;
      case 5: {
        v1::PathProfile profile;
        auto request = demo_request('c');
        request.set_analysis_points(2001);
        status = stub.AnalyzePath(ctx.get(), request, &profile);
        break;
      }
      case 6: {
        v1::ConvertResponse response;
        status = stub.ConvertConstraints(ctx.get(), example<v1::ConvertRequest>("convert_table_5_10.json"), &response);
        break;
      }
      case 7: {
        v1::ListRobotsResponse response;
        status = stub.ListRobots(ctx.get(), {}, &response);
        break;
      }
      case 8: {  // a stream, as fast as possible
        std::size_t samples = 0;
        status = read_stream(stub, demo_request('a'), samples, *ctx);
        if (status.ok()) {
          EXPECT_EQ(samples, 1001u);
        }
        break;
      }
      case 9: {  // a real-time stream
        std::size_t samples = 0;
        status = read_stream(stub, real_time_request(0.3), samples, *ctx);
        break;
      }
      case 10: {  // a joint-space stream on the PA-10
        std::size_t samples = 0;
        status = read_stream(stub, example<v1::PlanRequest>("joint_move_pa10.json"), samples, *ctx);
        break;
      }
      case 11: {  // forward kinematics
        v1::ForwardKinematicsResponse response;
        status = stub.ComputeForwardKinematics(ctx.get(), example<v1::ForwardKinematicsRequest>("fk_pa10.json"),
                                               &response);
        break;
      }
      case 12: {  // every branch of a UR5 pose (256 attempts of IK)
        v1::InverseKinematicsResponse response;
        status = stub.ComputeInverseKinematics(ctx.get(), example<v1::InverseKinematicsRequest>("ik_ur5_all.json"),
                                               &response);
        if (status.ok()) {
          EXPECT_EQ(response.solutions_size(), 8);
        }
        break;
      }
      case 13: {  // a sequence of moves streamed on the UR5 (IK seeded step by step)
        std::size_t samples = 0;
        status = read_stream(stub, example<v1::PlanRequest>("sequence_ur5.json"), samples, *ctx);
        break;
      }
      case 14: {  // forward kinematics of an inline URDF (urdfdom and TinyXML in every call)
        v1::ForwardKinematicsRequest request;
        request.mutable_robot()->set_urdf(std::string(planner::builtin_urdf("iiwa14")));
        for (int j = 0; j < 7; ++j) request.add_joints(0.1 * j);
        v1::ForwardKinematicsResponse response;
        status = stub.ComputeForwardKinematics(ctx.get(), request, &response);
        break;
      }
      case 15: {  // path C streamed on the Panda given inline as its URDF
        auto request = example<v1::PlanRequest>("plan_panda_path_c.json");
        request.mutable_robot()->set_urdf(std::string(planner::builtin_urdf("panda")));
        std::size_t samples = 0;
        status = read_stream(stub, request, samples, *ctx);
        break;
      }
      case 16: {  // Panda path C executed live: override 50 %, a pause, a resume, then a stop
        status = execute(stub, *ctx, "plan_panda_path_c.json", [](int n, v1::ExecuteRequest& c) {
          if (n == 5) c.set_speed_override(50.0);
          if (n == 10) c.mutable_pause();
          if (n == 20) c.mutable_resume();
          if (n == 30) c.mutable_stop();
          return n == 5 || n == 10 || n == 20 || n == 30;
        });
        break;
      }
      case 17: {  // a Cartesian jog of the Panda, then a stop
        auto stream = stub.Jog(ctx.get());
        v1::JogRequest first;
        first.mutable_start()->mutable_robot()->set_name("panda");
        first.mutable_start()->set_cycle_rate_hz(500.0);
        first.mutable_start()->set_deadman_s(5.0);
        stream->Write(first);
        v1::SampleBatch batch;
        for (int n = 0; stream->Read(&batch); ++n) {
          v1::JogRequest c;
          if (n == 1) c.mutable_twist()->mutable_linear()->set_x(0.5);
          if (n == 20) c.mutable_stop();
          if (n == 1 || n == 20) stream->Write(c);
        }
        stream->WritesDone();
        status = stream->Finish();
        break;
      }
      case 18: {  // a joint path through nine Panda waypoints, streamed (jerk-limited timing)
        std::size_t samples = 0;
        status = read_stream(stub, example<v1::PlanRequest>("plan_joint_path_panda.json"), samples, *ctx);
        break;
      }
      case 19: {  // the same joint path executed live: a pause, a resume, then a stop on the path
        status = execute(stub, *ctx, "plan_joint_path_panda.json", [](int n, v1::ExecuteRequest& c) {
          if (n == 5) c.mutable_pause();
          if (n == 15) c.mutable_resume();
          if (n == 25) c.mutable_stop();
          return n == 5 || n == 15 || n == 25;
        });
        break;
      }
      case 20: {  // the PA-10's self-motion chosen for the whole of path A (Ceres), 3 s at 100 Hz
        auto request = demo_request('a');
        request.mutable_robot()->set_name("pa10");
        request.mutable_robot()->set_report_only(true);
        request.mutable_motion()->set_duration_s(3.0);
        request.mutable_optimize()->mutable_redundancy()->set_acceleration_weight(1.0);
        status = stub.PlanTrajectory(ctx.get(), request, &plan);
        break;
      }
      case 21: {  // the UR5e's seam with the torch's roll chosen with the joints (Ceres), streamed
        std::size_t samples = 0;
        status = read_stream(stub, example<v1::PlanRequest>("plan_seam_roll_ur5e.json"), samples, *ctx);
        break;
      }
      default: {  // a health watch, read until cancelled or its deadline
        auto health_stub = grpc::health::v1::Health::NewStub(channel_for(stub));
        grpc::health::v1::HealthCheckRequest request;
        auto reader = health_stub->Watch(ctx.get(), request);
        HealthStatus s;
        while (reader->Read(&s)) {
          if (cancel_after.count() == 0) ctx->TryCancel();
        }
        status = reader->Finish();
        if (cancel_after.count() == 0 && status.error_code() == grpc::StatusCode::CANCELLED) status = grpc::Status::OK;
      }
    }
    if (canceller) canceller->request_stop();
    if (!status.ok() && cancel_after.count() == 0) {
      ADD_FAILURE() << "call kind " << k << ": " << status.error_code() << " " << status.error_message();
    }
    return status.error_code();
  }

  // Execute of the example request `file` (deadman 5 s); after the n-th batch, `control(n, c)`
  // fills a command c and says whether to send it.
  template <class Control>
  static grpc::Status execute(v1::TrajectoryService::Stub& stub, grpc::ClientContext& ctx, const char* file,
                              const Control& control) {
    auto stream = stub.Execute(&ctx);
    v1::ExecuteRequest first;
    *first.mutable_plan() = example<v1::PlanRequest>(file);
    first.mutable_options()->set_deadman_s(5.0);
    stream->Write(first);
    v1::SampleBatch batch;
    for (int n = 0; stream->Read(&batch); ++n) {
      v1::ExecuteRequest c;
      if (control(n, c)) stream->Write(c);
    }
    stream->WritesDone();
    return stream->Finish();
  }

  std::shared_ptr<grpc::Channel> channel_for(v1::TrajectoryService::Stub&) {
    return grpc::CreateChannel("127.0.0.1:" + std::to_string(running_.port), grpc::InsecureChannelCredentials());
  }

  server::RunningServer running_;
};

constexpr int kKinds = 23;

TEST_F(Concurrency, EveryRpcManyAtOnceSomeCancelledMidway) {
  constexpr int kClients = 6;
  // Under the sanitizers one round (some 200 s of three under ASan): every kind is still
  // called by the six clients, cancelled by two of them, with both variants of the kinds
  // that have two.
  constexpr int kRounds = kSanitized ? 1 : 3;
  std::mutex mutex;
  std::map<grpc::StatusCode, int> codes;
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&, c] {
      auto stub = v1::TrajectoryService::NewStub(grpc::CreateChannel(
          "127.0.0.1:" + std::to_string(running_.port), grpc::InsecureChannelCredentials()));
      std::mt19937 random(static_cast<unsigned>(c));
      for (int r = 0; r < kRounds; ++r) {
        for (int k = 0; k < kKinds; ++k) {
          const int kind = (k + c) % kKinds;
          // Every third call is cancelled after 1-30 ms: before, during or after its work.
          const bool cancel = (k + r + c) % 3 == 0;
          const auto after = std::chrono::milliseconds(cancel ? 1 + static_cast<int>(random() % 30) : 0);
          const auto code = call(*stub, kind, after, (r + c) % 2 == 1);
          const std::lock_guard lock(mutex);
          ++codes[code];
          if (cancel) {
            EXPECT_THAT(code, ::testing::AnyOf(grpc::StatusCode::OK, grpc::StatusCode::CANCELLED))
                << "kind " << kind << " cancelled midway";
          }
        }
      }
    });
  }
  for (auto& t : clients) t.join();
  for (const auto& [code, n] : codes) std::printf("[ measured ] code %d: %d calls\n", static_cast<int>(code), n);
  // The server is whole: health, and a plan.
  EXPECT_EQ(health(running_.port, ""), HealthStatus::SERVING);
  EXPECT_TRUE(list_robots(*stub_to(running_.port)).ok());
  // Cancelled work stops at its next check of the call (within a stage or 16 IK samples).
  EXPECT_TRUE(eventually([&] {
    const auto m = server::metrics_exposition(running_);
    return series(m, "geotraj_active_unary_calls") == 0.0 && series(m, "geotraj_active_streams") == 0.0;
  }));
}

// The defect that took the server down: four clients optimising tangent scales at once
// (each Ipopt solve factors with MUMPS, whose state is global).
TEST_F(Concurrency, TangentScaleOptimisationsAtOnce) {
  std::vector<std::future<grpc::Status>> calls;
  for (int c = 0; c < 4; ++c) {
    calls.push_back(std::async(std::launch::async, [this, c] {
      auto stub = stub_to(running_.port);
      grpc::Status last;
      for (int i = 0; i < 3; ++i) {
        v1::PlanResponse response;
        last = stub->PlanTrajectory(short_context(120).get(), tangent_scales((c + i) % 2 == 1), &response);
        if (!last.ok()) return last;
        EXPECT_TRUE(response.optimization().has_tangent_scales());
      }
      return last;
    }));
  }
  for (auto& c : calls) {
    const auto status = c.get();
    EXPECT_TRUE(status.ok()) << status.error_message();
  }
}

}  // namespace
}  // namespace geotraj::testing
