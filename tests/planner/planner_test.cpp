// The planner (planner/planner.hpp) as the server calls it: one request value in, one plan or
// one error out. Its budget stops every kind of long work (cancelled, or past its deadline),
// its errors carry their kind, and every field path it reports is absolute from the
// request's root in proto JSON names (core/error.hpp).
#include "planner/planner.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <stop_token>
#include <thread>

#include "long_work.hpp"

namespace geotraj {
namespace {

using std::chrono::milliseconds;
using testing::LongWork;
using ::testing::AllOf;
using ::testing::Each;
using ::testing::Field;
using ::testing::StartsWith;

class LongWorkTest : public ::testing::TestWithParam<LongWork> {};

// A stop requested 100 ms into work that takes seconds ends it with kStopped, not with a
// plan: the work watched the token (how soon: bench_planner, docs/performance.md).
TEST_P(LongWorkTest, ACancelledBudgetStopsTheWork) {
  const auto request = testing::long_request(GetParam());
  std::stop_source stop;
  planner::Budget budget;
  budget.stop = stop.get_token();
  auto result = std::async(std::launch::async, [&] { return testing::run_long_work(GetParam(), request, budget); });
  ASSERT_EQ(result.wait_for(milliseconds(100)), std::future_status::timeout)
      << "the work ended within 100 ms: it is no longer long enough to show the cancellation";
  stop.request_stop();
  const auto error = result.get();
  ASSERT_TRUE(error.has_value()) << "the work ran to its end although it was cancelled";
  EXPECT_EQ(error->kind, planner::ErrorKind::kStopped);
}

TEST_P(LongWorkTest, APassedDeadlineStopsTheWork) {
  const auto request = testing::long_request(GetParam());
  planner::Budget budget;
  budget.deadline = std::chrono::steady_clock::now() + milliseconds(100);
  const auto error = testing::run_long_work(GetParam(), request, budget);
  ASSERT_TRUE(error.has_value()) << "the work ran past its deadline to its end";
  EXPECT_EQ(error->kind, planner::ErrorKind::kDeadlineExceeded);
}

INSTANTIATE_TEST_SUITE_P(Planner, LongWorkTest, ::testing::ValuesIn(testing::kLongWork),
                         [](const auto& test) { return testing::name(test.param); });

// A budget stopped before the call: nothing runs.
TEST(Planner, AStoppedBudgetPlansNothing) {
  std::stop_source stop;
  stop.request_stop();
  planner::Budget budget;
  budget.stop = stop.get_token();
  const auto plan = planner::plan(testing::long_request(LongWork::kRobotPass), budget, planner::Limits{});
  ASSERT_FALSE(plan.has_value());
  EXPECT_EQ(plan.error().kind, planner::ErrorKind::kStopped);
}

// The same request plans to the end with an open budget (what the tests above stop is work
// that succeeds).
TEST(Planner, TheAnalysisRunsToItsEndWithAnOpenBudget) {
  auto request = testing::long_request(LongWork::kAnalysis);
  const auto analysis = planner::analyze(request, 1000, planner::Budget{});
  ASSERT_TRUE(analysis.has_value());
  EXPECT_EQ(analysis->points.size(), 1000u);
}

// Field paths leave the planner absolute from the request's root, whichever layer found the
// problem: the path's validation (relative in core, prefixed once here), the motion's, the
// breakpoint optimiser's options and the path it was given.
TEST(Planner, FieldPathsAreAbsoluteFromTheRequestRoot) {
  auto request = testing::long_request(LongWork::kRobotPass);
  auto& spec = std::get<core::PathSpec>(request.geometry);
  spec.frames[1].kappa = -1.0;  // curvature must be >= 0
  auto plan = planner::plan(request, planner::Budget{}, planner::Limits{});
  ASSERT_FALSE(plan.has_value());
  EXPECT_EQ(plan.error().kind, planner::ErrorKind::kInvalidArgument);
  ASSERT_FALSE(plan.error().violations.empty());
  EXPECT_THAT(plan.error().violations, Each(Field(&core::FieldViolation::field, StartsWith("path.frames[1]."))));

  request = testing::long_request(LongWork::kRobotPass);
  request.motion->duration_s = -1.0;
  plan = planner::plan(request, planner::Budget{}, planner::Limits{});
  ASSERT_FALSE(plan.has_value());
  ASSERT_FALSE(plan.error().violations.empty());
  EXPECT_EQ(plan.error().violations.front().field, "motion.durationS");

  request = testing::long_request(LongWork::kBreakpoints);
  request.optimize->breakpoints->min_ramp = 0.5;
  plan = planner::plan(request, planner::Budget{}, planner::Limits{});
  ASSERT_FALSE(plan.has_value());
  ASSERT_FALSE(plan.error().violations.empty());
  EXPECT_EQ(plan.error().violations.front().field, "optimize.breakpoints.minRamp");

  request = testing::long_request(LongWork::kBreakpoints);
  std::get<core::PathSpec>(request.geometry).frames[0].tangent_scale = -2.0;
  plan = planner::plan(request, planner::Budget{}, planner::Limits{});
  ASSERT_FALSE(plan.has_value());
  ASSERT_FALSE(plan.error().violations.empty());
  EXPECT_THAT(plan.error().violations, Each(Field(&core::FieldViolation::field, StartsWith("path."))));
}

// Without a robot, which of the tool's limits sets the pace is measured on the samples, as
// the robot report measures it with one: the thesis's path A at maxSpeed 0.05 m/s cruises at
// that speed (CARTESIAN_SPEED at 100 %), and a jerk-limited timing's report carries the
// stretches measured on its own samples (its warm start's belong to a faster motion).
TEST(Planner, WithoutARobotTheToolLimitThatBindsIsMeasuredOnTheSamples) {
  planner::Request request;
  request.geometry = testing::thesis_demo_path('A');
  request.motion = core::MotionSpec{};
  request.motion->duration_s = 0.0;
  request.motion->max_speed = 0.05;
  request.motion->max_acceleration = 0.5;
  request.motion->max_jerk = 5.0;
  auto plan = planner::plan(request, planner::Budget{}, planner::Limits{});
  ASSERT_TRUE(plan.has_value());
  ASSERT_TRUE(plan->summary.has_value());
  const auto& binding = plan->summary->binding;
  ASSERT_FALSE(binding.empty());
  const auto speed = std::find_if(binding.begin(), binding.end(), [](const core::BindingStretch& b) {
    return b.kind == core::BindingKind::kCartesianSpeed;
  });
  ASSERT_NE(speed, binding.end());
  EXPECT_NEAR(speed->usage, 1.0, 1e-6);
  EXPECT_NEAR(speed->value, 0.05, 1e-8);
  EXPECT_GT(speed->t_end - speed->t_start, 0.5 * plan->summary->duration_s) << "it cruises most of the way";
  EXPECT_LE(plan->summary->tool.speed, 0.05 * (1.0 + 1e-9));
  for (const auto& b : binding) EXPECT_LE(b.usage, 1.0 + 1e-6) << core::name(b.kind);

  request.optimize = planner::Optimize{};
  request.optimize->jerk_limited = true;
  plan = planner::plan(request, planner::Budget{}, planner::Limits{});
  ASSERT_TRUE(plan.has_value());
  ASSERT_TRUE(plan->optimizers.timing.has_value());
  EXPECT_TRUE(plan->optimizers.timing->jerk_limited);
  const auto& measured = plan->summary->binding;
  ASSERT_FALSE(measured.empty());
  ASSERT_EQ(plan->optimizers.timing->binding.size(), measured.size());
  EXPECT_EQ(plan->optimizers.timing->binding.back().t_end, measured.back().t_end);
  EXPECT_NEAR(measured.back().t_end, plan->summary->duration_s, 1e-9) << "the stretches cover this motion";
  const double most = std::max_element(measured.begin(), measured.end(), [](const auto& a, const auto& b) {
                        return a.usage < b.usage;
                      })->usage;
  EXPECT_GT(most, 0.99) << "some limit sets the pace";
  EXPECT_LE(most, 1.0 + 1e-6);
}

TEST(Planner, ConvertNamesFieldsFromTheRequestRoot) {
  auto spec = testing::thesis_demo_path('A');
  spec.frames[2].kappa = -3.0;
  const auto frames = planner::convert(spec);
  ASSERT_FALSE(frames.has_value());
  EXPECT_EQ(frames.error().kind, planner::ErrorKind::kInvalidArgument);
  EXPECT_THAT(frames.error().violations, Each(Field(&core::FieldViolation::field, StartsWith("path.frames[2]."))));
  EXPECT_TRUE(planner::convert(testing::thesis_demo_path('A')).has_value());
}

}  // namespace
}  // namespace geotraj
