// Chapter 5 conversion beyond the thesis's tables: the rows (5.14), (5.19), (5.22) are met
// exactly by the minimum-norm solutions, the orders follow the given constraints, the two
// derivative conventions differ by the tangent scale, and the sides of cusps and
// inflections carry the flipped frames.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "core/geometry/constraints.hpp"
#include "core/geometry/path.hpp"
#include "core/geometry/validate.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::DerivativeConvention;

const Vector3d kT = Vector3d(1, 2, 2) / 3.0;
const Vector3d kN = Vector3d(2, 1, -2) / 3.0;  // kT . kN = 0

TEST(Constraints, ThirdDerivativeMeetsBothRowsWithMinimumNorm) {
  const Vector3d p_u = 1.7 * kT;
  const double kappa = 2.5, tau = -1.3, kappa_du = 4.0;
  const Vector3d p_uu = core::second_derivative(p_u, kappa, kN);
  EXPECT_TRUE(VecNear(p_uu, p_u.squaredNorm() * kappa * kN, 1e-15));  // (5.10)
  const Vector3d C = p_u.cross(p_uu);
  const Vector3d a0 = C / C.squaredNorm(), a1 = C.cross(p_u);
  const Vector3d p_uuu = core::third_derivative(p_u, p_uu, tau, kappa_du);
  EXPECT_NEAR(a0.dot(p_uuu), tau, 1e-14);                                               // (5.14)
  EXPECT_NEAR(a1.dot(p_uuu), kappa_du * kappa * std::pow(p_u.norm(), 6), 1e-12);        // (5.19)
  EXPECT_NEAR(p_uuu.dot(p_u), 0.0, 1e-13);  // minimum norm: in span(a0, a1), no part along p'
  // One row alone: the other row's direction gets nothing.
  EXPECT_NEAR(a1.dot(core::third_derivative(p_u, p_uu, tau, std::nullopt)), 0.0, 1e-13);
  EXPECT_NEAR(a0.dot(core::third_derivative(p_u, p_uu, std::nullopt, kappa_du)), 0.0, 1e-14);
}

TEST(Constraints, FourthDerivativeMeetsRowWithMinimumNorm) {
  const Vector3d p_u = 0.8 * kT;
  const double kappa = 1.5, tau = 0.7, tau_du = -3.0;
  const Vector3d p_uu = core::second_derivative(p_u, kappa, kN);
  const Vector3d p_uuu = core::third_derivative(p_u, p_uu, tau, 0.2);
  const Vector3d p_uuuu = core::fourth_derivative(p_u, p_uu, p_uuu, tau, tau_du);
  const Vector3d C = p_u.cross(p_uu);
  EXPECT_NEAR(C.dot(p_uuuu), tau_du * C.squaredNorm() + 2 * tau * C.dot(p_u.cross(p_uuu)), 1e-13);  // (5.22)
  EXPECT_NEAR(p_uuuu.cross(C).norm(), 0.0, 1e-13);  // minimum norm: along C
}

core::KeyFrame valid(const core::KeyFrame& f) {
  auto spec = make_spec({Frame({-1, 0, 0}, {1, 0, 0}), f, Frame({1, 0, 0}, {1, 0, 0})});
  const auto r = core::validate_path(spec);
  EXPECT_TRUE(r);
  return r ? r->frames[1] : f;
}

TEST(Constraints, OrderFollowsGivenConstraints) {
  struct Case {
    core::KeyFrame frame;
    int order;
  };
  const Case cases[] = {
      {Frame({0, 0, 0}, kT), 1},
      {Frame({0, 0, 0}, kT).normal(kN), 1},
      {Frame({0, 0, 0}, kT).curvature(0), 2},
      {Frame({0, 0, 0}, kT).normal(kN).curvature(2), 2},
      {Frame({0, 0, 0}, kT).normal(kN).curvature(2).torsion(0), 3},
      {Frame({0, 0, 0}, kT).normal(kN).curvature(2).curvature_derivative(1), 3},
      {Frame({0, 0, 0}, kT).normal(kN).curvature(2).torsion(1).torsion_derivative(0), 4},
  };
  for (const auto& c : cases) {
    const auto f = core::convert_frame(valid(c.frame), DerivativeConvention::kPerArcLength);
    EXPECT_EQ(f.approach.order, c.order);
    EXPECT_EQ(f.leave.order, c.order);
  }
}

// Under PER_ARC_LENGTH, kappa' and tau' are per metre: d/du = |dp/du| d/ds at the frame.
TEST(Constraints, ConventionsDifferByTangentScale) {
  const double scale = 2.5;
  const auto per_s = core::convert_frame(
      valid(Frame({0, 0, 0}, kT).normal(kN).curvature(2).curvature_derivative(0.4).torsion(1).torsion_derivative(-0.6)
                .scale(scale)),
      DerivativeConvention::kPerArcLength);
  const auto per_u = core::convert_frame(
      valid(Frame({0, 0, 0}, kT).normal(kN).curvature(2).curvature_derivative(0.4 * scale).torsion(1)
                .torsion_derivative(-0.6 * scale).scale(scale)),
      DerivativeConvention::kPerParameter);
  for (int k = 0; k < 4; ++k) EXPECT_TRUE(VecNear(per_s.leave.d[k], per_u.leave.d[k], 1e-12)) << "d" << k + 1;
}

TEST(Constraints, CuspAndInflectionSides) {
  const auto cusp = core::convert_frame(valid(Frame({0, 0, 0}, kT).normal(kN).curvature(2).torsion(1).cusp()),
                                        DerivativeConvention::kPerArcLength);
  EXPECT_TRUE(VecNear(cusp.approach.T, kT, 1e-15));
  EXPECT_TRUE(VecNear(cusp.leave.T, -kT, 1e-15));
  EXPECT_TRUE(VecNear(cusp.leave.N, cusp.approach.N, 0.0));
  // The leaving side's own binormal is -B, and it meets the same torsion along increasing u.
  const Vector3d C_leave = cusp.leave.d[0].cross(cusp.leave.d[1]);
  EXPECT_TRUE(VecNear(C_leave.normalized(), -kT.cross(kN), 1e-15));
  EXPECT_NEAR(C_leave.dot(cusp.leave.d[2]) / C_leave.squaredNorm(), 1.0, 1e-14);

  const auto inflection = core::convert_frame(valid(Frame({0, 0, 0}, kT).normal(kN).curvature(2).inflection()),
                                              DerivativeConvention::kPerArcLength);
  EXPECT_TRUE(VecNear(inflection.leave.T, kT, 1e-15));
  EXPECT_TRUE(VecNear(inflection.leave.N, -inflection.approach.N, 0.0));
  EXPECT_TRUE(VecNear(inflection.leave.d[1], -inflection.approach.d[1], 0.0));
}

TEST(BuildPath, ConstraintsThatWouldOverflowAreRejected) {
  // d3p/du3 = tau C with |C| = 1e10: 1e300 x 1e10 would overflow; the bound on |tau| says so.
  const auto r = core::build_path(make_spec(
      {Frame({0, 0, 0}, {1, 0, 0}), Frame({1, 1, 0}, {0, 1, 0}).normal({-1, 0, 0}).curvature(1e10).torsion(1e300),
       Frame({0, 2, 0}, {-1, 0, 0})}));
  ASSERT_FALSE(r);
  ASSERT_EQ(r.error().size(), 1u);
  EXPECT_EQ(r.error()[0].field, "frames[1].torsion");
  EXPECT_NE(r.error()[0].description.find("at most 1e+12"), std::string::npos) << r.error()[0].description;
}

}  // namespace
}  // namespace geotraj::test
