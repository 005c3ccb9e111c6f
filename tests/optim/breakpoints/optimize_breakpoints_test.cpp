// Unit and property tests of optimize_breakpoints: each objective improves (recomputed
// independently from core::analyze), the key frames' constraints stay met, the breakpoints
// are ordered and inside their segment, results are deterministic, time limits return the
// best valid result with an honest status, and bad requests are named errors.
#include <chrono>
#include <random>
#include <stop_token>

#include <gtest/gtest.h>

#include "appendix_b_paths.hpp"
#include "breakpoint_support.hpp"
#include "thesis_paths.hpp"

namespace geotraj::test {
namespace {

using optim::BreakpointObjective;
using optim::OptimizerStatus;

constexpr std::uint64_t kSeed = 20240611;  // fixed: the random cases are reproducible
constexpr int kRandomCases = 6;

constexpr BreakpointObjective kObjectives[] = {BreakpointObjective::kPeakTorsion, BreakpointObjective::kPeakCurvature,
                                               BreakpointObjective::kPeakDerivatives};

// Closed-loop error of a spec's curve (the frames' constraints as measured on it).
double frame_error(const core::PathSpec& spec) {
  auto path = core::build_path(spec);
  if (!path) return 1e300;
  return core::closed_loop_error(*path, core::achieved_geometry(*path)).max_error;
}

// The checks every successful result passes, against the request it came from.
void ExpectValidResult(const core::PathSpec& request, const optim::BreakpointResult& r, BreakpointObjective objective) {
  auto path = core::build_path(r.spec);
  ASSERT_TRUE(path) << path.error().front().field << ": " << path.error().front().description;
  EXPECT_EQ(testing::breakpoint_problem(*path, r.breakpoints), "");
  EXPECT_LE(r.report.objective_after, r.report.objective_before);
  // Frames: what the request's curve met, the result's curve meets as well.
  const double before = frame_error(request), after = frame_error(r.spec);
  EXPECT_LE(after, std::max(1e-9, 10.0 * before));
  // The reported objective agrees with an independent dense measure.
  const double dense = testing::dense_objective(*path, objective);
  EXPECT_NEAR(r.report.objective_after, dense, 0.01 * std::max(dense, 1e-3)) << optim::name(objective);
}

TEST(OptimizeBreakpoints, ImprovesEachObjectiveOnTableB1) {
  for (const auto objective : kObjectives) {
    SCOPED_TRACE(optim::name(objective));
    optim::BreakpointOptions options;
    options.objective = objective;
    const auto r = optim::optimize_breakpoints(testing::table_b1_path(), options);
    ASSERT_TRUE(r);
    ExpectValidResult(testing::table_b1_path(), *r, objective);
    if (objective == BreakpointObjective::kPeakCurvature) {
      // Table B.1's peak curvature is frame 2's own kappa = 5 (B.10's largest interior
      // value is 4.08): no breakpoints can lower it, and the optimiser says so.
      EXPECT_NEAR(r->report.objective_before, 5.0, 1e-6);
      EXPECT_EQ(r->report.status, OptimizerStatus::kNoImprovement);
      continue;
    }
    EXPECT_LT(r->report.objective_after, 0.9 * r->report.objective_before);
    EXPECT_TRUE(r->report.status == OptimizerStatus::kConverged || r->report.status == OptimizerStatus::kIterationLimit)
        << optim::name(r->report.status);
    EXPECT_GT(r->report.iterations, 0);
  }
}

TEST(OptimizeBreakpoints, ImprovesRandomTrapezoidPaths) {
  std::mt19937_64 rng(kSeed);
  int built = 0;
  for (int trial = 0; built < kRandomCases && trial < 10 * kRandomCases; ++trial) {
    const core::PathSpec spec = testing::random_trapezoid_path(rng);
    if (!core::build_path(spec)) continue;
    ++built;
    SCOPED_TRACE("random case (seed " + std::to_string(kSeed) + ", trial " + std::to_string(trial) + "):\n" +
                 testing::describe(spec));
    for (const auto objective : kObjectives) {
      SCOPED_TRACE(optim::name(objective));
      optim::BreakpointOptions options;
      options.objective = objective;
      options.max_evaluations = 3000;
      const auto r = optim::optimize_breakpoints(spec, options);
      ASSERT_TRUE(r);
      ExpectValidResult(spec, *r, objective);
      if (objective == BreakpointObjective::kPeakDerivatives) {
        EXPECT_LT(r->report.objective_after, r->report.objective_before);  // the levels always can move
      }
      if (r->report.status == OptimizerStatus::kNoImprovement) {
        EXPECT_EQ(r->report.objective_after, r->report.objective_before);
      }
    }
  }
  EXPECT_EQ(built, kRandomCases);
}

TEST(OptimizeBreakpoints, Deterministic) {
  for (const auto objective : kObjectives) {
    optim::BreakpointOptions options;
    options.objective = objective;
    options.max_evaluations = 2000;
    const auto a = optim::optimize_breakpoints(testing::table_b1_path(), options);
    const auto b = optim::optimize_breakpoints(testing::table_b1_path(), options);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->report.objective_after, b->report.objective_after);
    EXPECT_EQ(a->report.iterations, b->report.iterations);
    ASSERT_EQ(a->breakpoints.size(), b->breakpoints.size());
    for (std::size_t i = 0; i < a->breakpoints.size(); ++i) {
      EXPECT_EQ(a->breakpoints[i].x, b->breakpoints[i].x);
      EXPECT_EQ(a->breakpoints[i].y, b->breakpoints[i].y);
      EXPECT_EQ(a->breakpoints[i].z, b->breakpoints[i].z);
    }
  }
}

// Starting from hand-tuned breakpoints: never worse than them.
TEST(OptimizeBreakpoints, NeverWorseThanTheRequest) {
  optim::BreakpointOptions options;
  options.max_evaluations = 600;
  const auto r = optim::optimize_breakpoints(testing::table_b1_with_b13(), options);
  ASSERT_TRUE(r);
  ExpectValidResult(testing::table_b1_with_b13(), *r, options.objective);
}

// A zero budget: the request comes back, valid, with the time limit reported.
TEST(OptimizeBreakpoints, ZeroBudgetReturnsTimeLimitWithValidResult) {
  optim::BreakpointOptions options;
  options.time_budget_s = 0.0;
  const auto r = optim::optimize_breakpoints(testing::table_b1_path(), options);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->report.status, OptimizerStatus::kTimeLimit);
  EXPECT_EQ(r->report.objective_after, r->report.objective_before);
  ExpectValidResult(testing::table_b1_path(), *r, options.objective);
}

TEST(OptimizeBreakpoints, PastDeadlineReturnsTimeLimit) {
  optim::BreakpointOptions options;
  options.deadline = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  const auto r = optim::optimize_breakpoints(testing::table_b1_path(), options);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->report.status, OptimizerStatus::kTimeLimit);
  ExpectValidResult(testing::table_b1_path(), *r, options.objective);
}

TEST(OptimizeBreakpoints, CancelledReturnsTimeLimit) {
  std::stop_source source;
  source.request_stop();
  optim::BreakpointOptions options;
  options.stop = source.get_token();
  const auto r = optim::optimize_breakpoints(testing::table_b1_path(), options);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->report.status, OptimizerStatus::kTimeLimit);
  EXPECT_EQ(r->report.message, "cancelled");
}

// A short budget: stops early (kTimeLimit) or finishes, and either way the result is valid
// and no worse than the request. (No timing assertion: only the status's honesty.)
TEST(OptimizeBreakpoints, ShortBudgetIsHonest) {
  optim::BreakpointOptions options;
  options.time_budget_s = 0.02;
  options.max_evaluations = 1000000;
  const auto r = optim::optimize_breakpoints(testing::thesis_demo_path('B', core::BlendMethod::kTrapezoidal), options);
  ASSERT_TRUE(r);
  ExpectValidResult(testing::thesis_demo_path('B', core::BlendMethod::kTrapezoidal), *r, options.objective);
  if (r->report.status != OptimizerStatus::kTimeLimit) {
    EXPECT_TRUE(r->report.status == OptimizerStatus::kConverged ||
                r->report.status == OptimizerStatus::kIterationLimit ||
                r->report.status == OptimizerStatus::kNoImprovement);
  }
}

TEST(OptimizeBreakpoints, PolynomialBlendIsANamedError) {
  auto spec = testing::table_b1_path();
  spec.blend = core::BlendMethod::kPolynomial;
  const auto r = optim::optimize_breakpoints(spec, {});
  ASSERT_FALSE(r);
  ASSERT_EQ(r.error().size(), 1u);
  EXPECT_EQ(r.error()[0].field, "path.blend");
  EXPECT_NE(r.error()[0].description.find("TRAPEZOIDAL"), std::string::npos);
}

// Two values (a path and options): fields named from the PlanRequest's root (core/error.hpp).
TEST(OptimizeBreakpoints, InvalidPathReturnsItsViolations) {
  auto spec = testing::table_b1_path();
  spec.frames[1].tau = std::nan("");
  const auto r = optim::optimize_breakpoints(spec, {});
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error()[0].field, "path.frames[1].torsion");
}

TEST(OptimizeBreakpoints, BadOptionsAreNamedErrors) {
  optim::BreakpointOptions options;
  options.max_evaluations = 0;
  options.restarts = -1;
  options.min_ramp = 0.5;
  options.time_budget_s = -1.0;
  const auto r = optim::optimize_breakpoints(testing::table_b1_path(), options);
  ASSERT_FALSE(r);
  std::vector<std::string> fields;
  for (const auto& v : r.error()) fields.push_back(v.field);
  EXPECT_EQ(fields, (std::vector<std::string>{"optimize.breakpoints.maxEvaluations", "optimize.breakpoints.restarts",
                                              "optimize.breakpoints.minRamp", "optimize.timeBudgetS"}));
}

}  // namespace
}  // namespace geotraj::test
