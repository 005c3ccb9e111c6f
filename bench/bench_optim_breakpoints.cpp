// The trapezoid breakpoint optimiser (optim/breakpoints/breakpoints.hpp): time per optimisation on the
// path of thesis Table B.1 (2 segments, 4th-order trapezoids) and on the thesis's 4-frame
// demonstration path A (Table 7.18) blended with trapezoids, per objective, with the
// default options (4 runs per block, 12000 evaluations). Counters: objective before and
// after, evaluations. Run: build/bench/bench_optim_breakpoints --benchmark_repetitions=3
#include <benchmark/benchmark.h>

#include "../tests/optim/breakpoints/appendix_b_paths.hpp"
#include "core/geometry/path.hpp"
#include "optim/breakpoints/breakpoints.hpp"
#include "thesis_paths.hpp"

namespace {

using namespace geotraj;

core::PathSpec bench_path(int which) {
  return which == 0 ? testing::table_b1_path() : testing::thesis_demo_path('A', core::BlendMethod::kTrapezoidal);
}

void BM_OptimizeBreakpoints(benchmark::State& state) {
  const core::PathSpec spec = bench_path(static_cast<int>(state.range(0)));
  optim::BreakpointOptions options;
  options.objective = static_cast<optim::BreakpointObjective>(state.range(1));
  optim::OptimizerReport report;
  for (auto _ : state) {
    auto r = optim::optimize_breakpoints(spec, options);
    if (!r) {
      state.SkipWithError("optimize_breakpoints failed");
      return;
    }
    report = r->report;
    benchmark::DoNotOptimize(r);
  }
  state.SetLabel(std::string(state.range(0) == 0 ? "table_b1" : "demo_A") + "/" + optim::name(options.objective) +
                 "/" + optim::name(report.status));
  state.counters["before"] = report.objective_before;
  state.counters["after"] = report.objective_after;
  state.counters["evaluations"] = report.iterations;
}
BENCHMARK(BM_OptimizeBreakpoints)
    ->ArgsProduct({{0, 1}, {0, 1, 2}})
    ->ArgNames({"path", "objective"})
    ->Unit(benchmark::kMillisecond);

// One evaluation of the peak objective (the optimiser's inner loop) on Table B.1.
void BM_PeakObjective(benchmark::State& state) {
  const auto path = core::build_path(testing::table_b1_path());
  const auto objective = static_cast<optim::BreakpointObjective>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(optim::peak_objective(*path, objective));
  state.SetLabel(optim::name(objective));
}
BENCHMARK(BM_PeakObjective)->DenseRange(0, 2)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
