// Curves from their natural equations (natural.hpp; thesis 2.4, 4.4.1; the helix's relations
// against Tables 4.4 and 4.5 are golden tests, tests/core/golden/chapter4_test.cpp): the closed form against the helix's parametric form
// (4.17), the planar clothoid's closed form against its Fresnel integrals' power series
// (fresnel_test.cpp checks it against the Magnus integration), the Magnus integration
// against itself at a tighter tolerance, and the curvature and torsion measured on the curve (finite
// differences of its positions) against the profile it was built from.
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/natural.hpp"

namespace geotraj::test {
namespace {

using core::FrenetFrame;
using core::NaturalCurve;
using Eigen::Vector3d;

// The helix x = r cos u, y = r sin u, z = l u (4.17) and its Frenet frame at u.
struct Helix {
  double r, l;
  double c() const { return std::sqrt(r * r + l * l); }  // |dp/du|
  Vector3d p(double u) const { return {r * std::cos(u), r * std::sin(u), l * u}; }
  FrenetFrame frame(double u) const {
    FrenetFrame f;
    f.p = p(u);
    const Vector3d T = Vector3d(-r * std::sin(u), r * std::cos(u), l) / c();
    const Vector3d N(-std::cos(u), -std::sin(u), 0.0);
    f.R.col(0) = T;
    f.R.col(1) = N;
    f.R.col(2) = T.cross(N);
    return f;
  }
};

// The closed form (the exponential of SE(3)) against the parametric helix, right- and
// left-handed, one turn to a hundred, every frame column and position along the way.
TEST(NaturalEquations, TheClosedFormIsTheHelixOfItsRadiusAndPitch) {
  for (const double r : {0.005, 0.05, 0.5}) {
    for (const double pitch : {0.02, -0.02, 0.3, 1e-9}) {
      const Helix helix{r, pitch / (2.0 * std::numbers::pi)};
      const core::CurvatureTorsion kt = core::helix_curvature_torsion(r, pitch);
      for (const double turns : {0.25, 1.0, 100.0}) {
        const double u = 2.0 * std::numbers::pi * turns;
        const double s = helix.c() * u;
        const FrenetFrame f = core::advance_constant(helix.frame(0.0), kt.kappa, kt.tau, s);
        const FrenetFrame want = helix.frame(u);
        const double scale = std::max(1.0, s);  // rounding grows with the turns
        EXPECT_LT((f.p - want.p).norm(), 1e-13 * scale) << r << " " << pitch << " " << turns;
        EXPECT_LT((f.R - want.R).norm(), 1e-12 * scale) << r << " " << pitch << " " << turns;
      }
      // The curve built from the same numbers takes no step and says so.
      auto curve = NaturalCurve::build(helix.frame(0.0), helix.c() * 4.0, {kt.kappa}, {kt.tau});
      ASSERT_TRUE(curve);
      EXPECT_EQ(curve->steps(), 0u);
      EXPECT_LT((curve->frame_at(helix.c() * 2.5).p - helix.p(2.5)).norm(), 1e-13);
    }
  }
}

// int_0^s cos(a x^2) dx and int_0^s sin(a x^2) dx by their power series (long double; the
// terms fall below 1e-25 of the sum before 200 of them for a s^2 <= 20).
std::pair<double, double> fresnel(double a, double s) {
  long double c = 0.0L, sn = 0.0L;
  long double term = s;  // a^n s^(2n+1) / n!, n = 0
  for (int n = 0; n < 200; ++n) {
    const long double part = term / static_cast<long double>(2 * n + 1);
    switch (n % 4) {
      case 0: c += part; break;
      case 1: sn += part; break;
      case 2: c -= part; break;
      default: sn -= part; break;
    }
    term *= static_cast<long double>(a) * s * s / static_cast<long double>(n + 1);
  }
  return {static_cast<double>(c), static_cast<double>(sn)};
}

// The clothoid kappa(s) = k1 s from the origin along x, normal +y: x(s) = int cos(k1 s^2 / 2),
// y(s) = int sin(k1 s^2 / 2) (its heading is k1 s^2 / 2): in closed form, no step, within
// the long-double series' own rounding (1e-13 m at a turn of 20 rad).
TEST(NaturalEquations, AClothoidIsItsFresnelIntegrals) {
  for (const double k1 : {2.0, 20.0, 80.0}) {  // [1/m^2]
    const double length = std::min(1.0, std::sqrt(2.0 * 20.0 / k1));  // a turn of up to 20 rad
    auto curve = NaturalCurve::build(FrenetFrame{}, length, {0.0, k1}, {});
    ASSERT_TRUE(curve) << k1;
    double worst = 0.0;
    for (int i = 0; i <= 200; ++i) {
      const double s = length * i / 200.0;
      const auto [x, y] = fresnel(0.5 * k1, s);
      worst = std::max(worst, (curve->frame_at(s).p - Vector3d(x, y, 0.0)).norm());
      EXPECT_NEAR(curve->frame_at(s).T().dot(Vector3d(std::cos(0.5 * k1 * s * s), std::sin(0.5 * k1 * s * s), 0.0)),
                  1.0, 1e-12);
    }
    std::printf("clothoid k' = %g 1/m^2 over %.3f m: %zu steps, worst position error %.2e m\n", k1, length,
                curve->steps(), worst);
    EXPECT_EQ(curve->steps(), 0u);
    EXPECT_LT(worst, 1e-12) << k1;
  }
}

// A general profile: the curve built to 1e-9 m against the same built to 1e-13 m, and the
// curvature and torsion measured on its positions (central differences) against the profile.
TEST(NaturalEquations, TheCurveHasTheCurvatureAndTorsionItWasBuiltFrom) {
  FrenetFrame start;
  start.p = Vector3d(0.3, -0.2, 0.5);
  start.R = Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const std::vector<double> kappa{5.0, 3.0, -2.0}, tau{1.0, -4.0};
  const double length = 1.2;
  auto curve = NaturalCurve::build(start, length, kappa, tau);
  auto reference = NaturalCurve::build(start, length, kappa, tau, 1e-13);
  ASSERT_TRUE(curve && reference);
  EXPECT_GT(reference->steps(), curve->steps());
  double worst = 0.0;
  for (int i = 0; i <= 240; ++i) {
    const double s = length * i / 240.0;
    worst = std::max(worst, (curve->frame_at(s).p - reference->frame_at(s).p).norm());
  }
  std::printf("profile: %zu steps (%zu at 1e-13), worst position error %.2e m\n", curve->steps(), reference->steps(),
              worst);
  EXPECT_LT(worst, 1e-9);
  EXPECT_LT((curve->end().p - curve->frame_at(length).p).norm(), 1e-15);

  const double h = 1e-3;
  for (const double s : {0.1, 0.4, 0.77, 1.1}) {
    const Vector3d pm2 = curve->frame_at(s - 2 * h).p, pm = curve->frame_at(s - h).p, p0 = curve->frame_at(s).p,
                   pp = curve->frame_at(s + h).p, pp2 = curve->frame_at(s + 2 * h).p;
    const Vector3d d1 = (pp - pm) / (2 * h);
    const Vector3d d2 = (pp - 2 * p0 + pm) / (h * h);
    const Vector3d d3 = (pp2 - 2 * pp + 2 * pm - pm2) / (2 * h * h * h);
    EXPECT_NEAR(d1.norm(), 1.0, 1e-5) << "s is the arc length, s = " << s;
    const double k_measured = d1.cross(d2).norm() / std::pow(d1.norm(), 3);
    const double t_measured = d1.cross(d2).dot(d3) / d1.cross(d2).squaredNorm();
    EXPECT_NEAR(k_measured, curve->kappa_at(s), 1e-4) << "s = " << s;
    EXPECT_NEAR(t_measured, curve->tau_at(s), 1e-3) << "s = " << s;
    // The jet (from the profile) against the same differences.
    const core::Jet jet = curve->jet_at(s);
    EXPECT_LT((jet[1] - d1).norm(), 1e-5);
    EXPECT_LT((jet[2] - d2).norm(), 1e-4);
    EXPECT_LT((jet[3] - d3).norm(), 1e-3);
  }
}

TEST(NaturalEquations, BadInputNamesItsField) {
  auto bad_length = NaturalCurve::build(FrenetFrame{}, 0.0, {1.0}, {});
  ASSERT_FALSE(bad_length);
  EXPECT_EQ(bad_length.error().front().field, "lengthM");
  auto bad_coefficient = NaturalCurve::build(FrenetFrame{}, 1.0, {1.0, std::nan("")}, {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0});
  ASSERT_FALSE(bad_coefficient);
  ASSERT_EQ(bad_coefficient.error().size(), 2u);
  EXPECT_EQ(bad_coefficient.error()[0].field, "curvature[1]");
  EXPECT_EQ(bad_coefficient.error()[1].field, "torsion");
  FrenetFrame skewed;
  skewed.R(0, 1) = 0.1;
  auto bad_start = NaturalCurve::build(skewed, 1.0, {1.0}, {});
  ASSERT_FALSE(bad_start);
  EXPECT_EQ(bad_start.error().front().field, "start");
  FrenetFrame mirrored;
  mirrored.R(2, 2) = -1.0;
  EXPECT_FALSE(NaturalCurve::build(mirrored, 1.0, {1.0}, {}));
  // A curve that would need too many steps is refused, not integrated for ever.
  auto huge = NaturalCurve::build(FrenetFrame{}, 1e3, {0.0, 1e6}, {}, 1e-9);
  ASSERT_FALSE(huge);
  EXPECT_EQ(huge.error().front().field, "curvature");
}

}  // namespace
}  // namespace geotraj::test
