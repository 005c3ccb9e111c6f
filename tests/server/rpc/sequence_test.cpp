// PlanRequest.sequence through the real service: the UR5 pick-and-place example
// (client/grpcurl/sequence_ur5.json) planned and streamed, its samples checked by finite
// differences across the junctions (one grid, continuous joints, at rest there, within every
// joint limit), each step's start defaulting to where the previous one ended, and the
// refusals: a given start elsewhere, a path that starts elsewhere, mixed rates, a sequence
// with a path beside it, an empty step.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gmock/gmock.h>

#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

class SequenceTest : public ServerTest {
 protected:
  v1::ListRobotsResponse robots() {
    v1::ListRobotsResponse response;
    EXPECT_TRUE(stub_->ListRobots(context().get(), v1::ListRobotsRequest{}, &response).ok());
    return response;
  }
  const v1::RobotModel* model(const v1::ListRobotsResponse& all, const std::string& name) {
    for (const auto& r : all.robots()) {
      if (r.name() == name) return &r;
    }
    return nullptr;
  }
};

// Step i of `request` as a straight path up from z = 0.3 m to 0.45 m at (x, y).
void straight_up(v1::PlanRequest& request, int i, double x, double y) {
  auto* step = request.mutable_sequence(i);
  step->clear_linear_move();
  auto* path = step->mutable_path();
  for (double z : {0.3, 0.45}) {
    auto* f = path->add_frames();
    f->mutable_position()->set_x(x);
    f->mutable_position()->set_y(y);
    f->mutable_position()->set_z(z);
    f->mutable_tangent()->set_z(1.0);
  }
}

double norm(const v1::Vec3& v) { return std::sqrt(v.x() * v.x() + v.y() * v.y() + v.z() * v.z()); }

TEST_F(SequenceTest, PickAndPlaceStreamsOneContinuousMotionWithinTheJointLimits) {
  const auto request = example<v1::PlanRequest>("sequence_ur5.json");
  ASSERT_EQ(request.sequence_size(), 4);
  const auto response = plan_ok(request);
  ASSERT_EQ(response.steps_size(), 4);
  const double rate = request.motion().cycle_rate_hz();
  const double period = 1.0 / rate;

  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(samples.size(), response.motion().sample_count());
  EXPECT_NEAR(samples.back().t(), response.motion().duration_s(), 1e-12);

  // The steps tile the samples, each starting on the grid where the previous one ended.
  std::uint64_t next = 0;
  for (int i = 0; i < response.steps_size(); ++i) {
    SCOPED_TRACE("step " + std::to_string(i));
    const auto& step = response.steps(i);
    EXPECT_EQ(step.index(), static_cast<unsigned>(i));
    EXPECT_EQ(step.first_sample(), next);
    next += step.sample_count();
    const auto& first = samples[step.first_sample()];
    EXPECT_EQ(first.step(), static_cast<unsigned>(i));
    EXPECT_NEAR(first.t(), step.start_time_s(), 1e-12);
    EXPECT_NEAR(first.t() * rate, std::round(first.t() * rate), 1e-6) << "on the grid";
    EXPECT_LT(norm(first.velocity()), 1e-12) << "at rest at the junction";
    for (double qd : first.joint_velocities()) EXPECT_LT(std::abs(qd), 1e-9);
    if (i > 0) {
      const auto& prev = response.steps(i - 1);
      EXPECT_GE(step.start_time_s(), prev.start_time_s() + prev.duration_s() - 1e-12);
      EXPECT_LT(step.start_time_s(), prev.start_time_s() + prev.duration_s() + period);
    }
  }
  EXPECT_EQ(next, samples.size());
  EXPECT_EQ(response.steps(0).kind(), "linearMove");
  EXPECT_EQ(response.steps(2).kind(), "jointMove");
  EXPECT_NEAR(response.steps(1).arc_length(), 0.15, 1e-12);
  EXPECT_NEAR(response.steps(1).duration_s(), 1.5, 1e-12) << "its own motion";

  // Every sample on one grid (the last at the end), joints continuous: velocities and
  // accelerations by finite differences within the limits, across the junctions too.
  const auto all = robots();
  const v1::RobotModel* ur5 = model(all, "ur5");
  ASSERT_NE(ur5, nullptr);
  const int n = ur5->links_size();
  for (std::size_t k = 1; k < samples.size(); ++k) {
    SCOPED_TRACE("sample " + std::to_string(k));
    const double dt = samples[k].t() - samples[k - 1].t();
    ASSERT_GT(dt, 0.0);
    if (k + 1 < samples.size()) {
      ASSERT_NEAR(dt, period, 1e-9);
    }
    ASSERT_GE(samples[k].step(), samples[k - 1].step());
    for (int j = 0; j < n; ++j) {
      const auto& limits = ur5->limits(j);
      const double v = (samples[k].joints(j) - samples[k - 1].joints(j)) / dt;
      ASSERT_LE(std::abs(v), limits.max_velocity() * (1 + 1e-3)) << "joint " << j;
      if (k + 1 < samples.size()) {
        const double a = (samples[k + 1].joints(j) - 2 * samples[k].joints(j) + samples[k - 1].joints(j)) /
                         (period * period);
        ASSERT_LE(std::abs(a), limits.max_acceleration() * (1 + 2e-2)) << "joint " << j;
      }
    }
  }
  // The goals: the end of each step's move.
  const auto& end_of_step1 = samples[response.steps(2).first_sample()];
  EXPECT_NEAR(end_of_step1.position().z(), 0.45, 1e-9);
  EXPECT_NEAR(samples.back().position().x(), -0.1, 1e-9);
  EXPECT_NEAR(samples.back().position().y(), -0.45, 1e-9);
  EXPECT_NEAR(samples.back().position().z(), 0.3, 1e-9);
  EXPECT_NEAR(std::abs(samples.back().orientation().y()), 1.0, 1e-9);
  EXPECT_TRUE(response.robot().feasible());
  EXPECT_TRUE(response.robot().violations().empty());
}

TEST_F(SequenceTest, AGivenStartElsewhereIsNamed) {
  auto request = example<v1::PlanRequest>("sequence_ur5.json");
  auto* start = request.mutable_sequence(1)->mutable_linear_move()->mutable_start();
  start->mutable_position()->set_x(-0.3);
  start->mutable_position()->set_y(-0.25);
  start->mutable_position()->set_z(0.31);  // 1 cm above where step 0 ends
  start->mutable_orientation()->set_y(1.0);
  v1::PlanResponse response;
  auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_THAT(violation_of(bad_request_violations(status), "sequence[1].linearMove.start"),
              HasSubstr("0.01 m and 0 rad from where sequence[0] ends"));

  // Exactly there (to rounding) is accepted.
  start->mutable_position()->set_z(0.3 + 1e-9);
  EXPECT_TRUE(plan(request, response).ok());

  request = example<v1::PlanRequest>("sequence_ur5.json");
  auto* move = request.mutable_sequence(2)->mutable_joint_move();
  for (int j = 0; j < 6; ++j) move->add_start(0.0);
  status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_THAT(describe(bad_request_violations(status)), HasSubstr("sequence[2].jointMove.start["));
}

TEST_F(SequenceTest, APathThatStartsElsewhereIsAFailedPrecondition) {
  auto request = example<v1::PlanRequest>("sequence_ur5.json");
  // A straight path from 5 cm beside where step 0 ends.
  straight_up(request, 1, -0.25, -0.25);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  const auto violations = precondition_violations(status);
  ASSERT_EQ(violations.size(), 1u);
  EXPECT_EQ(violations[0].subject(), "sequence[1].path");
  EXPECT_THAT(violations[0].description(), HasSubstr("starts 0.05 m and 0 rad from where sequence[0] ends"));
}

TEST_F(SequenceTest, AStraightPathContinuesWhereTheLineEnded) {
  auto request = example<v1::PlanRequest>("sequence_ur5.json");
  request.mutable_sequence()->DeleteSubrange(2, 2);
  // Step 1 as a path up from where step 0 ends: the tool keeps its orientation (a straight
  // start takes the one the previous step ended with).
  straight_up(request, 1, -0.3, -0.25);
  const auto response = plan_ok(request);
  ASSERT_EQ(response.steps_size(), 2);
  EXPECT_EQ(response.steps(1).kind(), "path");
  EXPECT_NEAR(response.steps(1).arc_length(), 0.15, 1e-9);
  EXPECT_LT(response.steps(1).closed_loop().max_error(), 1e-9);
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_NEAR(samples.back().position().z(), 0.45, 1e-9);
  EXPECT_NEAR(std::abs(samples.back().orientation().y()), 1.0, 1e-9) << "the tool kept its orientation";
}

TEST_F(SequenceTest, BadSequencesAreNamed) {
  auto base = example<v1::PlanRequest>("sequence_ur5.json");
  {
    auto request = base;
    request.mutable_sequence(3)->mutable_motion()->set_cycle_rate_hz(250);
    request.mutable_sequence(3)->mutable_motion()->set_duration_s(1.0);
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
    EXPECT_THAT(violation_of(bad_request_violations(status), "sequence[3].motion.cycleRateHz"),
                HasSubstr("one rate, 500 Hz"));
  }
  {
    auto request = base;
    *request.mutable_path() = demo_request('a').path();
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(violation_of(bad_request_violations(status), "sequence"), HasSubstr("not both"));
  }
  {
    auto request = base;
    request.add_sequence();
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(violation_of(bad_request_violations(status), "sequence[4]"), HasSubstr("is empty"));
  }
  {
    auto request = base;
    request.mutable_sequence(3)->mutable_linear_move()->mutable_goal()->mutable_position()->set_x(
        std::numeric_limits<double>::quiet_NaN());
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    const auto violations = bad_request_violations(status);
    EXPECT_THAT(violation_of(violations, "sequence[3].linearMove.goal.position"), HasSubstr("finite"))
        << describe(violations);
  }
  {
    auto request = base;
    request.clear_motion();
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    const auto violations = bad_request_violations(status);
    EXPECT_THAT(violation_of(violations, "sequence[0].motion"), HasSubstr("is required")) << describe(violations);
    EXPECT_EQ(violation_of(violations, "sequence[1].motion"), "") << "step 1 gives its own";
  }
  {
    v1::PathProfile profile;
    const auto status = analyze(base, profile);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(violation_of(bad_request_violations(status), "sequence"), HasSubstr("AnalyzePath"));
  }
}

}  // namespace
}  // namespace geotraj::testing
