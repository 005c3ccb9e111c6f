// Golden: thesis Section 7.2, the PA-10 demonstration, Tables 7.9-7.16, 7.19 and 7.20.
// Key frames of Table 7.8 (frame 1's binormal with the thesis-notes erratum: printed
// (0, -1, 0), it is T x N = (0, 0, -1)); frame 3 is the tray pick-up with a cusp. One test
// per printed row; tolerance = half a unit of the last printed digit. See golden_support.hpp
// for the cusp convention: Tables 7.11, 7.14 and 7.20 print the approaching side of frame 3
// (dp/du = +0.25 T); the leaving side is checked against geotraj's convention.
#include <gtest/gtest.h>

#include "golden_support.hpp"

namespace geotraj::test {
namespace {

/// Table 7.8, every frame with the same tangent scale and no constraint above the tangent.
core::PathSpec table7_8(double scale) {
  return make_spec({
      Frame({0.106, 0.0, 0.975}, {1, 0, 0}).normal({0, -1, 0}).binormal({0, 0, -1}).scale(scale),  // erratum B
      Frame({0.4, 0.15, 0.5}, {0, -1, 0}).normal({0, 0, -1}).binormal({1, 0, 0}).scale(scale),
      Frame({0.5, -0.3, 0.525}, {1, 0, 0}).normal({0, 1, 0}).binormal({0, 0, 1}).scale(scale).cusp(),
      Frame({0.2, -0.5, 0.6}, {0, -1, 0}).normal({0, 0, -1}).binormal({1, 0, 0}).scale(scale),
  });
}

constexpr double kDemoScale = 0.25;  // "For the rest of this demonstration, a tangent scale of 0.25 is used"

/// The converted frame `index` of Table 7.8 with scale 0.25 after `edit` sets its constraints.
template <class Edit>
core::FrameConstraints demo_frame(std::size_t index, Edit edit) {
  core::PathSpec spec = table7_8(kDemoScale);
  edit(spec.frames[index]);
  return convert_or_fail(spec)[index];
}

/// The leaving side of a cusp: dp/du and d3p/du3 change sign, d2p/du2 (along N) does not,
/// since its frame is (-T, N, -B) and it meets the same kappa and tau along increasing u.
void ExpectCuspMirror(const core::FrameConstraints& f) {
  ASSERT_EQ(f.leave.order, f.approach.order);
  EXPECT_TRUE(VecNear(f.leave.d[0], -f.approach.d[0], 0.0));
  if (f.approach.order >= 2) {
    EXPECT_TRUE(VecNear(f.leave.d[1], f.approach.d[1], 1e-15));
  }
  if (f.approach.order >= 3) {
    EXPECT_TRUE(VecNear(f.leave.d[2], -f.approach.d[2], 1e-12));
  }
}

// ---------------------------------------------------------------------------------------
// Table 7.9: only the tangent scale varies; "the higher-order parametric constraints all
// being set to zero", i.e. kappa = 0 given at every frame (d2p/du2 = 0, the rest free).

void ExpectTangentScaleRow(double scale, const std::array<PrintedVec, 4>& dp) {
  core::PathSpec spec = table7_8(scale);
  for (auto& f : spec.frames) f.kappa = 0.0;
  const auto frames = convert_or_fail(spec);
  const PrintedVec positions[] = {{"0.106", "0.0", "0.975"}, {"0.4", "0.15", "0.5"}, {"0.5", "-0.3", "0.525"},
                                  {"0.2", "-0.5", "0.6"}};
  for (std::size_t i = 0; i < 4; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i + 1));
    ExpectPosition(frames[i], positions[i]);
    ExpectSide(frames[i].approach, 2, {dp[i], {"0.0", "0.0", "0.0"}});
  }
  ExpectSide(frames[0].leave, 2, {dp[0]});
  ExpectSide(frames[1].leave, 2, {dp[1]});
  ExpectCuspMirror(frames[2]);
}

TEST(Chapter7, Table7_9_PathA) {
  ExpectTangentScaleRow(0.25, {{{"0.25", "0.0", "0.0"}, {"0.0", "-0.25", "0.0"}, {"0.25", "0.0", "0.0"},
                                {"0.0", "-0.25", "0.0"}}});
}
TEST(Chapter7, Table7_9_PathB) {
  ExpectTangentScaleRow(0.50, {{{"0.50", "0.0", "0.0"}, {"0.0", "-0.50", "0.0"}, {"0.50", "0.0", "0.0"},
                                {"0.0", "-0.50", "0.0"}}});
}
TEST(Chapter7, Table7_9_PathC) {
  ExpectTangentScaleRow(0.75, {{{"0.75", "0.0", "0.0"}, {"0.0", "-0.75", "0.0"}, {"0.75", "0.0", "0.0"},
                                {"0.0", "-0.75", "0.0"}}});
}

// ---------------------------------------------------------------------------------------
// Table 7.10: curvature at frame 2 (the sphere; N points into it).

void ExpectFrame2Curvature(double kappa, const PrintedVec& d2) {
  const auto f = demo_frame(1, [&](core::KeyFrame& k) { k.kappa = kappa; });
  for (const auto* side : {&f.approach, &f.leave}) ExpectSide(*side, 2, {{"0.0", "-0.25", "0.0"}, d2});
}

TEST(Chapter7, Table7_10_PathA) { ExpectFrame2Curvature(1.0, {"0.0", "0.0", "-0.0625"}); }
TEST(Chapter7, Table7_10_PathB) { ExpectFrame2Curvature(10.0, {"0.0", "0.0", "-0.625"}); }
TEST(Chapter7, Table7_10_PathC) { ExpectFrame2Curvature(20.0, {"0.0", "0.0", "-1.25"}); }

// ---------------------------------------------------------------------------------------
// Table 7.11: curvature at the cusp, frame 3 (the thesis's text says "frame 2").

void ExpectFrame3Curvature(double kappa, const PrintedVec& d2) {
  const auto f = demo_frame(2, [&](core::KeyFrame& k) { k.kappa = kappa; });
  ExpectSide(f.approach, 2, {{"0.25", "0.0", "0.0"}, d2});
  ExpectCuspMirror(f);
}

TEST(Chapter7, Table7_11_PathA) { ExpectFrame3Curvature(1.0, {"0.0", "0.0625", "0.0"}); }
TEST(Chapter7, Table7_11_PathB) { ExpectFrame3Curvature(10.0, {"0.0", "0.625", "0.0"}); }
TEST(Chapter7, Table7_11_PathC) { ExpectFrame3Curvature(20.0, {"0.0", "1.25", "0.0"}); }

// ---------------------------------------------------------------------------------------
// Tables 7.12 and 7.13: torsion at frame 2, kappa = 20 and kappa = 5.

void ExpectFrame2Torsion(double kappa, double tau, const PrintedVec& d2, const PrintedVec& d3) {
  const auto f = demo_frame(1, [&](core::KeyFrame& k) {
    k.kappa = kappa;
    k.tau = tau;
  });
  for (const auto* side : {&f.approach, &f.leave}) ExpectSide(*side, 3, {{"0.0", "-0.25", "0.0"}, d2, d3});
}

TEST(Chapter7, Table7_12_PathA) { ExpectFrame2Torsion(20, 50, {"0.0", "0.0", "-1.25"}, {"15.625", "0.0", "0.0"}); }
TEST(Chapter7, Table7_12_PathB) { ExpectFrame2Torsion(20, 100, {"0.0", "0.0", "-1.25"}, {"31.25", "0.0", "0.0"}); }
TEST(Chapter7, Table7_12_PathC) { ExpectFrame2Torsion(20, -50, {"0.0", "0.0", "-1.25"}, {"-15.625", "0.0", "0.0"}); }
TEST(Chapter7, Table7_12_PathD) { ExpectFrame2Torsion(20, -100, {"0.0", "0.0", "-1.25"}, {"-31.25", "0.0", "0.0"}); }

TEST(Chapter7, Table7_13_PathA) { ExpectFrame2Torsion(5, 50, {"0.0", "0.0", "-.3125"}, {"3.9063", "0.0", "0.0"}); }
TEST(Chapter7, Table7_13_PathB) { ExpectFrame2Torsion(5, 100, {"0.0", "0.0", "-.3125"}, {"7.8125", "0.0", "0.0"}); }
TEST(Chapter7, Table7_13_PathC) { ExpectFrame2Torsion(5, -50, {"0.0", "0.0", "-.3125"}, {"-3.9063", "0.0", "0.0"}); }
TEST(Chapter7, Table7_13_PathD) { ExpectFrame2Torsion(5, -100, {"0.0", "0.0", "-.3125"}, {"-7.8125", "0.0", "0.0"}); }

// ---------------------------------------------------------------------------------------
// Table 7.14: torsion at the cusp, frame 3, kappa = 20. The thesis prints one side, the
// approaching one. geotraj's leaving side has d3p/du3 of the opposite sign (its binormal is
// -B), so that the leaving branch also has torsion +tau.

void ExpectFrame3Torsion(double kappa, double tau, const PrintedVec& d2, const PrintedVec& d3) {
  const auto f = demo_frame(2, [&](core::KeyFrame& k) {
    k.kappa = kappa;
    k.tau = tau;
  });
  ExpectSide(f.approach, 3, {{"0.25", "0.0", "0.0"}, d2, d3});
  ExpectCuspMirror(f);
}

TEST(Chapter7, Table7_14_PathA) { ExpectFrame3Torsion(20, 50, {"0.0", "1.25", "0.0"}, {"0.0", "0.0", "15.625"}); }
TEST(Chapter7, Table7_14_PathB) { ExpectFrame3Torsion(20, 100, {"0.0", "1.25", "0.0"}, {"0.0", "0.0", "31.25"}); }
TEST(Chapter7, Table7_14_PathC) { ExpectFrame3Torsion(20, -50, {"0.0", "1.25", "0.0"}, {"0.0", "0.0", "-15.625"}); }
TEST(Chapter7, Table7_14_PathD) { ExpectFrame3Torsion(20, -100, {"0.0", "1.25", "0.0"}, {"0.0", "0.0", "-31.25"}); }

// ---------------------------------------------------------------------------------------
// Table 7.15: curvature derivative at frame 2, kappa = 10 (row (5.19) alone).

void ExpectFrame2CurvatureDerivative(double kappa_du, const PrintedVec& d3) {
  const auto f = demo_frame(1, [&](core::KeyFrame& k) {
    k.kappa = 10.0;
    k.kappa_d = kappa_du;
  });
  for (const auto* side : {&f.approach, &f.leave})
    ExpectSide(*side, 3, {{"0.0", "-0.25", "0.0"}, {"0.0", "0.0", "-0.625"}, d3});
}

TEST(Chapter7, Table7_15_PathA) { ExpectFrame2CurvatureDerivative(0, {"0.0", "0.0", "0.0"}); }
TEST(Chapter7, Table7_15_PathB) { ExpectFrame2CurvatureDerivative(200, {"0.0", "0.0", "-12.50"}); }
TEST(Chapter7, Table7_15_PathC) { ExpectFrame2CurvatureDerivative(400, {"0.0", "0.0", "-25.00"}); }

// ---------------------------------------------------------------------------------------
// Table 7.16: torsion derivative at frame 2, kappa = 10, kappa' = 0, tau = 0 (5.22).

void ExpectFrame2TorsionDerivative(double tau_du, const PrintedVec& d4) {
  const auto f = demo_frame(1, [&](core::KeyFrame& k) {
    k.kappa = 10.0;
    k.kappa_d = 0.0;
    k.tau = 0.0;
    k.tau_d = tau_du;
  });
  for (const auto* side : {&f.approach, &f.leave}) {
    ExpectSide(*side, 4,
               {{"0.0", "-0.25", "0.0"}, {"0.0", "0.0", "-0.625"}, {"0.0", "0.0", "0.0"}, d4});
  }
}

TEST(Chapter7, Table7_16_PathA) { ExpectFrame2TorsionDerivative(1000, {"156.25", "0.0", "0.0"}); }
TEST(Chapter7, Table7_16_PathB) { ExpectFrame2TorsionDerivative(5000, {"781.25", "0.0", "0.0"}); }
TEST(Chapter7, Table7_16_PathC) { ExpectFrame2TorsionDerivative(10000, {"1562.5", "0.0", "0.0"}); }

// ---------------------------------------------------------------------------------------
// Tables 7.19 and 7.20: the full motion specification of Table 7.18. Frames 1 and 4 have a
// tangent only; frames 2 and 3 have kappa and tau, with kappa' = tau' = 0 given ("also set
// to zero in this demonstration"), so both sides fix derivatives up to the 4th order (the
// 4th is zero, since p''' = tau C is parallel to C: not printed).

core::PathSpec table7_18(double kappa2, double tau2, double kappa3, double tau3) {
  core::PathSpec spec = table7_8(kDemoScale);
  auto set = [](core::KeyFrame& f, double kappa, double tau) {
    f.kappa = kappa;
    f.tau = tau;
    f.kappa_d = 0.0;
    f.tau_d = 0.0;
  };
  set(spec.frames[1], kappa2, tau2);
  set(spec.frames[2], kappa3, tau3);
  return spec;
}

void ExpectFullSpecFrame2(double kappa2, double tau2, double kappa3, double tau3, const PrintedVec& d2,
                          const PrintedVec& d3) {
  const auto f = convert_or_fail(table7_18(kappa2, tau2, kappa3, tau3))[1];
  for (const auto* side : {&f.approach, &f.leave}) {
    ExpectSide(*side, 4, {{"0.0", "-0.25", "0.0"}, d2, d3});
    EXPECT_TRUE(VecNear(side->d[3], Vector3d::Zero(), 1e-12));
  }
}

void ExpectFullSpecFrame3(double kappa2, double tau2, double kappa3, double tau3, const PrintedVec& d2,
                          const PrintedVec& d3) {
  const auto f = convert_or_fail(table7_18(kappa2, tau2, kappa3, tau3))[2];
  ExpectSide(f.approach, 4, {{"0.25", "0.0", "0.0"}, d2, d3});
  EXPECT_TRUE(VecNear(f.approach.d[3], Vector3d::Zero(), 1e-12));
  ExpectCuspMirror(f);
}

TEST(Chapter7, Table7_19_PathA) {
  // d2z printed -0.3175: erratum, it is 0.25^2 * 5 = 0.3125.
  ExpectFullSpecFrame2(5, -50, 1, 0, {"0.0", "0.0", "-0.3125"}, {"-3.9063", "0.0", "0.0"});
}
TEST(Chapter7, Table7_19_PathB) {
  ExpectFullSpecFrame2(10, -50, 10, 100, {"0.0", "0.0", "-0.625"}, {"-7.8125", "0.0", "0.0"});
}
TEST(Chapter7, Table7_19_PathC) {
  ExpectFullSpecFrame2(20, -50, 10, -100, {"0.0", "0.0", "-1.25"}, {"-15.625", "0.0", "0.0"});
}

TEST(Chapter7, Table7_20_PathA) {
  ExpectFullSpecFrame3(5, -50, 1, 0, {"0.0", "0.0625", "0.0"}, {"0.0", "0.0", "0.0"});
}
TEST(Chapter7, Table7_20_PathB) {
  ExpectFullSpecFrame3(10, -50, 10, 100, {"0.0", "0.625", "0.0"}, {"0.0", "0.0", "15.625"});
}
TEST(Chapter7, Table7_20_PathC) {
  ExpectFullSpecFrame3(20, -50, 10, -100, {"0.0", "0.625", "0.0"}, {"0.0", "0.0", "-15.625"});
}

}  // namespace
}  // namespace geotraj::test
