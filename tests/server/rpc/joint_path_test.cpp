// Joint paths through waypoints through the real service: a pick and place of nine Panda
// waypoints (as a sampling planner returns them) planned, streamed at 1 and 4 kHz and
// measured on the samples (the ends met exactly, every interior waypoint passed within the
// tolerance, never at rest between the ends, every joint's velocity, acceleration and jerk
// within its limits by differences, the acceleration's steps shrinking with the rate);
// random waypoints on every built-in arm; the time-optimal sweep alone faster than the
// jerk-limited default; a joint path as a sequence step; Execute with pause and resume;
// bad input named by field.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <gmock/gmock.h>

#include "tests/server/support/live_client.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;
using Waypoints = std::vector<std::vector<double>>;

class JointPathTest : public ServerTest {};

// Nine waypoints of a pick and place on the Panda: from home over a part, down, up, across,
// down to the place, up and back (joint values a sampling planner would return).
const Waypoints kPickAndPlace = {
    {0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785},   {0.35, -0.45, 0.1, -2.2, 0.05, 1.8, 1.1},
    {0.42, -0.1, 0.12, -2.35, 0.02, 2.25, 1.2},      {0.42, 0.05, 0.12, -2.45, 0.02, 2.5, 1.2},
    {0.3, -0.3, 0.05, -2.3, 0.0, 2.0, 1.0},          {-0.3, -0.35, -0.05, -2.25, 0.0, 1.95, 0.4},
    {-0.45, 0.0, -0.1, -2.4, -0.02, 2.4, 0.3},       {-0.3, -0.4, -0.05, -2.2, 0.0, 1.85, 0.5},
    {0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785}};

v1::PlanRequest joint_path_request(const std::string& robot, const Waypoints& waypoints, double tolerance,
                                   double rate_hz) {
  v1::PlanRequest request;
  request.mutable_robot()->set_name(robot);
  request.mutable_motion()->set_cycle_rate_hz(rate_hz);
  auto& path = *request.mutable_joint_path();
  path.set_blend_tolerance(tolerance);
  for (const auto& w : waypoints) {
    auto& out = *path.add_waypoints();
    for (const double q : w) out.add_positions(q);
  }
  return request;
}

Eigen::VectorXd joints(const v1::Sample& s) {
  Eigen::VectorXd q(s.joints_size());
  for (int j = 0; j < s.joints_size(); ++j) q(j) = s.joints(j);
  return q;
}

Eigen::VectorXd vec(const std::vector<double>& v) { return Eigen::Map<const Eigen::VectorXd>(v.data(), v.size()); }

// Waypoints drawn within the middle half of `model`'s position limits.
Waypoints random_waypoints(const v1::RobotModel& model, std::size_t count, unsigned seed) {
  std::mt19937 rng(seed);
  Waypoints out(count);
  for (auto& w : out) {
    for (const auto& l : model.limits()) {
      const double mid = 0.5 * (l.min_position() + l.max_position()), half = 0.25 * (l.max_position() - l.min_position());
      w.push_back(std::uniform_real_distribution<double>(mid - half, mid + half)(rng));
    }
  }
  return out;
}

// What the samples of a joint path show.
struct Measured {
  double worst_velocity = 0.0, worst_acceleration = 0.0, worst_jerk = 0.0;  // of the limits, by differences
  double largest_acceleration_step = 0.0;                                  // [rad/s^2] between samples
  double farthest_waypoint = 0.0;  // the largest distance of an interior waypoint to the samples
};

Measured measure(const v1::RobotModel& model, const std::vector<v1::Sample>& s, const Waypoints& waypoints) {
  Measured m;
  for (std::size_t k = 1; k + 1 < s.size(); ++k) {
    const double h0 = s[k].t() - s[k - 1].t(), h1 = s[k + 1].t() - s[k].t();
    for (int j = 0; j < model.limits_size(); ++j) {
      const auto& l = model.limits(j);
      const double v = (s[k + 1].joints(j) - s[k].joints(j)) / h1;
      const double a = 2.0 * (v - (s[k].joints(j) - s[k - 1].joints(j)) / h0) / (h0 + h1);
      m.worst_velocity = std::max(m.worst_velocity, std::abs(v) / l.max_velocity());
      m.worst_acceleration = std::max(m.worst_acceleration, std::abs(a) / l.max_acceleration());
      const double step = std::abs(s[k].joint_accelerations(j) - s[k - 1].joint_accelerations(j));
      m.largest_acceleration_step = std::max(m.largest_acceleration_step, step);
      if (l.has_max_jerk()) m.worst_jerk = std::max(m.worst_jerk, step / h0 / l.max_jerk());
    }
  }
  for (std::size_t i = 1; i + 1 < std::max<std::size_t>(waypoints.size(), 1); ++i) {
    double nearest = 1e300;
    for (const auto& x : s) nearest = std::min(nearest, (joints(x) - vec(waypoints[i])).norm());
    m.farthest_waypoint = std::max(m.farthest_waypoint, nearest);
  }
  return m;
}

TEST_F(JointPathTest, APickAndPlaceOnThePandaPassesItsWaypointsWithinTheLimits) {
  const auto model = robot_model("panda");
  constexpr double kTolerance = 0.05;
  double steps[2] = {0.0, 0.0}, durations[2] = {0.0, 0.0};
  for (const double rate : {1000.0, 4000.0}) {
    const auto request = joint_path_request("panda", kPickAndPlace, kTolerance, rate);
    const v1::PlanResponse planned = plan_ok(request);
    grpc::Status status;
    const auto samples = stream_all(request, status);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(samples.size(), planned.motion().sample_count());
    EXPECT_EQ(joints(samples.front()), vec(kPickAndPlace.front()));
    EXPECT_EQ(joints(samples.back()), vec(kPickAndPlace.back()));
    for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
      double speed = 0.0;
      for (const double v : samples[k].joint_velocities()) speed = std::max(speed, std::abs(v));
      ASSERT_GT(speed, 0.0) << "at rest at t " << samples[k].t();
    }
    const Measured m = measure(model, samples, kPickAndPlace);
    EXPECT_LE(m.worst_velocity, 1.0 + 1e-3) << rate << " Hz";
    EXPECT_LE(m.worst_acceleration, 1.0 + 2e-2) << rate << " Hz";
    EXPECT_LE(m.worst_jerk, 1.0 + 1e-6) << rate << " Hz";
    // Within the tolerance, and the samples' spacing (at most maxVelocity / rate per joint).
    EXPECT_LE(m.farthest_waypoint, kTolerance + 3.0 * 2.61 / rate) << rate << " Hz";
    const int r = rate == 1000.0 ? 0 : 1;
    steps[r] = m.largest_acceleration_step;
    durations[r] = planned.motion().duration_s();
    std::printf("[ figure   ] panda pick and place at %g Hz: %.4f s, largest acceleration step %.5f rad/s^2, "
                "farthest waypoint %.4f rad\n",
                rate, durations[r], m.largest_acceleration_step, m.farthest_waypoint);
  }
  // The acceleration is continuous: its steps between samples shrink with the period.
  EXPECT_LT(steps[1], 0.4 * steps[0]);
  EXPECT_NEAR(durations[1], durations[0], 0.02 * durations[0]);
}

TEST_F(JointPathTest, RandomWaypointsOnEveryArmStayWithinTheLimits) {
  for (const std::string robot : {"panda", "ur5e", "ur5", "pa10"}) {
    const auto model = robot_model(robot);
    const Waypoints waypoints = random_waypoints(model, 6, 17);
    const auto request = joint_path_request(robot, waypoints, 0.1, 500.0);
    grpc::Status status;
    const auto samples = stream_all(request, status);
    ASSERT_TRUE(status.ok()) << robot << ": " << status.error_message();
    const Measured m = measure(model, samples, waypoints);
    EXPECT_LE(m.worst_velocity, 1.0 + 1e-3) << robot;
    EXPECT_LE(m.worst_acceleration, 1.0 + 2e-2) << robot;
    EXPECT_LE(m.farthest_waypoint, 0.1 + 3.0 * 3.2 / 500.0) << robot;
    EXPECT_EQ(joints(samples.back()), vec(waypoints.back())) << robot;
  }
}

TEST_F(JointPathTest, TheSweepAloneIsFasterAndALargerToleranceFaster) {
  auto request = joint_path_request("panda", kPickAndPlace, 0.05, 250.0);
  const double jerk_limited = plan_ok(request).motion().duration_s();
  request.mutable_optimize()->mutable_timing()->set_time_optimal(true);
  // The sweep alone steps the accelerations, which may break the Panda's jerk limits at the
  // cycle rate (then refused naming the jerk): the robot only reports what it cannot follow.
  request.mutable_robot()->set_report_only(true);
  const v1::PlanResponse sweep = plan_ok(request);
  EXPECT_LT(sweep.motion().duration_s(), jerk_limited);
  request.mutable_joint_path()->set_blend_tolerance(0.2);
  EXPECT_LT(plan_ok(request).motion().duration_s(), sweep.motion().duration_s());
  request.mutable_joint_path()->set_blend_tolerance(0.0);
  EXPECT_GT(plan_ok(request).motion().duration_s(), sweep.motion().duration_s());
}

TEST_F(JointPathTest, AGivenDurationIsHonoured) {
  auto request = joint_path_request("panda", kPickAndPlace, 0.05, 250.0);
  request.mutable_motion()->set_duration_s(12.0);
  EXPECT_DOUBLE_EQ(plan_ok(request).motion().duration_s(), 12.0);
}

TEST_F(JointPathTest, AJointPathIsASequenceStepThatStartsWhereThePreviousEnds) {
  auto request = joint_path_request("panda", kPickAndPlace, 0.05, 250.0);
  v1::PlanRequest sequence;
  *sequence.mutable_robot() = request.robot();
  *sequence.mutable_motion() = request.motion();
  auto& move = *sequence.add_sequence()->mutable_joint_move();
  for (const double q : kPickAndPlace.front()) move.add_goal(q);
  *sequence.add_sequence()->mutable_joint_path() = request.joint_path();
  const v1::PlanResponse planned = plan_ok(sequence);
  ASSERT_EQ(planned.steps_size(), 2);
  EXPECT_EQ(planned.steps(1).kind(), "jointPath");

  sequence.mutable_sequence(1)->mutable_joint_path()->mutable_waypoints(0)->set_positions(2, 0.3);
  v1::PlanResponse response;
  const auto status = plan(sequence, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_THAT(violation_of(bad_request_violations(status), "sequence[1].jointPath.waypoints[0].positions[2]"),
              HasSubstr("where sequence[0] ends"));
}

TEST_F(JointPathTest, ExecutePausesAndResumesOnThePathAndEndsAtTheLastWaypoint) {
  v1::ExecuteRequest first;
  *first.mutable_plan() = joint_path_request("panda", kPickAndPlace, 0.05, 250.0);
  first.mutable_options()->set_deadman_s(2.0);
  PauseResume script(/*pause_at=*/0.8, /*hold_s=*/0.3);
  auto ctx = context();
  using Stream = grpc::ClientReaderWriter<v1::ExecuteRequest, v1::SampleBatch>;
  const LiveRun run = run_live<v1::ExecuteRequest>(stub_->Execute(ctx.get()), *ctx, first,
                                                   [&](Stream& stream, const LiveRun& r) { script(stream, r); });
  const double paused_at = script.paused_at();
  ASSERT_TRUE(run.status.ok()) << run.status.error_message();
  EXPECT_EQ(run.reason, "completed");
  EXPECT_TRUE(script.resumed());
  // Held while paused: one point of the path, at rest; then the rest of the plan.
  const v1::Sample* held = nullptr;
  for (const auto& s : run.samples) {
    if (s.t() < paused_at || s.t() > paused_at + 0.25) continue;
    if (held == nullptr) held = &s;
    EXPECT_EQ(s.plan_time(), held->plan_time());
    EXPECT_EQ(joints(s), joints(*held));
  }
  ASSERT_NE(held, nullptr);
  EXPECT_EQ(joints(run.samples.back()), vec(kPickAndPlace.back()));
  EXPECT_NEAR(run.samples.back().plan_time(), run.last.plan_duration_s(), 1e-12);
  // Every joint within its limits through the pause, by differences of what was streamed.
  const Measured m = measure(robot_model("panda"), run.samples, {});
  EXPECT_LE(m.worst_velocity, 1.0 + 1e-3);
  EXPECT_LE(m.worst_acceleration, 1.0 + 2e-2);
}

TEST_F(JointPathTest, BadInputIsNamedByField) {
  auto request = joint_path_request("panda", kPickAndPlace, -0.1, 250.0);
  request.mutable_joint_path()->mutable_waypoints(3)->set_positions(1, std::nan(""));
  request.mutable_joint_path()->mutable_waypoints(4)->add_positions(0.0);
  request.mutable_joint_path()->mutable_waypoints(5)->set_positions(3, 1.0);  // beyond joint 3's limit
  v1::PlanResponse response;
  auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  auto violations = bad_request_violations(status);
  EXPECT_THAT(violation_of(violations, "jointPath.blendTolerance"), HasSubstr(">= 0")) << describe(violations);
  EXPECT_THAT(violation_of(violations, "jointPath.waypoints[3].positions[1]"), HasSubstr("finite"));
  EXPECT_THAT(violation_of(violations, "jointPath.waypoints[4].positions"), HasSubstr("7 joints"));
  EXPECT_THAT(violation_of(violations, "jointPath.waypoints[5].positions[3]"), HasSubstr("position limits"));

  request = joint_path_request("panda", kPickAndPlace, 0.05, 250.0);
  request.mutable_motion()->set_max_speed(0.5);
  request.mutable_robot()->add_initial_joints(0.1);
  for (int j = 1; j < 7; ++j) request.mutable_robot()->add_initial_joints(kPickAndPlace[0][static_cast<std::size_t>(j)]);
  status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  violations = bad_request_violations(status);
  EXPECT_THAT(violation_of(violations, "motion.maxSpeed"), HasSubstr("Cartesian")) << describe(violations);
  EXPECT_THAT(violation_of(violations, "jointPath.waypoints[0].positions[0]"), HasSubstr("initialJoints"));

  request = joint_path_request("panda", kPickAndPlace, 0.05, 250.0);
  request.clear_robot();
  status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "robot"), HasSubstr("jointPath"));

  request = joint_path_request("panda", {kPickAndPlace[0]}, 0.05, 250.0);
  status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "jointPath.waypoints"), HasSubstr("at least 2"));
}

}  // namespace
}  // namespace geotraj::testing
