// optimize.redundancy through the real service: the PA-10 along the thesis's paths A and B
// in its 10 s (client/grpcurl/plan_demo_path_*.json with the PA-10, reportOnly): the
// self-motion chosen for the whole path lowers the joints' peak acceleration, as the plan's
// robot report says and as the streamed joints show by second differences at 100 Hz and
// 1 kHz (the samples follow the joints chosen); the report's objective falls; bad requests
// name their field.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gmock/gmock.h>

#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

class RedundancyTest : public ServerTest {};

v1::PlanRequest pa10_demo(char path, double rate_hz, bool optimized) {
  auto request = demo_example(path);
  request.mutable_robot()->set_name("pa10");
  request.mutable_robot()->set_report_only(true);
  request.mutable_motion()->set_duration_s(10.0);
  request.mutable_motion()->set_cycle_rate_hz(rate_hz);
  if (optimized) request.mutable_optimize()->mutable_redundancy()->set_acceleration_weight(1.0);
  return request;
}

double peak_acceleration_usage(const v1::PlanResponse& response) {
  double worst = 0.0;
  for (const auto& j : response.robot().joints()) worst = std::max(worst, j.acceleration_usage());
  return worst;
}

// The largest |second difference of the streamed joints| / (dt^2 max_acceleration).
double streamed_acceleration_usage(const std::vector<v1::Sample>& samples, const v1::RobotModel& model) {
  double worst = 0.0;
  for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
    const double dt = samples[k + 1].t() - samples[k].t();
    for (int j = 0; j < samples[k].joints_size(); ++j) {
      const double d2 = samples[k + 1].joints(j) - 2.0 * samples[k].joints(j) + samples[k - 1].joints(j);
      worst = std::max(worst, std::abs(d2) / (dt * dt) / model.limits(j).max_acceleration());
    }
  }
  return worst;
}

TEST_F(RedundancyTest, TheSelfMotionChosenForThePathLowersThePa10sAccelerations) {
  const auto model = robot_model("pa10");
  for (const char path : {'a', 'b'}) {
    SCOPED_TRACE(std::string("path ") + path);
    v1::PlanResponse plain, optimized;
    ASSERT_TRUE(plan(pa10_demo(path, 100.0, false), plain).ok());
    const auto status = plan(pa10_demo(path, 100.0, true), optimized);
    ASSERT_TRUE(status.ok()) << status.error_message();
    const auto& report = optimized.optimization().redundancy();
    EXPECT_EQ(report.status(), v1::OPTIMIZER_STATUS_CONVERGED) << report.message();
    EXPECT_LT(report.objective_after(), report.objective_before());
    const double before = peak_acceleration_usage(plain), after = peak_acceleration_usage(optimized);
    std::printf("[ measured ] PA-10, path %c at 10 s: peak joint acceleration usage %.4f -> %.4f (%d iterations, "
                "%.3f s)\n", path, before, after, report.iterations(), report.seconds());
    EXPECT_LT(after, 0.9 * before);
    EXPECT_NEAR(optimized.motion().duration_s(), plain.motion().duration_s(), 1e-12) << "the timing is the same";
    EXPECT_LE(optimized.robot().max_ik_position_error(), 1e-9);

    // The stream follows the joints chosen: by second differences, at 100 Hz and at 1 kHz.
    for (const double rate : {100.0, 1000.0}) {
      grpc::Status stream_status;
      const auto samples = stream_all(pa10_demo(path, rate, true), stream_status);
      ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
      const double streamed = streamed_acceleration_usage(samples, model);
      std::printf("[ measured ]   streamed at %.0f Hz: %.4f\n", rate, streamed);
      EXPECT_LT(streamed, 0.9 * before) << rate << " Hz";
      EXPECT_LT(streamed, after * 1.05 + 0.02) << rate << " Hz: the report's usage, measured";
    }
  }
}

TEST_F(RedundancyTest, BadRequestsNameTheirField) {
  auto field_of = [&](const v1::PlanRequest& request) {
    v1::PlanResponse response;
    const auto status = plan(request, response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    const auto v = bad_request_violations(status);
    return v.empty() ? std::string() : v.front().field + ": " + v.front().description;
  };
  auto negative = pa10_demo('a', 100.0, true);
  negative.mutable_optimize()->mutable_redundancy()->set_velocity_weight(-1.0);
  EXPECT_THAT(field_of(negative), HasSubstr("optimize.redundancy.velocityWeight"));
  auto huge = pa10_demo('a', 100.0, true);
  huge.mutable_optimize()->mutable_redundancy()->set_acceleration_weight(1e300);
  EXPECT_THAT(field_of(huge), HasSubstr("optimize.redundancy.accelerationWeight: must be a weight in [0, "));
  auto none = pa10_demo('a', 100.0, false);
  none.mutable_optimize()->mutable_redundancy();
  EXPECT_THAT(field_of(none), HasSubstr("optimize.redundancy: weighs nothing"));
  auto ur5 = pa10_demo('a', 100.0, true);
  ur5.mutable_robot()->set_name("ur5");
  EXPECT_THAT(field_of(ur5), HasSubstr("more than 6 joints"));
  auto no_robot = pa10_demo('a', 100.0, true);
  no_robot.clear_robot();
  EXPECT_THAT(field_of(no_robot), HasSubstr("optimize.redundancy: needs a robot"));
}

}  // namespace
}  // namespace geotraj::testing
