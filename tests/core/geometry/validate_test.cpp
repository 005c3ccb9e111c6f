// core::validate_path and the checks of build_path: every violation is reported, with the
// field path relative to the PathSpec and a message that names the value and the rule.
#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "core/geometry/path.hpp"
#include "core/geometry/validate.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::Violations;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A valid open path of three frames with curvature and torsion at the middle one.
core::PathSpec valid_spec() {
  return make_spec({
      Frame({0, 0, 0}, {1, 0, 0}),
      Frame({1, 1, 0}, {0, 1, 0}).normal({-1, 0, 0}).curvature(2).torsion(1),
      Frame({0, 2, 0}, {-1, 0, 0}),
  });
}

std::string listing(const Violations& v) {
  std::string s;
  for (const auto& fv : v) s += "\n  " + fv.field + ": " + fv.description;
  return s;
}

/// The violations of validate_path (none when it accepts the spec).
Violations violations_of(const core::PathSpec& spec) {
  const auto r = core::validate_path(spec);
  return r ? Violations{} : r.error();
}

/// Exactly one violation, on `field`, whose message contains every fragment.
::testing::AssertionResult OneViolation(const Violations& v, const std::string& field,
                                        std::initializer_list<const char*> fragments) {
  if (v.size() != 1) {
    return ::testing::AssertionFailure() << "expected one violation on " << field << ", got " << v.size() << ":"
                                         << listing(v);
  }
  if (v[0].field != field) return ::testing::AssertionFailure() << "expected field " << field << ", got" << listing(v);
  for (const char* f : fragments) {
    if (v[0].description.find(f) == std::string::npos) {
      return ::testing::AssertionFailure() << "message lacks \"" << f << "\":" << listing(v);
    }
  }
  return ::testing::AssertionSuccess();
}

bool has_field(const Violations& v, const std::string& field) {
  for (const auto& fv : v)
    if (fv.field == field) return true;
  return false;
}

TEST(Validate, ValidSpecPasses) {
  const auto r = core::validate_path(valid_spec());
  ASSERT_TRUE(r) << listing(r.error());
  EXPECT_FALSE(r->frames[1].B_W);  // a binormal is checked, then always T x N
}

// --- positions and tangents --------------------------------------------------------------

TEST(Validate, NonFinitePosition) {
  auto spec = valid_spec();
  spec.frames[2].p_W.y() = kNaN;
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[2].position", {"finite", "NaN"}));
}

TEST(Validate, NonFiniteTangent) {
  auto spec = valid_spec();
  spec.frames[0].T_W.x() = kInf;
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[0].tangent", {"finite", "Infinity"}));
}

TEST(Validate, TangentOfLengthHalfIsRejected) {
  auto spec = valid_spec();
  spec.frames[0].T_W = {0.5, 0, 0};
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[0].tangent", {"unit vector", "0.001", "length 0.5"}));
}

TEST(Validate, TangentOfLength0_9995IsNormalised) {
  auto spec = valid_spec();
  spec.frames[0].T_W = {0.9995, 0, 0};
  spec.frames[1].T_W = Vector3d(0, 0.9995, 0);
  const auto r = core::validate_path(spec);
  ASSERT_TRUE(r) << listing(r.error());
  EXPECT_TRUE(VecNear(r->frames[0].T_W, Vector3d(1, 0, 0), 1e-15));
  EXPECT_TRUE(VecNear(r->frames[1].T_W, Vector3d(0, 1, 0), 1e-15));
}

// --- normal and binormal -----------------------------------------------------------------

TEST(Validate, NormalNotPerpendicularIsRejected) {
  auto spec = valid_spec();
  spec.frames[1].N_W = Vector3d(-1, 0.002, 0).normalized();  // T . N = 0.002 > 1e-3
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].normal", {"perpendicular", "0.002"}));
}

TEST(Validate, NormalSlightlyOffIsMadeExact) {
  auto spec = valid_spec();
  spec.frames[1].N_W = Vector3d(-1, 5e-4, 0.0003);  // T . N = 5e-4, |N| = 1.0000002
  const auto r = core::validate_path(spec);
  ASSERT_TRUE(r) << listing(r.error());
  const auto& f = r->frames[1];
  EXPECT_NEAR(f.T_W.dot(*f.N_W), 0.0, 1e-16);
  EXPECT_NEAR(f.N_W->norm(), 1.0, 1e-15);
  EXPECT_NEAR(f.N_W->x(), -1.0, 1e-6);
}

TEST(Validate, NormalOfWrongLengthIsRejected) {
  auto spec = valid_spec();
  spec.frames[1].N_W = Vector3d(-2, 0, 0);
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].normal", {"unit vector", "length 2"}));
}

TEST(Validate, BinormalInconsistentWithTangentCrossNormal) {
  auto spec = valid_spec();
  spec.frames[1].B_W = Vector3d(0, 0, -1);  // T x N = (0, 1, 0) x (-1, 0, 0) = (0, 0, 1)
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].binormal", {"tangent x normal = (0, ", ", 1)", "got (0, 0, -1)"}));
}

// Regression: validate.cpp's fmt prints IEEE negative zero as "-0", so the message
// above reads "must equal tangent x normal = (0, -0, 1)" (0 * -1 - 0 * 0 = -0). Fixed by: format
// `v + 0.0` (which turns -0 into +0) in fmt(double). 
TEST(Validate, MessagesDoNotPrintNegativeZero) {
  auto spec = valid_spec();
  spec.frames[1].B_W = Vector3d(0, 0, -1);
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].binormal", {"tangent x normal = (0, 0, 1)"}));
}

TEST(Validate, BinormalConsistentIsAccepted) {
  auto spec = valid_spec();
  spec.frames[1].B_W = Vector3d(0, 0.0004, 1);  // within 1e-3 of T x N
  EXPECT_TRUE(violations_of(spec).empty()) << listing(violations_of(spec));
}

TEST(Validate, BinormalWithoutNormal) {
  auto spec = valid_spec();
  spec.frames[0].B_W = Vector3d(0, 0, 1);
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[0].binormal", {"needs a normal"}));
}

// --- curvature, torsion and their derivatives ---------------------------------------------

TEST(Validate, NegativeCurvature) {
  auto spec = valid_spec();
  spec.frames[1].kappa = -2.0;
  spec.frames[1].tau.reset();
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].curvature", {">= 0", "-2"}));
}

TEST(Validate, NormalMissingWhereCurvaturePositive) {
  auto spec = valid_spec();
  spec.frames[1].N_W.reset();
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].normal", {"required", "curvature > 0"}));
}

TEST(Validate, NormalNotNeededWhereCurvatureZero) {
  auto spec = valid_spec();
  spec.frames[0].kappa = 0.0;
  EXPECT_TRUE(violations_of(spec).empty()) << listing(violations_of(spec));
}

struct NeedsCurvatureCase {
  const char* field;
  void (*give)(core::KeyFrame&);
};

const NeedsCurvatureCase kNeedsCurvature[] = {
    {"torsion", [](core::KeyFrame& f) { f.tau = 1.0; }},
    {"curvatureDerivative", [](core::KeyFrame& f) { f.kappa_d = 1.0; }},
    {"torsionDerivative", [](core::KeyFrame& f) { f.tau = 0.0, f.tau_d = 1.0; }},
};

TEST(Validate, TorsionAndDerivativesWithCurvatureZero) {
  for (const auto& c : kNeedsCurvature) {
    SCOPED_TRACE(c.field);
    auto spec = valid_spec();
    spec.frames[0].kappa = 0.0;
    c.give(spec.frames[0]);
    const auto v = violations_of(spec);
    ASSERT_TRUE(has_field(v, std::string("frames[0].") + c.field)) << listing(v);
    for (const auto& fv : v) EXPECT_NE(fv.description.find("undefined where curvature is 0"), std::string::npos);
  }
}

TEST(Validate, TorsionAndDerivativesWithCurvatureAbsent) {
  for (const auto& c : kNeedsCurvature) {
    SCOPED_TRACE(c.field);
    auto spec = valid_spec();
    c.give(spec.frames[2]);
    const auto v = violations_of(spec);
    ASSERT_TRUE(has_field(v, std::string("frames[2].") + c.field)) << listing(v);
    for (const auto& fv : v) EXPECT_NE(fv.description.find("curvature is not given"), std::string::npos);
  }
}

TEST(Validate, TorsionDerivativeWithoutTorsion) {
  auto spec = valid_spec();
  spec.frames[1].tau.reset();
  spec.frames[1].tau_d = 3.0;
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].torsionDerivative", {"needs the torsion"}));
}

TEST(Validate, NonFiniteCurvatureAndTorsion) {
  auto spec = valid_spec();
  spec.frames[1].tau = kNaN;
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].torsion", {"finite number"}));
  spec = valid_spec();
  spec.frames[1].kappa = kInf;
  spec.frames[1].tau.reset();
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].curvature", {"finite number"}));
}

// --- tangent scale -------------------------------------------------------------------------

TEST(Validate, TangentScaleMustBePositive) {
  for (const double bad : {0.0, -1.5}) {
    auto spec = valid_spec();
    spec.frames[1].tangent_scale = bad;
    EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].tangentScale", {"> 0"})) << bad;
  }
}

TEST(Validate, TangentScaleNaN) {
  auto spec = valid_spec();
  spec.frames[0].tangent_scale = kNaN;
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[0].tangentScale", {"finite"}));
}

// --- cusps and inflections ----------------------------------------------------------------

TEST(Validate, CuspAtEndsOfOpenPath) {
  auto spec = valid_spec();
  spec.frames[0].cusp = true;
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[0].cusp", {"first frame"}));
  spec = valid_spec();
  spec.frames[2].cusp = true;
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[2].cusp", {"last frame"}));
}

TEST(Validate, InflectionAtEndsOfOpenPath) {
  auto spec = valid_spec();
  spec.frames[0].inflection = true;
  spec.frames[0].kappa = 1.0;
  spec.frames[0].N_W = Vector3d(0, 1, 0);
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[0].inflection", {"first frame"}));
  spec = valid_spec();
  spec.frames[2].inflection = true;
  spec.frames[2].kappa = 1.0;
  spec.frames[2].N_W = Vector3d(0, 1, 0);
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[2].inflection", {"last frame"}));
}

TEST(Validate, CuspAndInflectionAtEndsOfClosedPath) {
  auto spec = valid_spec();
  spec.closed = true;
  spec.frames[0].cusp = true;
  spec.frames[2].kappa = 1.0;
  spec.frames[2].N_W = Vector3d(0, 1, 0);
  spec.frames[2].inflection = true;
  EXPECT_TRUE(violations_of(spec).empty()) << listing(violations_of(spec));
}

TEST(Validate, InflectionNeedsCurvature) {
  auto spec = valid_spec();
  spec.frames[1].inflection = true;
  spec.frames[1].kappa.reset();
  spec.frames[1].tau.reset();
  EXPECT_TRUE(OneViolation(violations_of(spec), "frames[1].inflection", {"curvature"}));
}

// --- frame count ---------------------------------------------------------------------------

TEST(Validate, FewerThanTwoFrames) {
  for (std::size_t n : {0u, 1u}) {
    auto spec = valid_spec();
    spec.frames.resize(n);
    EXPECT_TRUE(OneViolation(violations_of(spec), "frames", {"at least 2", ("got " + std::to_string(n)).c_str()}));
  }
}

TEST(Validate, TooManyFrames) {
  const auto r = core::validate_path(valid_spec(), {}, core::PathLimits{2});
  ASSERT_FALSE(r);
  EXPECT_TRUE(OneViolation(r.error(), "frames", {"at most 2", "got 3"}));
}

// --- trapezoid breakpoints ----------------------------------------------------------------

core::PathSpec trapezoid_spec(core::SegmentBreakpoints bp) {
  auto spec = valid_spec();
  spec.blend = core::BlendMethod::kTrapezoidal;
  spec.breakpoints = {std::move(bp)};
  return spec;
}

core::SegmentBreakpoints breakpoints_all(std::uint32_t segment, std::vector<double> all) {
  core::SegmentBreakpoints bp;
  bp.segment = segment;
  bp.all = std::move(all);
  return bp;
}

TEST(Validate, BreakpointsWithPolynomialBlend) {
  auto spec = trapezoid_spec(breakpoints_all(0, {0, 0.25, 0.5, 0.75, 0.9, 1}));
  spec.blend = core::BlendMethod::kPolynomial;
  EXPECT_TRUE(OneViolation(violations_of(spec), "breakpoints", {"TRAPEZOIDAL", "POLYNOMIAL"}));
}

TEST(Validate, BreakpointOutsideUnitInterval) {
  const auto v = violations_of(trapezoid_spec(breakpoints_all(0, {0, 0.2, 0.4, 0.6, 0.8, 1.2})));
  EXPECT_TRUE(OneViolation(v, "breakpoints[0].all", {"breakpoint 5", "1.2", "[0, 1]"}));
  const auto nan = violations_of(trapezoid_spec(breakpoints_all(0, {kNaN, 0.2, 0.4, 0.6, 0.8, 1})));
  EXPECT_TRUE(OneViolation(nan, "breakpoints[0].all", {"breakpoint 0", "[0, 1]"}));
}

TEST(Validate, DecreasingBreakpoints) {
  core::SegmentBreakpoints bp;
  bp.segment = 1;
  bp.x = {0, 0.2, 0.5, 0.4, 0.8, 1};
  EXPECT_TRUE(OneViolation(violations_of(trapezoid_spec(bp)), "breakpoints[0].x", {"must not decrease", "0.4 < 0.5"}));
}

TEST(Validate, FirstRampNeedsWidth) {
  core::SegmentBreakpoints bp;
  bp.segment = 0;
  bp.z = {0.1, 0.1, 0.5, 0.6, 0.8, 1};
  EXPECT_TRUE(OneViolation(violations_of(trapezoid_spec(bp)), "breakpoints[0].z", {"u_1 > u_0"}));
}

TEST(Validate, UnknownSegment) {
  EXPECT_TRUE(OneViolation(violations_of(trapezoid_spec(breakpoints_all(2, {0, 0.2, 0.4, 0.6, 0.8, 1}))),
                           "breakpoints[0].segment", {"segment 2", "2 segments"}));
}

TEST(Validate, SegmentGivenTwice) {
  auto spec = trapezoid_spec(breakpoints_all(1, {0, 0.2, 0.4, 0.6, 0.8, 1}));
  spec.breakpoints.push_back(breakpoints_all(1, {0, 0.2, 0.4, 0.6, 0.8, 1}));
  EXPECT_TRUE(OneViolation(violations_of(spec), "breakpoints[1].segment", {"twice"}));
}

TEST(Validate, BreakpointEntryWithoutLists) {
  EXPECT_TRUE(OneViolation(violations_of(trapezoid_spec(breakpoints_all(0, {}))), "breakpoints[0]", {"no breakpoints"}));
}

// The count depends on the orders that the frames fix, so build_path checks it: segment 0
// runs from a tangent-only frame (order 1) to a frame with torsion (order 3), so it blends
// with an order-4 trapezoid, which needs 10 breakpoints.
TEST(BuildPath, WrongBreakpointCountForTrapezoidOrder) {
  const auto r = core::build_path(trapezoid_spec(breakpoints_all(0, {0, 0.2, 0.4, 0.6, 0.8, 1})));
  ASSERT_FALSE(r);
  ASSERT_GE(r.error().size(), 1u);
  for (const auto& fv : r.error()) {
    EXPECT_EQ(fv.field, "breakpoints[0].all");
    EXPECT_NE(fv.description.find("order-4"), std::string::npos) << fv.description;
    EXPECT_NE(fv.description.find("needs 10 breakpoints; got 6"), std::string::npos) << fv.description;
  }
}

// Regression: make_segment checks the count per axis, and the three axes that fall
// back to the same `all` list report the same violation three times. Fixed by: in make_segment,
// skip a violation whose field was already reported for this segment (or check each given
// list once before the axis loop). 
TEST(BuildPath, WrongBreakpointCountReportedOncePerField) {
  const auto r = core::build_path(trapezoid_spec(breakpoints_all(0, {0, 0.2, 0.4, 0.6, 0.8, 1})));
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().size(), 1u) << listing(r.error());
}

TEST(BuildPath, PerAxisBreakpointCount) {
  core::SegmentBreakpoints bp;
  bp.segment = 1;  // order 3 -> order 1: a 4th-order trapezoid, 10 breakpoints
  bp.all = {0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 1};
  bp.y = {0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 1};
  const auto r = core::build_path(trapezoid_spec(bp));
  ASSERT_FALSE(r);
  EXPECT_TRUE(OneViolation(r.error(), "breakpoints[0].y", {"needs 10 breakpoints; got 8"}));
}

TEST(BuildPath, ValidBreakpointsAreUsed) {
  core::SegmentBreakpoints bp = breakpoints_all(0, {0, 0.02, 0.24, 0.26, 0.49, 0.51, 0.74, 0.76, 0.98, 1.0});  // (B.11)
  const auto r = core::build_path(trapezoid_spec(bp));
  ASSERT_TRUE(r) << listing(r.error());
  const auto& axis = std::get<core::TrapezoidSegment>(r->segments[0]).axes[0];
  EXPECT_EQ(axis.n, 4);
  EXPECT_EQ(axis.u[2], 0.24);
}

// --- everything at once --------------------------------------------------------------------

TEST(Validate, SeveralViolationsReportedTogether) {
  auto spec = valid_spec();
  spec.blend = core::BlendMethod::kTrapezoidal;
  spec.frames[0].T_W = {0.5, 0, 0};
  spec.frames[0].cusp = true;
  spec.frames[1].kappa = -1.0;
  spec.frames[1].tangent_scale = 0.0;
  spec.frames[2].tau = 2.0;
  spec.breakpoints = {breakpoints_all(7, {0, 1})};
  const auto v = violations_of(spec);
  for (const char* field : {"frames[0].tangent", "frames[0].cusp", "frames[1].curvature", "frames[1].tangentScale",
                            "frames[2].torsion", "breakpoints[0].segment"}) {
    EXPECT_TRUE(has_field(v, field)) << field << " missing from" << listing(v);
  }
  EXPECT_EQ(v.size(), 6u) << listing(v);
}

TEST(BuildPath, ReturnsValidationViolations) {
  auto spec = valid_spec();
  spec.frames[1].N_W.reset();
  spec.frames[2].tangent_scale = -1.0;
  const auto r = core::build_path(spec);
  ASSERT_FALSE(r);
  EXPECT_TRUE(has_field(r.error(), "frames[1].normal"));
  EXPECT_TRUE(has_field(r.error(), "frames[2].tangentScale"));
}

TEST(BuildPath, ConvertPathReturnsViolations) {
  auto spec = valid_spec();
  spec.frames[1].kappa = 0.0;
  const auto r = core::convert_path(spec);
  ASSERT_FALSE(r);
  EXPECT_TRUE(OneViolation(r.error(), "frames[1].torsion", {"curvature is 0"}));
}

TEST(Validate, PrefixedViolations) {
  auto spec = valid_spec();
  spec.frames[1].N_W.reset();
  const auto v = core::prefixed(violations_of(spec), "path.");
  EXPECT_TRUE(OneViolation(v, "path.frames[1].normal", {"required"}));
}

}  // namespace
}  // namespace geotraj::test
