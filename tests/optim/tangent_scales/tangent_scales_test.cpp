// Tangent-scale optimisation (optim/tangent_scales/tangent_scales.hpp). Every objective is recomputed here
// independently of the optimiser, from core's blended path:
//  - bending energy: int kappa^2 |p'| du by composite Simpson (2 kDense intervals per
//    segment) on core::evaluate and core::local_geometry, plus length_weight times core's
//    (adaptive) arc length;
//  - arc length: core::Path::length() (adaptive Gauss-Kronrod);
//  - peak curvature and torsion: the largest kappa and |tau| over core::analyze's profile.
// Properties: each objective improves on the thesis demo paths A, B, C and on random frame
// sets (fixed seed); the frames' constraints hold after optimisation (closed loop); two runs
// give the same bits; the AD gradient matches central differences; a zero budget stops with
// kTimeLimit and a feasible path; bad options are named errors.
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/analysis.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/path.hpp"
#include "core/geometry/validate.hpp"
#include "optim/tangent_scales/tangent_scales.hpp"
#include "thesis_paths.hpp"

namespace geotraj::optim {
namespace {

using core::PathSpec;
using Eigen::Vector3d;
using Objective = TangentScaleObjective;

constexpr std::size_t kDense = 4000;  // profile points per segment for the independent measures
const Objective kAllObjectives[] = {Objective::kBendingEnergy, Objective::kPeakCurvature, Objective::kPeakTorsion,
                                    Objective::kArcLength};

const char* objective_name(Objective o) {
  switch (o) {
    case Objective::kBendingEnergy: return "bending energy";
    case Objective::kPeakCurvature: return "peak curvature";
    case Objective::kPeakTorsion: return "peak torsion";
    case Objective::kArcLength: return "arc length";
  }
  return "?";
}

// The objective measured on core's path, independently of the optimiser's quadrature.
double independent_objective(const PathSpec& spec, Objective objective, double length_weight = 0.0) {
  auto path = core::build_path(spec);
  EXPECT_TRUE(path.has_value());
  if (!path) return NAN;
  if (objective == Objective::kArcLength) return path->length();
  if (objective == Objective::kBendingEnergy) {
    // Composite Simpson in u of kappa^2 |p'| on each segment, from core's evaluation.
    double energy = 0.0;
    const int n = 2 * static_cast<int>(kDense);
    for (std::size_t i = 0; i < path->segment_count(); ++i) {
      for (int j = 0; j <= n; ++j) {
        core::Jet jet;
        core::evaluate(path->segments[i], static_cast<double>(j) / n, 2, jet);
        const auto g = core::local_geometry(jet);
        const double w = (j == 0 || j == n) ? 1.0 : (j % 2 ? 4.0 : 2.0);
        energy += w * g.kappa * g.kappa * g.speed / (3.0 * n);
      }
    }
    return energy + length_weight * path->length();
  }
  const auto profile = core::analyze(*path, kDense * path->segment_count() + 1);
  double result = 0.0;
  for (const auto& point : profile) {
    const auto& g = point.geometry;
    if (objective == Objective::kPeakCurvature) result = std::max(result, g.kappa);
    if (objective == Objective::kPeakTorsion && g.has_normal) {
      // Nearly straight points are left out as documented: kappa < kTorsionCurvatureFraction / chord.
      const std::size_t n = spec.frames.size();
      const std::size_t i = std::min(point.segment, path->segment_count() - 1);
      const double chord = (spec.frames[(i + 1) % n].p_W - spec.frames[i].p_W).norm();
      if (g.kappa >= kTorsionCurvatureFraction / chord) result = std::max(result, std::abs(g.tau));
    }
  }
  return result;
}

double closed_loop(const PathSpec& spec) {
  auto path = core::build_path(spec);
  EXPECT_TRUE(path.has_value());
  if (!path) return INFINITY;
  return core::closed_loop_error(*path, core::achieved_geometry(*path)).max_error;
}

std::string describe(const PathSpec& spec) {
  std::ostringstream os;
  os.precision(17);
  os << "closed=" << spec.closed << " convention=" << static_cast<int>(spec.convention) << "\n";
  for (const auto& f : spec.frames) {
    os << "  p=" << f.p_W.transpose() << " T=" << f.T_W.transpose();
    if (f.N_W) os << " N=" << f.N_W->transpose();
    if (f.kappa) os << " kappa=" << *f.kappa;
    if (f.kappa_d) os << " kappa_d=" << *f.kappa_d;
    if (f.tau) os << " tau=" << *f.tau;
    if (f.tau_d) os << " tau_d=" << *f.tau_d;
    if (f.tangent_scale) os << " scale=" << *f.tangent_scale;
    if (f.leave_tangent_scale) os << " leave_scale=" << *f.leave_tangent_scale;
    if (f.cusp) os << " cusp";
    if (f.inflection) os << " inflection";
    os << "\n";
  }
  return os.str();
}

// Runs one optimisation and checks the properties every result must have. Returns the
// independent objective before and after.
std::pair<double, double> check_optimisation(const PathSpec& spec, const TangentScaleOptions& options) {
  const auto result = optimize_tangent_scales(spec, options);
  EXPECT_TRUE(result.has_value());
  if (!result) return {NAN, NAN};
  const auto& r = *result;
  EXPECT_NE(r.report.status, OptimizerStatus::kFailed) << r.report.message << "\n" << describe(spec);
  EXPECT_LE(r.report.objective_after, r.report.objective_before);
  // The frames' constraints are met exactly (the conversion meets them for any scale).
  {
    const auto path = core::build_path(r.spec);
    EXPECT_TRUE(path.has_value()) << describe(spec);
    if (!path) return {NAN, NAN};
    const auto loop = core::closed_loop_error(*path, core::achieved_geometry(*path));
    // Under the degree 9 readings at scales near their lower bound (0.1 chord, where the
    // arc-length objective goes) the fourth derivative at a frame is a fourth difference of
    // control points a metre in size, 9 * 8 * 7 * 6 times amplified: its rounding reaches a few
    // 1e-9 of a given tau' (measured 7e-9 on one random set). Elsewhere 1e-9.
    const bool degree9 = spec.unspecified != core::UnspecifiedConstraints::kLowestDegree;
    const double loop_tolerance = degree9 && options.objective == Objective::kArcLength ? 1e-8 : 1e-9;
    EXPECT_LT(loop.max_error, loop_tolerance) << loop.worst_field << " " << objective_name(options.objective) << "\n"
                                    << describe(r.spec);
  }
  // Within the default bounds, in the documented layout.
  std::size_t k = 0;
  for (const auto& f : r.spec.frames) {
    EXPECT_EQ(*f.tangent_scale, r.scales.at(k++));
    if (f.leave_tangent_scale) {  // a cusp, or a frame whose two sides have scales of their own
      EXPECT_EQ(*f.leave_tangent_scale, r.scales.at(k++));
    }
  }
  EXPECT_EQ(k, r.scales.size());
  for (double s : r.scales) EXPECT_GT(s, 0.0);
  // The reported objective is what core measures (quadrature vs dense sampling; the peaks
  // are taken at kPeakSamples points, so they can only be below the dense maximum).
  const double after = independent_objective(r.spec, options.objective, r.length_weight);
  if (options.objective == Objective::kPeakCurvature || options.objective == Objective::kPeakTorsion) {
    // Peak torsion: both measures sample a function that spikes at the curvature floor, so
    // they differ by a little either way (2 %, as the property test allows).
    const double slack = options.objective == Objective::kPeakTorsion ? 1.02 : 1 + 1e-3;
    EXPECT_LE(r.report.objective_after, after * slack) << objective_name(options.objective) << "\n"
                                                            << describe(r.spec);
    // Torsion can spike between samples where the curve is nearly straight (a known
    // limitation of the sampled peak, see the header): only curvature is held to the dense measure.
    if (options.objective == Objective::kPeakCurvature) {
      EXPECT_GE(r.report.objective_after, after * 0.9) << describe(spec);
    }
  } else {
    EXPECT_NEAR(r.report.objective_after, after, 2e-3 * after);
  }
  const double before = independent_objective(spec, options.objective, r.length_weight);
  return {before, after};
}

using Reading = core::UnspecifiedConstraints;
const Reading kAllReadings[] = {Reading::kSmoothest, Reading::kThesisZeros, Reading::kLowestDegree};

const char* reading_name(Reading r) {
  switch (r) {
    case Reading::kSmoothest: return "smoothest";
    case Reading::kThesisZeros: return "thesis zeros";
    case Reading::kLowestDegree: return "lowest degree";
  }
  return "?";
}

class ThesisDemo : public ::testing::TestWithParam<std::tuple<char, Objective, Reading>> {};

TEST_P(ThesisDemo, ObjectiveImprovesAndFramesStayMet) {
  const auto [which, objective, reading] = GetParam();
  SCOPED_TRACE(std::string("path ") + which + ", " + objective_name(objective) + ", " + reading_name(reading));
  const PathSpec spec = testing::thesis_demo_path(which, core::BlendMethod::kPolynomial, reading);
  TangentScaleOptions options;
  options.objective = objective;
  const auto [before, after] = check_optimisation(spec, options);
  const auto result = optimize_tangent_scales(spec, options);
  ASSERT_TRUE(result.has_value());
  // Justified exception: the frames' own |tau| bound the peak torsion from below (the
  // conversion meets tau exactly at every scale). Path B's start already attains that bound
  // (frame 3's |tau| = 100 1/m is its peak away from nearly straight points), so no scales
  // can lower it; the result must then be no worse than the start.
  double frame_tau = 0.0;
  for (const auto& f : spec.frames) frame_tau = std::max(frame_tau, std::abs(f.tau.value_or(0.0)));
  if (objective == Objective::kPeakTorsion && before <= frame_tau * 1.01) {
    EXPECT_LE(after, before * 1.01) << "path " << which;
    EXPECT_NE(result->report.status, OptimizerStatus::kFailed);
    return;
  }
  EXPECT_LT(after, 0.99 * before) << "path " << which << ", " << objective_name(objective);
  // The smooth peak objectives (a soft maximum) may stop at the iteration budget once the
  // improvement is made (path B's peak curvature: 206 -> 14.5 1/m); the integral objectives
  // converge.
  if (objective == Objective::kBendingEnergy || objective == Objective::kArcLength) {
    EXPECT_EQ(result->report.status, OptimizerStatus::kConverged) << result->report.message;
  } else {
    EXPECT_TRUE(result->report.status == OptimizerStatus::kConverged ||
                result->report.status == OptimizerStatus::kIterationLimit)
        << result->report.message;
  }
  // The cusp at frame 3 has a free leaving side: 4 frames + 1 cusp side.
  EXPECT_EQ(result->scales.size(), 5u);
}

INSTANTIATE_TEST_SUITE_P(PathsAndObjectives, ThesisDemo,
                         ::testing::Combine(::testing::Values('A', 'B', 'C'), ::testing::ValuesIn(kAllObjectives),
                                            ::testing::ValuesIn(kAllReadings)));

TEST(TangentScales, BendingEnergyWithLengthWeight) {
  const PathSpec spec = testing::thesis_demo_path('B');
  TangentScaleOptions plain, weighted;
  weighted.length_weight = 200.0;  // [1/m^2]
  const auto a = optimize_tangent_scales(spec, plain);
  const auto b = optimize_tangent_scales(spec, weighted);
  ASSERT_TRUE(a && b);
  const auto [before, after] = check_optimisation(spec, weighted);
  EXPECT_LT(after, before);
  EXPECT_NE(a->scales, b->scales);
}

TEST(TangentScales, QuadratureAgreesWithCoreArcLength) {
  for (char which : {'A', 'B', 'C'}) {
    const PathSpec spec = testing::thesis_demo_path(which);
    TangentScaleOptions options;
    options.objective = Objective::kArcLength;
    const auto ours = tangent_scale_objective(spec, options);
    ASSERT_TRUE(ours.has_value());
    // 8 x 8 Gauss nodes integrate the smooth speed of a degree <= 9 polynomial to ~1e-8.
    EXPECT_NEAR(*ours, core::build_path(spec)->length(), 1e-7 * *ours) << which;
  }
}

// Well-posedness: with the regularity rows the curve never nearly stops inside a segment, so
// kappa^2 stays bounded and the solver's fixed rule integrates it. At the optimum (where a
// rule that misses a spike would be exploited) the solver's own value, the reported value
// and core's dense Simpson measure agree within 1 %.
TEST(TangentScales, OptimisedBendingEnergyAgreesWithDenseSampling) {
  for (char which : {'A', 'B', 'C'}) {
    for (double weight : {0.0, 200.0}) {
      TangentScaleOptions options;
      options.length_weight = weight;
      const auto r = optimize_tangent_scales(testing::thesis_demo_path(which), options);
      ASSERT_TRUE(r.has_value());
      const double dense = independent_objective(r->spec, Objective::kBendingEnergy, weight);
      const auto solver = tangent_scale_objective(r->spec, options);
      ASSERT_TRUE(solver.has_value());
      EXPECT_NEAR(*solver, dense, 0.01 * dense) << which << " weight " << weight;
      EXPECT_NEAR(r->report.objective_after, dense, 0.01 * dense) << which << " weight " << weight;
      EXPECT_LT(r->report.objective_after, r->report.objective_before) << which;
    }
  }
}

TEST(TangentScales, Deterministic) {
  for (Objective objective : kAllObjectives) {
    TangentScaleOptions options;
    options.objective = objective;
    const auto a = optimize_tangent_scales(testing::thesis_demo_path('C'), options);
    const auto b = optimize_tangent_scales(testing::thesis_demo_path('C'), options);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->scales, b->scales) << objective_name(objective);
    EXPECT_EQ(a->report.objective_after, b->report.objective_after);
    EXPECT_EQ(a->report.iterations, b->report.iterations);
  }
}

// Central differences with a relative step of 1e-6 (truncation ~1e-12 relative, rounding
// ~1e-10 / 1e-6): the AD gradient agrees to 1e-5 relative to the gradient's size.
TEST(TangentScales, GradientMatchesCentralDifferences) {
  for (char which : {'A', 'B', 'C'}) {
    for (Objective objective : kAllObjectives) {
      TangentScaleOptions options;
      options.objective = objective;
      options.length_weight = objective == Objective::kBendingEnergy ? 3.0 : 0.0;
      const PathSpec spec = testing::thesis_demo_path(which);
      std::vector<double> x = {0.25, 0.3, 0.2, 0.35, 0.28};  // frame 3 is a cusp: two sides
      const auto g = tangent_scale_gradient(spec, x, options);
      ASSERT_TRUE(g.has_value());
      double norm = 0.0;
      for (double v : g->gradient) norm = std::max(norm, std::abs(v));
      for (std::size_t i = 0; i < x.size(); ++i) {
        const double h = 1e-6 * x[i];
        auto xp = x, xm = x;
        xp[i] += h;
        xm[i] -= h;
        const double fd = (tangent_scale_gradient(spec, xp, options)->value -
                           tangent_scale_gradient(spec, xm, options)->value) / (2 * h);
        // Rounding of the central difference: ~1e-12 |f| / h (the value sums many terms).
        EXPECT_NEAR(g->gradient[i], fd, 1e-5 * norm + 1e-12 * std::abs(g->value) / h) << which << " " << objective_name(objective) << " scale " << i;
      }
    }
  }
}

TEST(TangentScales, ZeroBudgetReturnsTheFeasibleStartWithTimeLimit) {
  TangentScaleOptions options;
  options.budget_seconds = 0.0;
  const PathSpec spec = testing::thesis_demo_path('A');
  const auto r = optimize_tangent_scales(spec, options);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->report.status, OptimizerStatus::kTimeLimit);
  EXPECT_EQ(r->report.iterations, 0);
  EXPECT_EQ(r->scales, (std::vector<double>{0.25, 0.25, 0.25, 0.25, 0.25}));
  EXPECT_LT(closed_loop(r->spec), 1e-9);

  // A deadline in the past and a stop request end the same way.
  TangentScaleOptions past;
  past.deadline = std::chrono::steady_clock::now() - std::chrono::seconds(1);
  EXPECT_EQ(optimize_tangent_scales(spec, past)->report.status, OptimizerStatus::kTimeLimit);
  std::stop_source source;
  source.request_stop();
  TangentScaleOptions stopped;
  stopped.stop = source.get_token();
  EXPECT_EQ(optimize_tangent_scales(spec, stopped)->report.status, OptimizerStatus::kTimeLimit);
}

TEST(TangentScales, IterationLimitReturnsTheBestPointSoFar) {
  TangentScaleOptions options;
  options.max_iterations = 3;
  const PathSpec spec = testing::thesis_demo_path('A');
  const auto r = optimize_tangent_scales(spec, options);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->report.status, OptimizerStatus::kIterationLimit);
  EXPECT_LT(r->report.objective_after, r->report.objective_before);
  EXPECT_LT(closed_loop(r->spec), 1e-9);
}

TEST(TangentScales, BoundsHold) {
  TangentScaleOptions options;
  options.objective = Objective::kArcLength;  // pushes every scale to its lower bound
  options.min_scale = 0.1;
  options.max_scale = 0.4;
  const auto r = optimize_tangent_scales(testing::thesis_demo_path('A'), options);
  ASSERT_TRUE(r.has_value());
  for (double s : r->scales) {
    EXPECT_GE(s, 0.1);
    EXPECT_LE(s, 0.4);
  }
}

bool has_field(const core::Violations& v, const std::string& field) {
  return std::any_of(v.begin(), v.end(), [&](const core::FieldViolation& f) { return f.field == field; });
}

TEST(TangentScales, BadOptionsAreNamedErrors) {
  const PathSpec spec = testing::thesis_demo_path('A');
  TangentScaleOptions bad;
  bad.min_scale = 0.0;
  bad.max_scale = -1.0;
  bad.length_weight = -1.0;
  bad.budget_seconds = NAN;
  bad.max_iterations = 0;
  const auto r = optimize_tangent_scales(spec, bad);
  ASSERT_FALSE(r.has_value());
  for (const char* field : {"minScale", "maxScale", "lengthWeight", "budgetSeconds", "maxIterations"}) {
    EXPECT_TRUE(has_field(r.error(), std::string("optimize.tangentScales.") + field)) << field;
  }

  TangentScaleOptions inverted;
  inverted.min_scale = 0.5;
  inverted.max_scale = 0.2;
  const auto i = optimize_tangent_scales(spec, inverted);
  ASSERT_FALSE(i.has_value());
  EXPECT_TRUE(has_field(i.error(), "optimize.tangentScales.maxScale"));
}

TEST(TangentScales, InvalidPathsAreNamedErrors) {
  PathSpec spec = testing::thesis_demo_path('A');
  spec.frames[1].kappa = -1.0;
  spec.frames[3].leave_tangent_scale = 0.3;  // the last frame has no leaving side
  const auto r = optimize_tangent_scales(spec);
  ASSERT_FALSE(r.has_value());
  EXPECT_TRUE(has_field(r.error(), "path.frames[1].curvature"));
  EXPECT_TRUE(has_field(r.error(), "path.frames[3].leaveTangentScale"));

  const auto t = optimize_tangent_scales(testing::thesis_demo_path('A', core::BlendMethod::kTrapezoidal));
  ASSERT_FALSE(t.has_value());
  EXPECT_TRUE(has_field(t.error(), "path.blend"));
}

// The leaving side of a cusp takes its own scale in core's conversion.
TEST(TangentScales, CuspLeavingSideHasItsOwnScale) {
  PathSpec spec = testing::thesis_demo_path('C');
  spec.frames[2].leave_tangent_scale = 0.4;
  const auto path = core::build_path(spec);
  ASSERT_TRUE(path.has_value());
  EXPECT_NEAR(path->frames[2].approach.d[0].norm(), 0.25, 1e-15);
  EXPECT_NEAR(path->frames[2].leave.d[0].norm(), 0.4, 1e-15);
  const auto achieved = core::achieved_geometry(*path);
  EXPECT_NEAR(achieved[2].leave->speed, 0.4, 1e-12);
  EXPECT_NEAR(achieved[2].approach->speed, 0.25, 1e-12);
  EXPECT_LT(core::closed_loop_error(*path, achieved).max_error, 1e-9);

  spec.frames[2].leave_tangent_scale = -1.0;
  const auto bad = core::validate_path(spec);
  ASSERT_FALSE(bad.has_value());
  EXPECT_TRUE(has_field(bad.error(), "frames[2].leaveTangentScale"));
}

// The default length weight is E0 / L0 at the start: it keeps the optimised curve close to
// the request's length, where the energy alone buys its gentleness with length.
TEST(TangentScales, DefaultLengthWeightKeepsTheLengthInCheck) {
  for (Reading reading : kAllReadings) {
    for (char which : {'A', 'B', 'C'}) {
      SCOPED_TRACE(std::string("path ") + which + ", " + reading_name(reading));
      const PathSpec spec = testing::thesis_demo_path(which, core::BlendMethod::kPolynomial, reading);
      const double e0 = independent_objective(spec, Objective::kBendingEnergy, 0.0);
      const double l0 = core::build_path(spec)->length();
      const auto by_default = optimize_tangent_scales(spec);
      TangentScaleOptions energy_only;
      energy_only.length_weight = 0.0;
      const auto unweighted = optimize_tangent_scales(spec, energy_only);
      ASSERT_TRUE(by_default && unweighted);
      EXPECT_NEAR(by_default->length_weight, e0 / l0, 2e-3 * e0 / l0);
      EXPECT_EQ(unweighted->length_weight, 0.0);
      const double l_default = core::build_path(by_default->spec)->length();
      const double l_unweighted = core::build_path(unweighted->spec)->length();
      EXPECT_LT(l_default, l_unweighted);
      EXPECT_LT(l_default, 1.3 * l0);
      // Each is the better of the two by its own objective.
      EXPECT_LE(independent_objective(unweighted->spec, Objective::kBendingEnergy, 0.0),
                independent_objective(by_default->spec, Objective::kBendingEnergy, 0.0) * (1 + 2e-3));
      // Under the default reading the optimum is also gentler than the request: its peak
      // curvature is lower (not a property of the energy in general: path B under the thesis's
      // zeros rises from 123.7 to 126.1 1/m while its energy falls).
      if (reading == Reading::kSmoothest) {
        EXPECT_LT(independent_objective(by_default->spec, Objective::kPeakCurvature),
                  independent_objective(spec, Objective::kPeakCurvature));
      }
    }
  }
}

// The peak objectives keep the length within kPeakLengthGrowth of their start (the request,
// or the bending-energy optimum they start from).
TEST(TangentScales, PeakObjectivesKeepTheLengthInCheck) {
  for (Reading reading : kAllReadings) {
    for (char which : {'A', 'B', 'C'}) {
      const PathSpec spec = testing::thesis_demo_path(which, core::BlendMethod::kPolynomial, reading);
      const auto bending = optimize_tangent_scales(spec);
      ASSERT_TRUE(bending.has_value());
      const double start = std::max(core::build_path(spec)->length(), core::build_path(bending->spec)->length());
      for (Objective objective : {Objective::kPeakCurvature, Objective::kPeakTorsion}) {
        TangentScaleOptions options;
        options.objective = objective;
        const auto r = optimize_tangent_scales(spec, options);
        ASSERT_TRUE(r.has_value());
        EXPECT_LE(core::build_path(r->spec)->length(), kPeakLengthGrowth * start * (1 + 1e-3))
            << which << ", " << reading_name(reading) << ", " << objective_name(objective);
      }
    }
  }
}

// Under the smoothest reading the optimised curve is still G4 across frames where nothing
// breaks it (frame 2 of the demonstration; frame 3 is a cusp), now with optimised scales on
// both sides: kappa, tau, dkappa/ds and dtau/ds agree on both sides, measured on the curve.
TEST(TangentScales, SmoothestOptimumIsG4AtUnbrokenFrames) {
  for (char which : {'A', 'B', 'C'}) {
    for (Objective objective : kAllObjectives) {
      TangentScaleOptions options;
      options.objective = objective;
      const auto r = optimize_tangent_scales(
          testing::thesis_demo_path(which, core::BlendMethod::kPolynomial, Reading::kSmoothest), options);
      ASSERT_TRUE(r.has_value());
      const auto path = core::build_path(r->spec);
      ASSERT_TRUE(path.has_value());
      core::Jet arrive, leave;
      core::evaluate(path->segments[0], 1.0, 4, arrive);
      core::evaluate(path->segments[1], 0.0, 4, leave);
      const auto a = core::local_geometry(arrive);
      const auto b = core::local_geometry(leave);
      const auto close = [](double x, double y) { return std::abs(x - y) <= 1e-7 * std::max(1.0, std::abs(x)); };
      EXPECT_TRUE(close(a.kappa, b.kappa)) << which << " " << a.kappa << " " << b.kappa;
      EXPECT_TRUE(close(a.tau, b.tau)) << which << " " << a.tau << " " << b.tau;
      EXPECT_TRUE(close(a.kappa_ds, b.kappa_ds)) << which << " " << a.kappa_ds << " " << b.kappa_ds;
      EXPECT_TRUE(close(a.tau_ds, b.tau_ds)) << which << " " << a.tau_ds << " " << b.tau_ds;
      EXPECT_LT((a.T - b.T).norm(), 1e-12);
      EXPECT_LT((a.N - b.N).norm(), 1e-9);
    }
  }
}

// On the smoothest reading the derivatives are central differences of the global solve:
// they agree with a coarser independent difference of the objective.
TEST(TangentScales, SmoothestGradientMatchesDifferencesOfTheObjective) {
  const PathSpec spec = testing::thesis_demo_path('C', core::BlendMethod::kPolynomial, Reading::kSmoothest);
  TangentScaleOptions options;
  options.length_weight = 3.0;
  const std::vector<double> x = {0.25, 0.3, 0.2, 0.35, 0.28};
  const auto g = tangent_scale_gradient(spec, x, options);
  ASSERT_TRUE(g.has_value());
  const auto value = [&](const std::vector<double>& at) {
    PathSpec s = spec;
    s.frames[0].tangent_scale = at[0];
    s.frames[1].tangent_scale = at[1];
    s.frames[2].tangent_scale = at[2];
    s.frames[2].leave_tangent_scale = at[3];
    s.frames[3].tangent_scale = at[4];
    return *tangent_scale_objective(s, options);
  };
  EXPECT_NEAR(g->value, value(x), 1e-12 * g->value);
  double norm = 0.0;
  for (double v : g->gradient) norm = std::max(norm, std::abs(v));
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double h = 1e-4 * x[i];
    auto xp = x, xm = x;
    xp[i] += h;
    xm[i] -= h;
    const double fd = (value(xp) - value(xm)) / (2 * h);
    EXPECT_NEAR(g->gradient[i], fd, 1e-5 * norm) << "scale " << i;
  }
}

// Random frame sets: 3-5 frames of order 1 m apart, a random subset of the constraints,
// cusps and inflections where allowed, both conventions, open or closed. Fixed seed.
class RandomFrames {
 public:
  explicit RandomFrames(std::uint64_t seed) : rng_(seed) {}

  PathSpec next(Reading reading = Reading::kLowestDegree) {
    PathSpec spec;
    spec.unspecified = reading;
    const int count = uniform_int(3, 5);
    spec.closed = chance(0.25);
    spec.convention = chance(0.5) ? core::DerivativeConvention::kPerArcLength : core::DerivativeConvention::kPerParameter;
    Vector3d p(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    for (int i = 0; i < count; ++i) {
      const bool both_sides = spec.closed || (i > 0 && i + 1 < count);
      core::KeyFrame f;
      f.p_W = p;
      f.T_W = unit();
      f.N_W = f.T_W.cross(unit()).normalized();
      if (chance(0.7)) f.tangent_scale = uniform(0.3, 1.5);
      if (chance(0.7)) {
        f.kappa = std::exp(uniform(std::log(0.2), std::log(5.0)));
        if (chance(0.5)) f.tau = uniform(-5, 5);
        if (chance(0.3)) f.kappa_d = uniform(-5, 5);
        if (f.tau && chance(0.3)) f.tau_d = uniform(-10, 10);
        if (both_sides && chance(0.15)) f.inflection = true;
      }
      if (both_sides && chance(0.2)) f.cusp = true;
      spec.frames.push_back(f);
      p += uniform(0.4, 1.5) * unit();
    }
    return spec;
  }

 private:
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
  int uniform_int(int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng_); }
  bool chance(double p) { return uniform(0, 1) < p; }
  Vector3d unit() {
    std::normal_distribution<double> n;
    return Vector3d(n(rng_), n(rng_), n(rng_)).normalized();
  }
  std::mt19937_64 rng_;
};

int property_cases() {
  const char* env = std::getenv("GEOTRAJ_PROPERTY_CASES");
  return env ? std::max(1, std::atoi(env) / 50) : 20;
}

class TangentScalesProperty : public ::testing::TestWithParam<Reading> {};

TEST_P(TangentScalesProperty, RandomFrameSetsImproveAndStayMet) {
  for (Objective objective : kAllObjectives) {
    RandomFrames gen(20240611);
    const int cases = property_cases();
    int improved = 0;
    for (int c = 0; c < cases; ++c) {
      const PathSpec spec = gen.next(GetParam());
      ASSERT_TRUE(core::validate_path(spec).has_value()) << describe(spec);
      TangentScaleOptions options;
      options.objective = objective;
      const auto [before, after] = check_optimisation(spec, options);
      // The dense measure may exceed the sampled one by a little for the peaks.
      const double slack = objective == Objective::kPeakTorsion || objective == Objective::kPeakCurvature ? 1.02 : 1.0 + 1e-3;
      if (objective != Objective::kPeakTorsion) {
        EXPECT_LE(after, before * slack) << "case " << c << ", " << objective_name(objective) << "\n" << describe(spec);
      }
      if (after < 0.99 * before) ++improved;
    }
    // Random requests are rarely already optimal.
    EXPECT_GE(improved, cases * 3 / 4) << objective_name(objective);
  }
}

INSTANTIATE_TEST_SUITE_P(Readings, TangentScalesProperty, ::testing::ValuesIn(kAllReadings),
                         [](const ::testing::TestParamInfo<Reading>& param) {
                           std::string name = reading_name(param.param);
                           std::replace(name.begin(), name.end(), ' ', '_');
                           return name;
                         });

}  // namespace
}  // namespace geotraj::optim
