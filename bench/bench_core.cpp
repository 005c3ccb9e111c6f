// Core stages of geotraj, one benchmark each: Chapter 5 conversion per frame, building the
// thesis's 4-frame demonstration path (validation, conversion, blending, arc lengths), arc
// length alone, path evaluation, analysis, paths of 10 to 10,000 frames (cost linear in the
// number of frames), and curves from their natural equations (built, then evaluated).
// Run: build/bench/bench_core --benchmark_repetitions=5
#include <string>
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "core/geometry/analysis.hpp"
#include "core/geometry/arc_length.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/geometry_report.hpp"
#include "core/geometry/natural.hpp"
#include "core/geometry/path.hpp"
#include "thesis_paths.hpp"

namespace {

using namespace geotraj;

// A frame with every constraint given (orders 1..4): the most work per frame.
core::KeyFrame full_frame() {
  core::KeyFrame f;
  f.p_W = {1, 1, 1};
  f.T_W = Eigen::Vector3d(0.707, 0.3536, 0.6124).normalized();
  f.N_W = Eigen::Vector3d(0, -0.866, 0.5).normalized();
  f.kappa = 3;
  f.kappa_d = -10;
  f.tau = -5;
  f.tau_d = 25;
  return f;
}

void BM_ConvertFrame(benchmark::State& state) {
  const auto frame = full_frame();
  for (auto _ : state) {
    auto c = core::convert_frame(frame, core::DerivativeConvention::kPerArcLength);
    benchmark::DoNotOptimize(c);
  }
}
BENCHMARK(BM_ConvertFrame);

// Path C under each reading of unspecified constraints (arg 1: 0 smoothest, 1 thesis's
// zeros, 2 lowest degree), polynomial (arg 0 = 0) or trapezoidal blend.
void BM_BuildDemoPath(benchmark::State& state) {
  const auto blend = state.range(0) == 0 ? core::BlendMethod::kPolynomial : core::BlendMethod::kTrapezoidal;
  const core::UnspecifiedConstraints readings[] = {core::UnspecifiedConstraints::kSmoothest,
                                                   core::UnspecifiedConstraints::kThesisZeros,
                                                   core::UnspecifiedConstraints::kLowestDegree};
  const auto spec = testing::thesis_demo_path('C', blend, readings[state.range(1)]);
  for (auto _ : state) {
    auto path = core::build_path(spec);
    benchmark::DoNotOptimize(path);
  }
  static const char* kNames[] = {"smoothest", "thesis zeros", "lowest degree"};
  state.SetLabel(std::string(state.range(0) == 0 ? "polynomial, " : "trapezoidal, ") + kNames[state.range(1)]);
}
BENCHMARK(BM_BuildDemoPath)->ArgsProduct({{0, 1}, {0, 1, 2}})->Unit(benchmark::kMicrosecond);

void BM_ArcLengthDemoPath(benchmark::State& state) {
  const auto path = *core::build_path(testing::thesis_demo_path('C'));
  for (auto _ : state) {
    double s = 0.0;
    for (const auto& seg : path.segments) s += core::segment_arc_length(seg, 0.0, 1.0);
    benchmark::DoNotOptimize(s);
  }
}
BENCHMARK(BM_ArcLengthDemoPath)->Unit(benchmark::kMicrosecond);

void BM_EvaluateJet(benchmark::State& state) {
  const auto path = *core::build_path(testing::thesis_demo_path('C'));
  double u = 0.0;
  for (auto _ : state) {
    auto jet = core::evaluate(path, u, core::kMaxJetOrder);
    benchmark::DoNotOptimize(jet);
    u += 1e-3;
    if (u > path.u_max()) u = 0.0;
  }
}
BENCHMARK(BM_EvaluateJet);

// Curves from their natural equations (natural.hpp): Arg 0 a 100-turn helix (radius 0.05 m,
// pitch 0.02 m: the closed form), 1 a clothoid (kappa 0 -> 20 1/m over 1 m: the Fresnel
// integrals' closed form), 2 a profile (kappa = 5 + 3 s - 2 s^2, tau = 1 - 4 s over 1.2 m),
// 3 the clothoid of 1 integrated by the Magnus method instead (a torsion of 1e-300 1/m, which
// moves nothing, takes that path), each to 1e-9 m.
core::Expected<core::NaturalCurve> natural_curve(int which) {
  switch (which) {
    case 0: {
      const core::CurvatureTorsion kt = core::helix_curvature_torsion(0.05, 0.02);
      const double turn = 2.0 * 3.141592653589793 * std::hypot(0.05, 0.02 / (2.0 * 3.141592653589793));
      return core::NaturalCurve::build(core::FrenetFrame{}, 100.0 * turn, {kt.kappa}, {kt.tau});
    }
    case 1:
      return core::NaturalCurve::build(core::FrenetFrame{}, 1.0, {0.0, 20.0}, {});
    case 2:
      return core::NaturalCurve::build(core::FrenetFrame{}, 1.2, {5.0, 3.0, -2.0}, {1.0, -4.0});
    default:
      return core::NaturalCurve::build(core::FrenetFrame{}, 1.0, {0.0, 20.0}, {1e-300});
  }
}

void BM_NaturalCurveBuild(benchmark::State& state) {
  for (auto _ : state) {
    auto curve = natural_curve(static_cast<int>(state.range(0)));
    benchmark::DoNotOptimize(curve);
  }
  state.SetLabel(std::to_string(natural_curve(static_cast<int>(state.range(0)))->steps()) + " steps");
}
BENCHMARK(BM_NaturalCurveBuild)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

void BM_NaturalCurveJet(benchmark::State& state) {
  const auto curve = *natural_curve(static_cast<int>(state.range(0)));
  double s = 0.0;
  const double ds = curve.length() / 997.0;
  for (auto _ : state) {
    auto jet = curve.jet_at(s);
    benchmark::DoNotOptimize(jet);
    s += ds;
    if (s > curve.length()) s = 0.0;
  }
}
BENCHMARK(BM_NaturalCurveJet)->DenseRange(0, 3);

// Paths of pieces (core/geometry/pieces.hpp). Argument: 0 = the weld seam (line, quarter
// arc of 0.04 m, line) resting at its joins, 1 = the same with transitions within 0.1 mm,
// 2 = 100 turns of a helix (r 0.05 m, pitch 0.02 m) between two lines with transitions,
// 3 = 30 arcs and lines alternating with transitions (a piece's cost in a long path).
core::PathSpec pieces_path(int which) {
  core::PathSpec spec;
  core::KeyFrame start;
  start.N_W = Eigen::Vector3d::UnitY();
  spec.start = start;
  const auto piece = [](core::PieceShape shape, double length, double radius = 0.0, double pitch = 0.0) {
    core::PathPiece p;
    p.shape = shape;
    p.length_m = length;
    p.radius = radius;
    p.pitch = pitch;
    return p;
  };
  constexpr double kPi = 3.141592653589793;
  using core::PieceShape;
  if (which <= 1) {
    spec.pieces = {piece(PieceShape::kLine, 0.1), piece(PieceShape::kArc, 0.5 * kPi * 0.04, 0.04),
                   piece(PieceShape::kLine, 0.1)};
  } else if (which == 2) {
    const double turn = 2.0 * kPi * std::hypot(0.05, 0.02 / (2.0 * kPi));
    spec.pieces = {piece(PieceShape::kLine, 0.05), piece(PieceShape::kHelix, 100.0 * turn, 0.05, 0.02),
                   piece(PieceShape::kLine, 0.05)};
  } else {
    for (int i = 0; i < 30; ++i)
      spec.pieces.push_back(i % 2 ? piece(PieceShape::kArc, 0.05, 0.1) : piece(PieceShape::kLine, 0.05));
  }
  if (which >= 1) spec.transition_tolerance = 1e-4;
  return spec;
}

void BM_BuildPiecePath(benchmark::State& state) {
  const auto spec = pieces_path(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    auto path = core::build_path(spec);
    benchmark::DoNotOptimize(path);
  }
  static const char* names[] = {"seam, rests", "seam, transitions 0.1 mm", "100-turn helix, transitions",
                                "30 pieces, transitions"};
  state.SetLabel(std::string(names[state.range(0)]) + ", " +
                 std::to_string(core::build_path(spec)->segment_count()) + " segments");
}
BENCHMARK(BM_BuildPiecePath)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

void BM_AnalyzeDemoPath(benchmark::State& state) {
  const auto path = *core::build_path(testing::thesis_demo_path('C'));
  for (auto _ : state) {
    auto profile = core::analyze(path, static_cast<std::size_t>(state.range(0)));
    benchmark::DoNotOptimize(profile);
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_AnalyzeDemoPath)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);

// A random walk of frames, 0.1 m apart, every third one with curvature and torsion.
core::PathSpec many_frames(std::size_t n) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  core::PathSpec spec;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    core::KeyFrame f;
    const Eigen::Vector3d T = Eigen::Vector3d(1.0, 0.3 * uni(rng), 0.3 * uni(rng)).normalized();
    Eigen::Vector3d N = T.cross(Eigen::Vector3d(uni(rng), uni(rng), uni(rng)));
    N.normalize();
    f.p_W = p;
    f.T_W = T;
    f.N_W = N;
    f.tangent_scale = 0.1;
    if (i % 3 == 1) {
      f.kappa = 2.0 + uni(rng);
      f.tau = 5.0 * uni(rng);
    }
    spec.frames.push_back(f);
    p += 0.1 * T;
  }
  return spec;
}

void BM_BuildManyFrames(benchmark::State& state) {
  const auto spec = many_frames(static_cast<std::size_t>(state.range(0)));
  for (auto _ : state) {
    auto path = core::build_path(spec);
    benchmark::DoNotOptimize(path);
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.SetComplexityN(state.range(0));
}
BENCHMARK(BM_BuildManyFrames)->RangeMultiplier(10)->Range(10, 10000)->Unit(benchmark::kMillisecond)->Complexity(benchmark::oN);

// The geometry between frames that every PlanTrajectory reports (geometry_report): the
// demonstration path (3 segments, 64 points each) and long paths (65,536 points in all).
void BM_GeometryReportDemoPath(benchmark::State& state) {
  const auto path = core::build_path(testing::thesis_demo_path('C', core::BlendMethod::kPolynomial,
                                                                core::UnspecifiedConstraints::kSmoothest))
                        .value();
  for (auto _ : state) benchmark::DoNotOptimize(core::geometry_report(path));
}
BENCHMARK(BM_GeometryReportDemoPath)->Unit(benchmark::kMicrosecond);

void BM_GeometryReportManyFrames(benchmark::State& state) {
  const auto path = core::build_path(many_frames(static_cast<std::size_t>(state.range(0)))).value();
  for (auto _ : state) benchmark::DoNotOptimize(core::geometry_report(path));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_GeometryReportManyFrames)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
