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

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gmock/gmock.h>

#include "planner/robots.hpp"
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

// A sequence's robot given as a URDF document is read once for all its steps: the same
// pick-and-place on the UR5e's URDF plans and streams; a document that does not parse is
// one violation of robot.urdf, not one a step.
TEST_F(SequenceTest, ARobotGivenAsUrdfServesEveryStep) {
  auto request = example<v1::PlanRequest>("sequence_ur5.json");
  const std::string urdf(planner::builtin_urdf("ur5e"));
  ASSERT_FALSE(urdf.empty());
  request.mutable_robot()->clear_name();
  request.mutable_robot()->set_urdf(urdf);
  const auto response = plan_ok(request);
  EXPECT_EQ(response.steps_size(), 4);
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(samples.size(), response.motion().sample_count());

  request.mutable_robot()->set_urdf(urdf.substr(0, urdf.size() / 2));
  v1::PlanResponse refused;
  status = plan(request, refused);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  const auto violations = bad_request_violations(status);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "robot.urdf");
}

// A step's own motion takes every field it does not give from the request's motion: a step
// that gives only its duration streams at the request's cycleRateHz (250 Hz here), and a
// violation is named on the field the user wrote (the request's motion or the step's).
TEST_F(SequenceTest, AStepsMotionTakesTheFieldsItDoesNotGiveFromTheRequests) {
  auto request = example<v1::PlanRequest>("sequence_ur5.json");
  request.mutable_motion()->set_cycle_rate_hz(250);
  request.mutable_sequence(1)->mutable_motion()->clear_cycle_rate_hz();  // durationS 1.5 only
  const auto response = plan_ok(request);
  ASSERT_EQ(response.steps_size(), 4);
  EXPECT_NEAR(response.steps(1).duration_s(), 1.5, 1e-12);
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
    ASSERT_NEAR(samples[k].t() - samples[k - 1].t(), 1.0 / 250.0, 1e-9) << "sample " << k;
  }

  // A bad maxSpeed in the request's motion, taken by step 1: named motion.maxSpeed.
  request.mutable_motion()->set_max_speed(-1.0);
  v1::PlanResponse refused;
  status = plan(request, refused);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  auto violations = bad_request_violations(status);
  EXPECT_FALSE(violation_of(violations, "motion.maxSpeed").empty()) << describe(violations);
  EXPECT_TRUE(violation_of(violations, "sequence[1].motion.maxSpeed").empty()) << describe(violations);
  // The same given by step 1 itself: named there.
  request.mutable_motion()->set_max_speed(0.25);
  request.mutable_sequence(1)->mutable_motion()->set_max_speed(-1.0);
  status = plan(request, refused);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  violations = bad_request_violations(status);
  EXPECT_FALSE(violation_of(violations, "sequence[1].motion.maxSpeed").empty()) << describe(violations);

  // Two rates: named on the step's own field, the other rate's field quoted.
  request.mutable_sequence(1)->mutable_motion()->set_max_speed(0.25);
  request.mutable_sequence(1)->mutable_motion()->set_cycle_rate_hz(500);
  status = plan(request, refused);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  violations = bad_request_violations(status);
  EXPECT_THAT(violation_of(violations, "sequence[1].motion.cycleRateHz"),
              HasSubstr("one rate, 250 Hz (motion.cycleRateHz)"));
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

// Distance [m] from p to the segment a-b.
double distance_to_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

Eigen::Vector3d vec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

// sequence_blended_ur5.json timed by an S-curve of `duration` s (acceleration continuous in
// time, so any jump of the tool's acceleration comes from the geometry), sampled at 1 kHz.
v1::PlanRequest blended_s_curve(double duration) {
  auto request = example<v1::PlanRequest>("sequence_blended_ur5.json");
  auto& motion = *request.mutable_motion();
  motion.set_profile(v1::MOTION_PROFILE_S_CURVE);
  motion.set_duration_s(duration);
  motion.set_ramp_fraction(0.3);
  motion.set_cycle_rate_hz(1000);
  return request;
}

// sequence_blended_ur5.json: three lines (down, across, up) joined by 2 cm blends. Checked on
// the streamed samples, independently of the blend's construction: every sample within the
// tolerance of the unblended route, exactly on the lines away from the corners, no rest at
// the corners, the tool's acceleration continuous through them (an S-curve timing, whose
// own acceleration is continuous, so a jump could only come from the geometry: a G1 arc's
// curvature steps from 0 to 1/r and the centripetal acceleration with it), the curvature 0
// on both sides of every cut frame, and every joint within its limits by finite differences.
// A junction where the lines go on in the same direction is no corner: a blended chain down
// z in two lines (then across) lists only the real corner, and streams through the
// tangent-continuous junction without resting.
TEST_F(SequenceTest, ATangentContinuousJunctionIsNotACorner) {
  auto request = example<v1::PlanRequest>("sequence_blended_ur5.json");
  ASSERT_EQ(request.sequence_size(), 4);
  // Step 1 goes down to z 0.3 (blended into step 2); step 2 now goes on down to z 0.25,
  // step 3 across from there.
  auto* down = request.mutable_sequence(2)->mutable_linear_move()->mutable_goal()->mutable_position();
  down->set_x(-0.3);
  down->set_y(-0.25);
  down->set_z(0.25);
  request.mutable_sequence(2)->set_blend_tolerance(0.02);
  auto* across = request.mutable_sequence(3)->mutable_linear_move()->mutable_goal()->mutable_position();
  across->set_x(-0.1);
  across->set_y(-0.45);
  across->set_z(0.25);
  request.mutable_sequence(3)->clear_blend_tolerance();
  const auto response = plan_ok(request);
  ASSERT_EQ(response.steps_size(), 2);
  const auto& chain = response.steps(1);
  EXPECT_EQ(chain.kind(), "blended");
  ASSERT_EQ(chain.corners_size(), 1) << "only the turn from down to across";
  EXPECT_EQ(chain.corners(0).after_step(), 2u);
  EXPECT_NEAR(chain.corners(0).corner(), M_PI / 2, 1e-9);
}

// optimize.timing times a sequence of lines, a blended chain of them included: accepted, and
// the chain's timing reported; the shape optimisers still need a path.
TEST_F(SequenceTest, OptimizeTimingTimesABlendedChainOfLines) {
  auto request = example<v1::PlanRequest>("sequence_blended_ur5.json");
  request.mutable_optimize()->mutable_timing()->set_time_optimal(true);
  const auto response = plan_ok(request);
  ASSERT_EQ(response.steps_size(), 2);
  EXPECT_EQ(response.steps(1).kind(), "blended");
  EXPECT_TRUE(response.steps(1).optimization().has_timing()) << response.steps(1).DebugString();

  // Jerk-limited, with joint jerk limits given for the UR5 (its model has none).
  auto jerk = request;
  jerk.mutable_optimize()->mutable_timing()->set_jerk_limited(true);
  const auto all = [&] {
    v1::ListRobotsResponse r;
    EXPECT_TRUE(stub_->ListRobots(context().get(), v1::ListRobotsRequest{}, &r).ok());
    return r;
  }();
  const v1::RobotModel* ur5 = model(all, "ur5");
  ASSERT_NE(ur5, nullptr);
  for (const auto& link : ur5->links()) {
    auto* l = jerk.mutable_robot()->add_joint_limits();
    l->set_joint(link.name());
    l->set_max_jerk(50.0);
  }
  const auto jerk_response = plan_ok(jerk);
  ASSERT_EQ(jerk_response.steps_size(), 2);
  EXPECT_GE(jerk_response.motion().duration_s(), response.motion().duration_s() - 1e-9)
      << "jerk limits cannot make it faster";

  request.mutable_optimize()->mutable_tangent_scales()->set_objective(v1::TANGENT_SCALE_OBJECTIVE_BENDING_ENERGY);
  v1::PlanResponse refused;
  const auto status = plan(request, refused);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_THAT(violation_of(bad_request_violations(status), "optimize.tangentScales"), HasSubstr("has none"));
}

TEST_F(SequenceTest, BlendedCornersStayWithinTheToleranceAndKeepTheAccelerationContinuous) {
  auto request = blended_s_curve(4.0);
  const auto response = plan_ok(request);
  ASSERT_EQ(response.steps_size(), 2);
  const auto& chain = response.steps(1);
  EXPECT_EQ(chain.kind(), "blended");
  EXPECT_EQ(chain.index(), 1u);
  EXPECT_EQ(chain.last_index(), 3u);
  ASSERT_EQ(chain.corners_size(), 2);
  const double tolerance = 0.02;
  for (const auto& c : chain.corners()) {
    EXPECT_LE(c.deviation(), tolerance);
    EXPECT_GT(c.deviation(), 0.5 * tolerance) << "the blend uses the room it is given";
    EXPECT_NEAR(c.corner(), M_PI / 2, 1e-12);
  }
  // The curvature is 0 on both sides of each frame where a blend meets a line.
  for (const auto& c : chain.corners()) {
    for (const unsigned frame : {c.segment(), c.segment() + 1}) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      ASSERT_LT(static_cast<int>(frame), chain.frames_size());
      const auto& f = chain.frames(static_cast<int>(frame));
      ASSERT_TRUE(f.has_approach() && f.has_leave());
      EXPECT_LT(f.approach().curvature(), 1e-9);
      EXPECT_LT(f.leave().curvature(), 1e-9);
    }
  }

  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const Eigen::Vector3d corners[] = {{-0.3, -0.25, 0.45}, {-0.3, -0.25, 0.3}, {-0.1, -0.45, 0.3}, {-0.1, -0.45, 0.45}};
  const auto first = chain.first_sample();
  const auto count = chain.sample_count();
  ASSERT_EQ(first + count, samples.size());
  double worst_route = 0.0, worst_line = 0.0, slowest = 1e9, worst_jump = 0.0, peak_a = 0.0;
  for (std::size_t k = first; k < first + count; ++k) {
    const auto& s = samples[k];
    const Eigen::Vector3d p = vec(s.position());
    double route = 1e9;
    for (int i = 0; i < 3; ++i) route = std::min(route, distance_to_segment(p, corners[i], corners[i + 1]));
    worst_route = std::max(worst_route, route);
    // Beyond the cuts from both corners, on the middle line exactly.
    const double along = (p - corners[1]).dot((corners[2] - corners[1]).normalized());
    const double cut = chain.corners(0).cut_after();
    if (along > cut + 1e-6 && along < (corners[2] - corners[1]).norm() - chain.corners(1).cut_before() - 1e-6) {
      worst_line = std::max(worst_line, distance_to_segment(p, corners[1], corners[2]));
    }
    if (s.segment() == chain.corners(0).segment() || s.segment() == chain.corners(1).segment()) {
      slowest = std::min(slowest, s.speed());  // on a blend
    }
    peak_a = std::max(peak_a, vec(s.acceleration()).norm());
    if (k > first) worst_jump = std::max(worst_jump, (vec(s.acceleration()) - vec(samples[k - 1].acceleration())).norm());
    // Each sample names the requested step it is in.
    EXPECT_GE(s.step(), 1u);
    EXPECT_LE(s.step(), 3u);
  }
  std::printf("[ measured ] blended chain: %zu samples, worst distance from the route %.6g m (tolerance %.3g), "
              "off the middle line %.3g m, slowest on a blend %.4g m/s, largest acceleration change per 1 ms %.4g of peak %.4g "
              "m/s^2\n",
              static_cast<std::size_t>(count), worst_route, tolerance, worst_line, slowest, worst_jump, peak_a);
  EXPECT_LE(worst_route, tolerance + 1e-9);
  EXPECT_LT(worst_line, 1e-9);
  EXPECT_GT(slowest, 0.05) << "no rest at the corners";
  EXPECT_LT(worst_jump, 0.05 * peak_a) << "the acceleration is continuous through the blends";
  EXPECT_EQ(samples[first + count / 2].step(), 2u);

  // Every joint within its limits by finite differences, across the whole sequence.
  v1::ListRobotsResponse all = robots();
  const v1::RobotModel* ur5 = model(all, "ur5");
  ASSERT_NE(ur5, nullptr);
  const double dt = 1e-3;
  for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
    for (int j = 0; j < ur5->limits_size(); ++j) {
      const double v = (samples[k].joints(j) - samples[k - 1].joints(j)) / (samples[k].t() - samples[k - 1].t());
      ASSERT_LE(std::abs(v), ur5->limits(j).max_velocity()) << "sample " << k << " joint " << j;
      const double a = (samples[k + 1].joints(j) - 2 * samples[k].joints(j) + samples[k - 1].joints(j)) / (dt * dt);
      if (samples[k + 1].t() - samples[k].t() > 0.999 * dt) {
        ASSERT_LE(std::abs(a), ur5->limits(j).max_acceleration() * 1.02) << "sample " << k << " joint " << j;
      }
    }
  }

  // Faster than resting at the corners.
  auto rested = request;
  for (auto& step : *rested.mutable_sequence()) step.clear_blend_tolerance();
  rested.mutable_motion()->set_duration_s(0);
  rested.mutable_motion()->set_profile(v1::MOTION_PROFILE_TRAPEZOIDAL);
  auto fastest = request;
  *fastest.mutable_motion() = example<v1::PlanRequest>("sequence_blended_ur5.json").motion();
  fastest.mutable_motion()->set_cycle_rate_hz(1000);
  rested.mutable_motion()->set_max_speed(0.25);
  rested.mutable_motion()->set_max_acceleration(1.0);
  const double t_rested = plan_ok(rested).motion().duration_s();
  const double t_blended = plan_ok(fastest).motion().duration_s();
  std::printf("[ measured ] fastest: %.4g s resting at the corners, %.4g s blended\n", t_rested, t_blended);
  EXPECT_LT(t_blended, t_rested - 0.3);
}

// A line into a path into a line, both corners blended: the path keeps its key frames (the
// blend meets its end frames with the path's own geometry), the chain moves without a rest
// and with a continuous acceleration, and ends where the last line does.
TEST_F(SequenceTest, LinesBlendIntoAndOutOfAPath) {
  auto request = blended_s_curve(6.0);
  // Step 1: down 7 cm; step 2: a path bending from down to +x over 10 cm; step 3: a line
  // along (1, -1, 0) (a 45 degree corner after the path).
  request.mutable_sequence(1)->mutable_linear_move()->mutable_goal()->mutable_position()->set_z(0.38);
  request.mutable_sequence(1)->set_blend_tolerance(0.005);
  auto* step = request.mutable_sequence(2);
  step->clear_linear_move();
  step->set_blend_tolerance(0.005);
  auto* path = step->mutable_path();
  auto* a = path->add_frames();
  a->mutable_position()->set_x(-0.3);
  a->mutable_position()->set_y(-0.25);
  a->mutable_position()->set_z(0.38);
  a->mutable_tangent()->set_z(-1.0);
  auto* c = path->add_frames();
  c->mutable_position()->set_x(-0.2);
  c->mutable_position()->set_y(-0.25);
  c->mutable_position()->set_z(0.3);
  c->mutable_tangent()->set_x(1.0);
  auto* goal = request.mutable_sequence(3)->mutable_linear_move()->mutable_goal()->mutable_position();
  goal->set_x(-0.1);
  goal->set_y(-0.35);
  goal->set_z(0.3);
  const auto response = plan_ok(request);
  ASSERT_EQ(response.steps_size(), 2);
  const auto& chain = response.steps(1);
  ASSERT_EQ(chain.corners_size(), 2);
  EXPECT_EQ(chain.kind(), "blended");
  for (const auto& corner : chain.corners()) {
    EXPECT_LE(corner.deviation(), 0.005);
    EXPECT_GT(corner.deviation(), 0.0);
  }
  EXPECT_GT(chain.corners(0).cut_before(), 0.0);
  EXPECT_EQ(chain.corners(0).cut_after(), 0.0) << "the path is not cut";
  EXPECT_EQ(chain.corners(1).cut_before(), 0.0);
  EXPECT_NEAR(chain.corners(1).corner(), M_PI / 4, 1e-9);
  EXPECT_LT(chain.closed_loop().max_error(), 1e-6) << chain.closed_loop().worst_field();

  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  double worst_jump = 0.0, peak_a = 0.0, slowest = 1e9;
  for (std::size_t k = chain.first_sample() + 1; k < samples.size(); ++k) {
    peak_a = std::max(peak_a, vec(samples[k].acceleration()).norm());
    worst_jump = std::max(worst_jump, (vec(samples[k].acceleration()) - vec(samples[k - 1].acceleration())).norm());
    if (samples[k].segment() == chain.corners(0).segment() || samples[k].segment() == chain.corners(1).segment()) {
      slowest = std::min(slowest, samples[k].speed());
    }
  }
  std::printf("[ measured ] line-path-line chain: slowest on a blend %.4g m/s, largest acceleration change per 1 ms "
              "%.4g of peak %.4g m/s^2\n",
              slowest, worst_jump, peak_a);
  EXPECT_GT(slowest, 0.02);
  EXPECT_LT(worst_jump, 0.05 * peak_a);
  EXPECT_NEAR(samples.back().position().x(), -0.1, 1e-9);
  EXPECT_NEAR(samples.back().position().y(), -0.35, 1e-9);
}

// A blended chain whose lines turn the tool: each line turns it on its straight part (an
// eased SLERP) and the blends hold it, so the angular velocity is continuous through the
// corners and the chain ends at the last goal's orientation.
TEST_F(SequenceTest, ABlendedChainTurnsTheToolWithAContinuousAngularVelocity) {
  auto request = blended_s_curve(8.0);
  // The goal of step 2 turned 30 degrees about z, and step 3 back.
  const Eigen::Quaterniond down(0, 0, 1, 0);
  const Eigen::Quaterniond turned = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ())) * down;
  auto* q = request.mutable_sequence(2)->mutable_linear_move()->mutable_goal()->mutable_orientation();
  q->set_w(turned.w());
  q->set_x(turned.x());
  q->set_y(turned.y());
  q->set_z(turned.z());
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const auto response = plan_ok(request);
  const auto& chain = response.steps(1);
  double worst_jump = 0.0, peak_w = 0.0;
  for (std::size_t k = chain.first_sample() + 1; k < samples.size(); ++k) {
    const Eigen::Vector3d w = vec(samples[k].angular_velocity()), w0 = vec(samples[k - 1].angular_velocity());
    peak_w = std::max(peak_w, w.norm());
    worst_jump = std::max(worst_jump, (w - w0).norm());
  }
  std::printf("[ measured ] turning chain: peak |omega| %.4g rad/s, largest change per 1 ms %.4g rad/s\n", peak_w,
              worst_jump);
  EXPECT_GT(peak_w, 0.1) << "the tool turns";
  EXPECT_LT(worst_jump, 0.02 * peak_w);
  // The corner after step 2: the blend holds the turned orientation.
  const auto& back = samples.back().orientation();
  EXPECT_NEAR(std::abs(Eigen::Quaterniond(back.w(), back.x(), back.y(), back.z()).dot(down)), 1.0, 1e-9);
  for (const auto& s : samples) {
    if (s.segment() != chain.corners(1).segment()) continue;
    const auto& o = s.orientation();
    EXPECT_NEAR(std::abs(Eigen::Quaterniond(o.w(), o.x(), o.y(), o.z()).dot(turned)), 1.0, 1e-9);
    EXPECT_LT(vec(s.angular_velocity()).norm(), 1e-9);
  }
}

TEST_F(SequenceTest, CornersThatCannotBeBlendedAreNamed) {
  const auto base = example<v1::PlanRequest>("sequence_blended_ur5.json");
  const auto refused = [&](const v1::PlanRequest& request, const std::string& field, const std::string& words) {
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
    const auto violations = bad_request_violations(status);
    EXPECT_THAT(violation_of(violations, field), HasSubstr(words)) << describe(violations);
  };
  {  // into a joint move
    auto request = base;
    auto* step = request.mutable_sequence(2);
    step->clear_linear_move();
    *step->mutable_joint_move()->mutable_goal_pose() = base.sequence(2).linear_move().goal();
    refused(request, "sequence[1].blendTolerance", "joint move");
  }
  {  // on the last step
    auto request = base;
    request.mutable_sequence(3)->set_blend_tolerance(0.01);
    refused(request, "sequence[3].blendTolerance", "last step");
  }
  {  // negative
    auto request = base;
    request.mutable_sequence(1)->set_blend_tolerance(-0.01);
    refused(request, "sequence[1].blendTolerance", "[0, 1000] m");
  }
  {  // a line that turns back on itself
    auto request = base;
    auto* goal = request.mutable_sequence(2)->mutable_linear_move()->mutable_goal()->mutable_position();
    goal->set_x(-0.3);
    goal->set_y(-0.25);
    goal->set_z(0.4);  // straight back up the line it came down
    refused(request, "sequence[1].blendTolerance", "180 degrees");
  }
  {  // a line of a chain with a pose that is not one, named as for a line on its own
    auto request = base;
    request.mutable_sequence(2)->mutable_linear_move()->mutable_goal()->mutable_position()->set_x(
        std::numeric_limits<double>::quiet_NaN());
    refused(request, "sequence[2].linearMove.goal.position", "finite");
  }
  {  // a later step of a chain with a motion of its own
    auto request = base;
    request.mutable_sequence(2)->mutable_motion()->set_duration_s(1.0);
    refused(request, "sequence[2].motion", "same timing");
  }
}

}  // namespace
}  // namespace geotraj::testing
