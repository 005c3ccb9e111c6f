// Golden: thesis Appendix B.3 (Table B.1, Eqs. B.10, B.11, B.13). The thesis reports, from
// its plots (Figures B.4, B.7, B.10; it prints no peak values):
//  - B.11 (narrow ramps) lowers the peak parametric derivatives and "the peak value of the
//    torsion plot ... decreased considerably" from B.10;
//  - B.13 (staggered axes on u in [1, 2]) "did lower the peak value of torsion at the
//    desired point" (the start of [1, 2]) but "created an extra smaller peak towards the end";
//  - optimising the breakpoints is left to future work: the optimiser must be at least as
//    good as the best hand-tuned set.
// The numbers are printed; the assertions are the orderings.
#include <cstdio>

#include <gtest/gtest.h>

#include "appendix_b_paths.hpp"
#include "breakpoint_support.hpp"

namespace geotraj::test {
namespace {

using optim::BreakpointObjective;

core::Path build_or_fail(const core::PathSpec& spec) {
  auto path = core::build_path(spec);
  if (!path) {
    ADD_FAILURE() << "build_path failed: " << path.error().front().field << ": " << path.error().front().description;
    return {};
  }
  return *path;
}

// The key frames' constraints on the curve, to the tolerance of the core's trapezoid tests.
void ExpectFramesMet(const core::Path& path) {
  const auto achieved = core::achieved_geometry(path);
  const auto err = core::closed_loop_error(path, achieved);
  EXPECT_LT(err.max_error, 1e-9) << err.worst_field;
  // Table B.1's tau' = 0 at frame 2, left out of the request (appendix_b_paths.hpp), holds.
  ASSERT_TRUE(achieved[1].approach && achieved[1].leave);
  EXPECT_NEAR(achieved[1].approach->tau_du, 0.0, 1e-9);
  EXPECT_NEAR(achieved[1].leave->tau_du, 0.0, 1e-9);
}

TEST(AppendixB3, TableB1PeakTorsion) {
  const core::Path b10 = build_or_fail(testing::table_b1_path());
  const core::Path b11 = build_or_fail(testing::table_b1_with_b11());
  const core::Path b13 = build_or_fail(testing::table_b1_with_b13());
  optim::BreakpointOptions options;  // defaults: peak torsion
  const auto opt = optim::optimize_breakpoints(testing::table_b1_path(), options);
  ASSERT_TRUE(opt);
  const core::Path best = build_or_fail(opt->spec);

  struct Row {
    const char* name;
    const core::Path* path;
  };
  const Row rows[] = {{"uniform (B.10)", &b10}, {"hand-tuned (B.11)", &b11}, {"staggered (B.13)", &b13},
                      {"optimised", &best}};
  std::printf("Table B.1, trapezoid blend: peaks along the path, frames included (dense, 20000 points per segment)\n");
  std::printf("%-18s %12s %12s %12s %14s\n", "breakpoints", "peak |tau|", "|tau| [1,1.5]", "peak kappa",
              "peak |d4p/du4|");
  double tau[4], tau_early[4];
  for (int i = 0; i < 4; ++i) {
    const core::Path& p = *rows[i].path;
    ExpectFramesMet(p);
    tau[i] = testing::dense_peak(p, BreakpointObjective::kPeakTorsion);
    tau_early[i] = testing::dense_peak(p, BreakpointObjective::kPeakTorsion, 20000, 1.0, 1.5);
    std::printf("%-18s %12.4f %12.4f %12.4f %14.2f\n", rows[i].name, tau[i], tau_early[i],
                testing::dense_peak(p, BreakpointObjective::kPeakCurvature), testing::dense_derivative_peak(p));
  }
  std::printf("optimiser: %s, %d evaluations, %.3f s\n", optim::name(opt->report.status), opt->report.iterations,
              opt->report.seconds);
  for (const auto& bp : opt->breakpoints) {
    for (const auto* list : {&bp.x, &bp.y, &bp.z}) {
      std::printf("  segment %u:", bp.segment);
      for (double u : *list) std::printf(" %.4f", u);
      std::printf("\n");
    }
  }

  EXPECT_LT(tau[1], tau[0]) << "B.11 lowers the peak torsion of B.10";
  EXPECT_LT(tau_early[2], tau_early[1]) << "B.13 lowers the torsion peak at the start of [1, 2]";
  EXPECT_LE(tau[3], std::min(tau[1], tau[2])) << "the optimiser is at least as good as the hand-tuned sets";
  // The report agrees with the independent dense measure (sampling + refinement: 1%).
  EXPECT_NEAR(opt->report.objective_before, tau[0], 0.01 * tau[0]);
  EXPECT_NEAR(opt->report.objective_after, tau[3], 0.01 * tau[3]);
}

// B.11 lowers the peak parametric derivatives (the aim the thesis tuned it for), and the
// derivative objective lowers them further.
TEST(AppendixB3, TableB1PeakDerivatives) {
  const double b10 = testing::dense_derivative_peak(build_or_fail(testing::table_b1_path()));
  const double b11 = testing::dense_derivative_peak(build_or_fail(testing::table_b1_with_b11()));
  optim::BreakpointOptions options;
  options.objective = BreakpointObjective::kPeakDerivatives;
  const auto opt = optim::optimize_breakpoints(testing::table_b1_path(), options);
  ASSERT_TRUE(opt);
  const double best = testing::dense_derivative_peak(build_or_fail(opt->spec));
  std::printf("peak |d4p/du4|: B.10 %.2f, B.11 %.2f, optimised %.2f\n", b10, b11, best);
  EXPECT_LT(b11, b10);
  EXPECT_LE(best, b11);
}

}  // namespace
}  // namespace geotraj::test
