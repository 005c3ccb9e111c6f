// robot.toolAxisFree through the real service: a seam whose plan turns the torch 2.6 rad
// about its own axis in 1.5 s (ORIENTATION_MODE_CUSTOM, eased) while it moves 0.2 m, on the
// UR5e (6 joints) and the Panda (7). As planned the wrist cannot follow (refused); with the
// roll free the plan is accepted, and the streamed joints, by an independent forward
// kinematics, hold the planned position and tool axis at every sample while their
// differences at 1 kHz stay within every limit. A line to goal joints with the roll free
// ends at them; in a sequence every path and line has its own; bad requests name the field.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gmock/gmock.h>

#include "tests/server/support/dh_reference.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

class ToolRollTest : public ServerTest {};

constexpr double kPlannedRoll = 2.6;  // [rad] about the tool's z axis
constexpr double kSeamLength = 0.2;   // [m] along W's y

void set(v1::Vec3* out, const Eigen::Vector3d& v) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

// A seam from the tool's pose at `start` (the robot's home when empty), `length` [m] along
// `direction`, the torch turning `roll` [rad] about its axis, in `duration` [s].
v1::PlanRequest seam(const v1::RobotModel& model, bool free, std::vector<double> start = {},
                     const Eigen::Vector3d& direction = Eigen::Vector3d::UnitY(), double length = kSeamLength,
                     double roll = kPlannedRoll, double duration = 1.5) {
  const std::string& robot = model.name();
  if (start.empty()) start.assign(model.home().begin(), model.home().end());
  const Eigen::Isometry3d X0 = forward_kinematics(model, start);
  const Eigen::Quaterniond q1(X0.linear() * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  v1::PlanRequest request;
  auto* f0 = request.mutable_path()->add_frames();
  set(f0->mutable_position(), X0.translation());
  set(f0->mutable_tangent(), direction);
  f0->set_orientation_mode(v1::ORIENTATION_MODE_CUSTOM);
  f0->mutable_orientation()->set_w(q1.w());
  f0->mutable_orientation()->set_x(q1.x());
  f0->mutable_orientation()->set_y(q1.y());
  f0->mutable_orientation()->set_z(q1.z());
  f0->set_ease_orientation(true);
  auto* f1 = request.mutable_path()->add_frames();
  set(f1->mutable_position(), X0.translation() + length * direction);
  set(f1->mutable_tangent(), direction);
  request.mutable_robot()->set_name(robot);
  request.mutable_robot()->set_tool_axis_free(free);
  for (const double q : start) request.mutable_robot()->add_initial_joints(q);
  request.mutable_motion()->set_duration_s(duration);
  request.mutable_motion()->set_profile(v1::MOTION_PROFILE_S_CURVE);
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  return request;
}

// The largest usage of the streamed joints' limits by differences: velocity, acceleration.
std::pair<double, double> streamed_usage(const std::vector<v1::Sample>& samples, const v1::RobotModel& model) {
  double velocity = 0.0, acceleration = 0.0;
  for (std::size_t k = 0; k + 1 < samples.size(); ++k) {
    const double h1 = samples[k + 1].t() - samples[k].t();
    for (int j = 0; j < samples[k].joints_size(); ++j) {
      const double v1 = (samples[k + 1].joints(j) - samples[k].joints(j)) / h1;
      velocity = std::max(velocity, std::abs(v1) / model.limits(j).max_velocity());
      if (k == 0) continue;
      const double h0 = samples[k].t() - samples[k - 1].t();
      const double v0 = (samples[k].joints(j) - samples[k - 1].joints(j)) / h0;
      acceleration = std::max(acceleration, std::abs(2.0 * (v1 - v0) / (h0 + h1)) / model.limits(j).max_acceleration());
    }
  }
  return {velocity, acceleration};
}

// How far the tool of the streamed joints (an independent forward kinematics) is from the
// samples' positions [m] and from the planned axis (the sine of the angle: acos loses 1e-8
// near 0; 1 for an axis turned beyond 90 degrees).
struct ToolOffPlan {
  double position = 0.0;
  double tilt = 0.0;
};
ToolOffPlan tool_off_plan(const std::vector<v1::Sample>& samples, const v1::RobotModel& model,
                          const Eigen::Vector3d& axis) {
  ToolOffPlan off;
  for (const auto& sample : samples) {
    const Eigen::Isometry3d X = forward_kinematics(model, sample.joints());
    off.position = std::max(off.position, (X.translation() - vec(sample.position())).norm());
    const Eigen::Vector3d z = X.linear().col(2);
    off.tilt = std::max(off.tilt, z.dot(axis) > 0.0 ? z.cross(axis).norm() : 1.0);
  }
  return off;
}

TEST_F(ToolRollTest, ASeamsTorchRollIsChosenAndItsAxisKept) {
  for (const char* name : {"ur5e", "panda"}) {
    SCOPED_TRACE(name);
    const auto model = robot_model(name);
    const Eigen::Isometry3d X0 = forward_kinematics(model, model.home());
    const Eigen::Vector3d axis = X0.linear().col(2);

    v1::PlanResponse fixed, free;
    EXPECT_EQ(plan(seam(model, false), fixed).error_code(), grpc::StatusCode::FAILED_PRECONDITION)
        << "the planned roll is beyond the wrist";
    auto reported = seam(model, false);
    reported.mutable_robot()->set_report_only(true);
    fixed = plan_ok(reported);
    double fixed_velocity = 0.0, fixed_acceleration = 0.0;
    for (const auto& j : fixed.robot().joints()) {
      fixed_velocity = std::max(fixed_velocity, j.velocity_usage());
      fixed_acceleration = std::max(fixed_acceleration, j.acceleration_usage());
    }
    std::printf("[ measured ] %s seam, roll as planned: peak joint usage velocity %.3f, acceleration %.3f (robot "
                "report)\n", name, fixed_velocity, fixed_acceleration);
    EXPECT_GT(std::max(fixed_velocity, fixed_acceleration), 1.0);
    const auto status = plan(seam(model, true), free);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_TRUE(free.robot().feasible());
    const auto& report = free.optimization().redundancy();
    EXPECT_EQ(report.status(), v1::OPTIMIZER_STATUS_CONVERGED) << report.message();
    EXPECT_LT(report.objective_after(), 0.1 * report.objective_before());

    grpc::Status stream_status;
    const auto samples = stream_all(seam(model, true), stream_status);
    ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
    ASSERT_EQ(samples.size(), 1501u);
    const auto [position, tilt] = tool_off_plan(samples, model, axis);
    double orientation = 0.0, off_seam = 0.0, turned = 0.0;
    for (const auto& sample : samples) {
      const Eigen::Isometry3d X = forward_kinematics(model, sample.joints());
      orientation = std::max(orientation, quat(sample.orientation()).angularDistance(Eigen::Quaterniond(X.linear())));
      const Eigen::Vector3d d = X.translation() - X0.translation();
      off_seam = std::max(off_seam, (d - d.y() * Eigen::Vector3d::UnitY()).norm());
      // The tool's turn about its axis from the start's: the angle of X0^T X about z.
      const Eigen::Matrix3d R = X0.linear().transpose() * X.linear();
      turned = std::max(turned, std::abs(std::atan2(R(1, 0), R(0, 0))));
    }
    const auto [velocity, acceleration] = streamed_usage(samples, model);
    std::printf("[ measured ] %s seam, roll free: objective %.4g -> %.4g (%d iterations, %.3f s); tool from FK of the "
                "streamed joints: %.1e m off the samples, %.1e m off the seam, axis within %.1e rad; turned at most "
                "%.3f rad about it (planned %.1f); joints by differences at 1 kHz: velocity %.3f, acceleration %.3f\n",
                name, report.objective_before(), report.objective_after(), report.iterations(), report.seconds(),
                position, off_seam, tilt, turned, kPlannedRoll, velocity, acceleration);
    EXPECT_LT(position, 1e-9);
    EXPECT_LT(off_seam, 1e-9);
    EXPECT_LT(tilt, 1e-9) << "the tool's axis as planned";
    EXPECT_LT(orientation, 1e-8) << "Sample.orientation is the pose the joints reach";
    EXPECT_LT(turned, 0.5 * kPlannedRoll) << "the roll is spent where the joints need it, not as planned";
    EXPECT_LE(velocity, 1.0);
    EXPECT_LE(acceleration, 1.02);
    // The first sample is the robot where it stands.
    for (int j = 0; j < samples.front().joints_size(); ++j) EXPECT_NEAR(samples.front().joints(j), model.home(j), 1e-12);
  }
}

double peak_usage(const v1::PlanResponse& response) {
  double worst = 0.0;
  for (const auto& j : response.robot().joints()) worst = std::max({worst, j.velocity_usage(), j.acceleration_usage()});
  return worst;
}

// Random seams (start joints, direction, length, planned roll, duration) on the UR5e and the
// Panda, with reportOnly: with the roll free the tool stays on the planned positions and axis
// (by an independent forward kinematics of the streamed joints), and the peak usage of the
// joints' limits never ends above both the limits and the planned roll's.
TEST_F(ToolRollTest, RandomSeamsKeepTheirAxisAndNeverUseMoreOfTheLimits) {
  std::mt19937 random(33);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int improved = 0, cases = 0;
  for (const char* name : {"ur5e", "panda"}) {
    const auto model = robot_model(name);
    for (int trial = 0; trial < 6; ++trial) {
      SCOPED_TRACE(std::string(name) + " trial " + std::to_string(trial));
      std::vector<double> start(model.home().begin(), model.home().end());
      for (std::size_t j = 0; j < start.size(); ++j) start[j] += 0.3 * unit(random);
      const double heading = std::numbers::pi * unit(random);
      const Eigen::Vector3d direction(std::cos(heading), std::sin(heading), 0.2 * unit(random));
      const double length = 0.1 + 0.05 * unit(random);
      const double roll = 1.5 * unit(random);
      const double duration = 1.5 + 0.5 * unit(random);
      auto planned = seam(model, false, start, direction.normalized(), length, roll, duration);
      planned.mutable_robot()->set_report_only(true);
      auto free = planned;
      free.mutable_robot()->set_tool_axis_free(true);
      v1::PlanResponse as_planned, chosen;
      const auto status = plan(planned, as_planned);
      if (!status.ok()) continue;  // a random seam the arm cannot follow at all (IK): nothing to compare
      ASSERT_TRUE(plan(free, chosen).ok());
      ++cases;
      const double before = peak_usage(as_planned), after = peak_usage(chosen);
      std::printf("[ measured ] %s seam %d: peak joint usage %.3f as planned, %.3f with the roll free (%s)\n", name,
                  trial, before, after, chosen.optimization().redundancy().message().c_str());
      EXPECT_LE(after, std::max(1.0, before) + 1e-6);
      improved += after < before ? 1 : 0;
      grpc::Status stream_status;
      const auto samples = stream_all(free, stream_status);
      if (!chosen.robot().feasible()) continue;
      ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
      const Eigen::Vector3d axis = forward_kinematics(model, start).linear().col(2);
      const ToolOffPlan off = tool_off_plan(samples, model, axis);
      EXPECT_LT(off.position, 1e-9);
      EXPECT_LT(off.tilt, 1e-9);
    }
  }
  EXPECT_GE(cases, 8) << "most random seams are within reach";
  EXPECT_GE(improved, cases - 2) << "the roll is a free choice worth having";
}

// As fast as the limits allow (jerk-limited: the models' jerk limits, or their default), the
// seam is timed on the planned roll (the UR5e's wrist 3 binds; the Panda's as planned breaks
// its position limit: reportOnly), then again along the roll chosen, the same way: faster on
// both arms, within every limit as streamed.
TEST_F(ToolRollTest, TimedByTheLimitsTheSeamIsFasterWithTheRollFree) {
  for (const char* name : {"ur5e", "panda"}) {
    SCOPED_TRACE(name);
    const auto model = robot_model(name);
    auto planned = seam(model, false, {}, Eigen::Vector3d::UnitY(), kSeamLength, kPlannedRoll, 0.0);
    auto free = seam(model, true, {}, Eigen::Vector3d::UnitY(), kSeamLength, kPlannedRoll, 0.0);
    planned.mutable_robot()->set_report_only(true);  // the Panda's as planned breaks its position limit
    const v1::PlanResponse as_planned = plan_ok(planned), chosen = plan_ok(free);
    const double before = as_planned.motion().duration_s(), after = chosen.motion().duration_s();
    std::printf("[ measured ] %s seam as fast as the limits allow: %.4f s with the roll as planned, %.4f s with it "
                "free (%s)\n", name, before, after, chosen.optimization().redundancy().message().c_str());
    EXPECT_LT(after, 0.7 * before);
    EXPECT_THAT(chosen.optimization().redundancy().message(), HasSubstr("timed again along the roll chosen"));
    EXPECT_TRUE(chosen.robot().feasible());
    grpc::Status stream_status;
    const auto samples = stream_all(free, stream_status);
    ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
    EXPECT_NEAR(samples.back().t(), after, 1e-9);
    const auto [velocity, acceleration] = streamed_usage(samples, model);
    std::printf("[ measured ]   by differences at 1 kHz: velocity %.4f, acceleration %.4f of the limits\n", velocity,
                acceleration);
    EXPECT_LE(velocity, 1.0 + 1e-6);
    EXPECT_LE(acceleration, 1.02);
    // Timed again as the first timing was: jerk-limited, within the jerk the plan reports
    // (the model's, or the default for joints without one), by third differences.
    const auto& reported = chosen.robot().default_jerk();
    double jerk = 0.0;
    for (std::size_t k = 0; k + 3 < samples.size(); ++k) {
      const double h = samples[k + 1].t() - samples[k].t();
      if (std::abs(samples[k + 3].t() - samples[k + 2].t() - h) > 1e-9) continue;  // the last, shorter step
      for (int j = 0; j < samples[k].joints_size(); ++j) {
        double limit = model.limits(j).has_max_jerk() ? model.limits(j).max_jerk() : 0.0;
        for (int i = 0; i < reported.joints_size(); ++i)
          if (static_cast<int>(reported.joints(i)) == j) limit = reported.max_jerk(i);
        ASSERT_GT(limit, 0.0) << "joint " << j << " has a jerk limit or a reported default";
        const double d3 = samples[k + 3].joints(j) - 3 * samples[k + 2].joints(j) + 3 * samples[k + 1].joints(j) -
                          samples[k].joints(j);
        jerk = std::max(jerk, std::abs(d3) / (h * h * h) / limit);
      }
    }
    std::printf("[ measured ]   jerk by third differences: %.4f of the limits\n", jerk);
    EXPECT_LE(jerk, 1.05);
    const ToolOffPlan off = tool_off_plan(samples, model, forward_kinematics(model, model.home()).linear().col(2));
    EXPECT_LT(off.position, 1e-9);
    EXPECT_LT(off.tilt, 1e-9);
  }
}

// A straight line to goal joints with the roll free ends at them (the roll back to 0 there).
TEST_F(ToolRollTest, ALineToGoalJointsEndsAtThem) {
  const auto model = robot_model("ur5e");
  std::vector<double> goal(model.home().begin(), model.home().end());
  const double offsets[6] = {0.3, -0.2, 0.25, 0.2, -0.25, 0.4};
  for (std::size_t j = 0; j < 6; ++j) goal[j] += offsets[j];
  v1::PlanRequest request;
  for (const double q : goal) request.mutable_linear_move()->add_goal_joints(q);
  request.mutable_robot()->set_name("ur5e");
  request.mutable_robot()->set_tool_axis_free(true);
  request.mutable_motion()->set_duration_s(3.0);
  request.mutable_motion()->set_cycle_rate_hz(1000.0);
  request.mutable_motion()->set_profile(v1::MOTION_PROFILE_S_CURVE);
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  double worst = 0.0;
  for (std::size_t j = 0; j < 6; ++j) worst = std::max(worst, std::abs(samples.back().joints(static_cast<int>(j)) - goal[j]));
  EXPECT_LT(worst, 1e-9);
  const auto [velocity, acceleration] = streamed_usage(samples, model);
  EXPECT_LE(velocity, 1.0);
  EXPECT_LE(acceleration, 1.02);
  v1::PlanResponse response;
  ASSERT_TRUE(plan(request, response).ok());
  EXPECT_NE(response.optimization().redundancy().status(), v1::OPTIMIZER_STATUS_FAILED)
      << response.optimization().redundancy().message();
}

// The seam as the first step of a sequence and a straight line back to its start as the
// second: each step's roll chosen for it, the line starting where the seam's roll left the
// tool; the tool's axis kept and the joints within their limits across the junction.
TEST_F(ToolRollTest, EveryStepOfASequenceHasItsRollChosen) {
  const auto model = robot_model("ur5e");
  const Eigen::Isometry3d X0 = forward_kinematics(model, model.home());
  const Eigen::Vector3d axis = X0.linear().col(2);
  auto request = seam(model, true);
  *request.add_sequence()->mutable_path() = request.path();
  request.clear_path();
  auto* back = request.add_sequence()->mutable_linear_move()->mutable_goal();
  set(back->mutable_position(), X0.translation());
  const Eigen::Quaterniond q0(X0.linear());
  back->mutable_orientation()->set_w(q0.w());
  back->mutable_orientation()->set_x(q0.x());
  back->mutable_orientation()->set_y(q0.y());
  back->mutable_orientation()->set_z(q0.z());
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(response.steps_size(), 2);
  for (const auto& step : response.steps())
    EXPECT_EQ(step.optimization().redundancy().status(), v1::OPTIMIZER_STATUS_CONVERGED)
        << step.optimization().redundancy().message();
  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), 3001u);
  const ToolOffPlan off = tool_off_plan(samples, model, axis);
  EXPECT_LT(off.position, 1e-9);
  EXPECT_LT(off.tilt, 1e-9);
  EXPECT_LT((vec(samples.back().position()) - X0.translation()).norm(), 1e-9) << "back at the start";
  const auto [velocity, acceleration] = streamed_usage(samples, model);
  std::printf("[ measured ] ur5e seam and line back, roll free: joints by differences at 1 kHz: velocity %.3f, "
              "acceleration %.3f\n", velocity, acceleration);
  EXPECT_LE(velocity, 1.0);
  EXPECT_LE(acceleration, 1.02);
}

TEST_F(ToolRollTest, BadRequestsNameTheField) {
  auto described = [&](const v1::PlanRequest& request) {
    v1::PlanResponse response;
    const auto status = plan(request, response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    return describe(bad_request_violations(status));
  };
  v1::PlanRequest joint_move;
  joint_move.mutable_robot()->set_name("ur5e");
  joint_move.mutable_robot()->set_tool_axis_free(true);
  for (int j = 0; j < 6; ++j) joint_move.mutable_joint_move()->add_goal(0.1 * j);
  joint_move.mutable_motion()->set_duration_s(1.0);
  EXPECT_THAT(described(joint_move), HasSubstr("robot.toolAxisFree: frees the tool's roll along a Cartesian path or "
                                               "line; a jointMove gives the joints"));
  auto sequence = joint_move;
  *sequence.add_sequence()->mutable_joint_move() = joint_move.joint_move();
  sequence.clear_joint_move();
  EXPECT_THAT(described(sequence), HasSubstr("robot.toolAxisFree: frees the tool's roll along the paths and lines of a "
                                             "sequence, and this one has none"));

  v1::ForwardKinematicsRequest fk;
  fk.mutable_robot()->set_name("ur5e");
  fk.mutable_robot()->set_tool_axis_free(true);
  for (int j = 0; j < 6; ++j) fk.add_joints(0.0);
  v1::ForwardKinematicsResponse fk_response;
  const auto status = stub_->ComputeForwardKinematics(context().get(), fk, &fk_response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(describe(bad_request_violations(status)), HasSubstr("robot.toolAxisFree: frees the tool's roll along a "
                                                                  "planned motion"));
}

}  // namespace
}  // namespace geotraj::testing
