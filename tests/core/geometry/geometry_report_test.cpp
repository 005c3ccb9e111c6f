// The geometry between frames (geometry_report): its extremes agree with a dense profile of
// the curve, and its warnings fire on the kinks, tight bends and loops that an operator did
// not ask for, and only there.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/geometry/analysis.hpp"
#include "core/geometry/arc_length.hpp"
#include "core/geometry/geometry_report.hpp"
#include "core/geometry/path.hpp"
#include "test_support.hpp"
#include "thesis_paths.hpp"

namespace geotraj {
namespace {

using core::PathWarningCode;
using core::UnspecifiedConstraints;
using Eigen::Vector3d;
using test::Frame;

// The README's minimal example; `scale` for the middle frame (0: the chord default).
core::PathSpec readme_example(double scale, UnspecifiedConstraints reading) {
  core::PathSpec spec = test::make_spec({Frame({0, 0, 0}, {1, 0, 0}).scale(0.5),
                                         Frame({0.3, 0.2, 0.1}, {0, 1, 0}).normal({-1, 0, 0}).curvature(5).torsion(2),
                                         Frame({0.1, 0.5, 0.1}, {-1, 0, 0}).scale(0.5)},
                                        core::DerivativeConvention::kPerArcLength, core::BlendMethod::kPolynomial,
                                        false, reading);
  spec.frames[1].tangent_scale = scale > 0.0 ? std::optional<double>(scale) : std::nullopt;
  return spec;
}

bool has_warning(const core::GeometryReport& r, PathWarningCode code, std::size_t segment) {
  return std::any_of(r.warnings.begin(), r.warnings.end(),
                     [&](const core::PathWarning& w) { return w.code == code && w.segment == segment; });
}

// Each segment's extremes against 20,001 points per segment of AnalyzePath's profile: the
// reported value is at least the densest sample's (refined between samples, never below)
// and within 1e-6 of it; s is the arc length at the reported u.
TEST(GeometryReport, ExtremesMatchADenseProfile) {
  for (auto reading : {UnspecifiedConstraints::kSmoothest, UnspecifiedConstraints::kThesisZeros,
                       UnspecifiedConstraints::kLowestDegree}) {
    for (char which : {'A', 'B', 'C'}) {
      SCOPED_TRACE(std::string("path ") + which + ", reading " + std::to_string(static_cast<int>(reading)));
      const auto path = test::build_or_fail(testing::thesis_demo_path(which, core::BlendMethod::kPolynomial, reading));
      const auto report = core::geometry_report(path);
      ASSERT_EQ(report.segments.size(), path.segment_count());
      const auto profile = core::analyze(path, 20000 * path.segment_count() + 1);
      for (std::size_t i = 0; i < path.segment_count(); ++i) {
        double kappa = 0.0, speed = HUGE_VAL;
        for (const auto& p : profile) {
          if (p.u < static_cast<double>(i) || p.u > static_cast<double>(i + 1)) continue;
          kappa = std::max(kappa, p.geometry.kappa);
          speed = std::min(speed, p.geometry.speed);
        }
        const auto& g = report.segments[i];
        EXPECT_GE(g.peak_curvature.value, kappa * (1 - 1e-12)) << "segment " << i;
        EXPECT_NEAR(g.peak_curvature.value, kappa, 1e-6 * kappa) << "segment " << i;
        EXPECT_LE(g.min_speed.value, speed * (1 + 1e-12)) << "segment " << i;
        EXPECT_NEAR(g.min_speed.value, speed, 1e-6 * speed) << "segment " << i;
        EXPECT_NEAR(g.peak_curvature.s, core::arc_length_at(path, g.peak_curvature.u), 1e-6);
        EXPECT_NEAR(g.min_speed.s, core::arc_length_at(path, g.min_speed.u), 1e-6);
        EXPECT_GE(g.peak_curvature.u, static_cast<double>(i));
        EXPECT_LE(g.peak_curvature.u, static_cast<double>(i + 1));
        // The turning is at least the angle between the end tangents.
        EXPECT_GT(g.turning, 0.0);
      }
      // The demonstration is what its operator asked for under the default and the thesis's
      // readings: no warnings. Lowest-degree segments curl path C's first segment (curvature
      // 233 1/m at the start frame, the tangent turning 4.8 rad against the 1.6 rad its ends
      // need): reported.
      if (reading == UnspecifiedConstraints::kLowestDegree && which == 'C') {
        ASSERT_EQ(report.warnings.size(), 1u);
        EXPECT_EQ(report.warnings[0].code, PathWarningCode::kTurnsBack);
        EXPECT_EQ(report.warnings[0].segment, 0u);
      } else {
        EXPECT_TRUE(report.warnings.empty()) << report.warnings.front().message;
      }
    }
  }
}

// The README's example with the old default scale of 1 m at its middle frame doubles back
// with a tiny radius (|dp/du| 0.0085 m, curvature ~64,500 1/m): reported as a near-cusp at
// that point; with the chord-length default it is gentle and nothing is reported.
TEST(GeometryReport, NearCuspOfTheReadmeExampleWithUnitScale) {
  const auto kinked = test::build_or_fail(readme_example(1.0, UnspecifiedConstraints::kLowestDegree));
  const auto report = core::geometry_report(kinked);
  ASSERT_TRUE(has_warning(report, PathWarningCode::kNearCusp, 1));
  const auto& w = *std::find_if(report.warnings.begin(), report.warnings.end(),
                                [](const auto& x) { return x.code == PathWarningCode::kNearCusp; });
  EXPECT_LT(w.value, core::kNearCuspFraction * kinked.segment_lengths[1]);
  // Below the 0.0085 m and above the 64,534 1/m that sampling at points found: the extremes
  // are refined between samples.
  EXPECT_LT(w.value, 0.0085);
  EXPECT_GT(w.value, 0.0);
  EXPECT_GT(report.segments[1].peak_curvature.value, 64534.0);
  EXPECT_NE(w.message.find("segment 1"), std::string::npos) << w.message;
  EXPECT_NE(w.message.find("tangent scales"), std::string::npos) << w.message;

  for (auto reading : {UnspecifiedConstraints::kSmoothest, UnspecifiedConstraints::kThesisZeros,
                       UnspecifiedConstraints::kLowestDegree}) {
    const auto gentle = test::build_or_fail(readme_example(0.0, reading));
    const auto r = core::geometry_report(gentle);
    EXPECT_TRUE(r.warnings.empty()) << r.warnings.front().message;
    for (const auto& g : r.segments) EXPECT_LT(g.peak_curvature.value, 20.0);
  }
}

// maxCurvature: a bend above it is reported with its peak, a limit above every bend is quiet.
TEST(GeometryReport, TightBendAgainstMaxCurvature) {
  auto spec = testing::thesis_demo_path('C', core::BlendMethod::kPolynomial, UnspecifiedConstraints::kSmoothest);
  const auto plain = core::geometry_report(test::build_or_fail(spec));
  double peak = 0.0;
  std::size_t worst = 0;
  for (std::size_t i = 0; i < plain.segments.size(); ++i) {
    if (plain.segments[i].peak_curvature.value > peak) peak = plain.segments[i].peak_curvature.value, worst = i;
  }
  spec.max_curvature = 0.9 * peak;
  const auto tight = core::geometry_report(test::build_or_fail(spec));
  ASSERT_TRUE(has_warning(tight, PathWarningCode::kTightBend, worst));
  for (const auto& w : tight.warnings) {
    ASSERT_EQ(w.code, PathWarningCode::kTightBend);
    EXPECT_GT(w.value, 0.9 * peak);
    EXPECT_NE(w.message.find("maxCurvature"), std::string::npos);
  }
  spec.max_curvature = 1.01 * peak;
  EXPECT_TRUE(core::geometry_report(test::build_or_fail(spec)).warnings.empty());

  for (double bad : {0.0, -1.0, std::nan(""), HUGE_VAL}) {
    spec.max_curvature = bad;
    const auto refused = core::build_path(spec);
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.error()[0].field, "maxCurvature");
  }
}

// A segment whose end tangents both point back along it must loop: it turns back on itself.
TEST(GeometryReport, TurnsBackOnALoop) {
  const auto path = test::build_or_fail(
      test::make_spec({Frame({0, 0, 0}, {-1, 0, 0}).scale(1.0), Frame({0.1, 0.02, 0}, {-1, 0, 0}).scale(1.0)}));
  const auto report = core::geometry_report(path);
  ASSERT_TRUE(has_warning(report, PathWarningCode::kTurnsBack, 0));
  EXPECT_GT(report.segments[0].turning, 3.14159265358979);
  // A gentle quarter turn is not a loop.
  const auto bend = test::build_or_fail(
      test::make_spec({Frame({0, 0, 0}, {1, 0, 0}).scale(0.1), Frame({0.1, 0.1, 0}, {0, 1, 0}).scale(0.1)}));
  const auto quiet = core::geometry_report(bend);
  EXPECT_TRUE(quiet.warnings.empty());
  EXPECT_NEAR(quiet.segments[0].turning, 3.14159265358979 / 2, 1e-3);
}

// A long path samples only 16 points per segment and still finds every kink:
// 1 m tangent scales on 1 cm chords make each segment double back.
TEST(GeometryReport, LongPathWithKinksInEverySegment) {
  std::vector<core::KeyFrame> frames;
  for (int i = 0; i < 2000; ++i) frames.push_back(Frame({0.01 * i, 0.002 * (i % 2), 0}, {1, 0, 0}).scale(1.0));
  const auto path = test::build_or_fail(test::make_spec(frames));
  const auto report = core::geometry_report(path);
  ASSERT_EQ(report.segments.size(), 1999u);
  for (std::size_t i = 0; i < report.segments.size(); ++i) {
    ASSERT_TRUE(has_warning(report, PathWarningCode::kNearCusp, i)) << "segment " << i;
  }
  // With the chord default the same frames are gentle.
  for (auto& f : frames) f.tangent_scale.reset();
  core::PathSpec gentle;
  gentle.frames = frames;
  EXPECT_TRUE(core::geometry_report(test::build_or_fail(gentle)).warnings.empty());
}

}  // namespace
}  // namespace geotraj
