// Tangent-scale optimisation (optim/tangent_scales/tangent_scales.hpp) on the thesis's 4-frame demo
// (Section 7.2, paths A, B, C of Table 7.18), one benchmark per objective. Arguments: the
// path (0 = A, 1 = B, 2 = C) and the reading of unspecified constraints (0 = smoothest, the
// default, on SLSQP; 1 = the thesis's zeros and 2 = lowest degree, on Ipopt). Counters: solver iterations and the objective before and after
// (in the objective's unit), so a change in cost can be told from a change in the solution.
// Each runs 7 repetitions and reports the median and the worst (max) case: the machine is
// often shared, and the median is the robust figure.
#include <algorithm>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "optim/tangent_scales/tangent_scales.hpp"
#include "thesis_paths.hpp"

namespace {

using geotraj::optim::TangentScaleObjective;

void run(benchmark::State& state, TangentScaleObjective objective) {
  const char which = "ABC"[state.range(0)];
  using Reading = geotraj::core::UnspecifiedConstraints;
  const Reading readings[] = {Reading::kSmoothest, Reading::kThesisZeros, Reading::kLowestDegree};
  const char* names[] = {"smoothest", "thesis zeros", "lowest degree"};
  const auto spec = geotraj::testing::thesis_demo_path(which, geotraj::core::BlendMethod::kPolynomial,
                                                       readings[state.range(1)]);
  geotraj::optim::TangentScaleOptions options;
  options.objective = objective;
  geotraj::optim::OptimizerReport report;
  for (auto _ : state) {
    auto result = geotraj::optim::optimize_tangent_scales(spec, options);
    benchmark::DoNotOptimize(result);
    report = result->report;
  }
  state.SetLabel(std::string("path ") + which + ", " + names[state.range(1)] + ", " +
                 geotraj::optim::name(report.status));
  state.counters["iterations"] = report.iterations;
  state.counters["before"] = report.objective_before;
  state.counters["after"] = report.objective_after;
}

double worst(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }

void repeated(benchmark::internal::Benchmark* b) {
  b->Unit(benchmark::kMillisecond)
      ->Repetitions(7)
      ->ComputeStatistics("max", worst)
      ->ReportAggregatesOnly(true);
}

void BM_BendingEnergy(benchmark::State& s) { run(s, TangentScaleObjective::kBendingEnergy); }
void BM_PeakCurvature(benchmark::State& s) { run(s, TangentScaleObjective::kPeakCurvature); }
void BM_PeakTorsion(benchmark::State& s) { run(s, TangentScaleObjective::kPeakTorsion); }
void BM_ArcLength(benchmark::State& s) { run(s, TangentScaleObjective::kArcLength); }

BENCHMARK(BM_BendingEnergy)->ArgsProduct({{0, 1, 2}, {0, 1, 2}})->Apply(repeated);
BENCHMARK(BM_PeakCurvature)->ArgsProduct({{0, 1, 2}, {0, 1, 2}})->Apply(repeated);
BENCHMARK(BM_PeakTorsion)->ArgsProduct({{0, 1, 2}, {0, 1, 2}})->Apply(repeated);
BENCHMARK(BM_ArcLength)->ArgsProduct({{0, 1, 2}, {0, 1, 2}})->Apply(repeated);

}  // namespace

BENCHMARK_MAIN();
