// The Fresnel integrals and the planar clothoid in closed form (fresnel.hpp) against
// Abramowitz and Stegun's values, long-double quadrature, and the curve integrated by the
// Magnus method from the same natural equations (natural.hpp).
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/fresnel.hpp"
#include "core/geometry/natural.hpp"

namespace geotraj::test {
namespace {

using Eigen::Vector3d;

// int_0^1 exp(i (b x + a x^2 / 2)) dx by five-point Gauss-Legendre panels in long double,
// each panel turning by at most 0.2 rad (the rule's error there is below 1e-18).
std::complex<double> quadrature(double a, double b) {
  const long double nodes[5] = {0.0L, -0.5384693101056830910363144L, 0.5384693101056830910363144L,
                                -0.9061798459386639927976269L, 0.9061798459386639927976269L};
  const long double weights[5] = {0.5688888888888888888888889L, 0.4786286704993664680412915L,
                                  0.4786286704993664680412915L, 0.2369268850561890875142640L,
                                  0.2369268850561890875142640L};
  const int panels = static_cast<int>(std::max(64.0, 5.0 * (std::abs(b) + std::abs(a))));
  long double re = 0.0L, im = 0.0L;
  for (int p = 0; p < panels; ++p) {
    const long double mid = (p + 0.5L) / panels, half = 0.5L / panels;
    for (int k = 0; k < 5; ++k) {
      const long double x = mid + half * nodes[k];
      const long double theta = b * x + 0.5L * a * x * x;
      re += weights[k] * half * std::cos(theta);
      im += weights[k] * half * std::sin(theta);
    }
  }
  return {static_cast<double>(re), static_cast<double>(im)};
}

// Abramowitz and Stegun, Table 7.7 (C and S to 15 digits), and the limits at infinity.
TEST(Fresnel, MatchesTheTablesValues) {
  struct Row {
    double u, c, s;
  };
  const Row rows[] = {{0.5, 0.492344225871446, 0.064732432859999},
                      {1.0, 0.779893400376823, 0.438259147390355},
                      {1.5, 0.445261176039822, 0.697504960082093},
                      {2.0, 0.488253406075341, 0.343415678363698},
                      {3.0, 0.605720789297686, 0.496312998967375},
                      {5.0, 0.563631188704012, 0.499191381917117}};
  for (const Row& row : rows) {
    for (const double sign : {1.0, -1.0}) {  // odd
      const std::complex<double> e = core::fresnel(sign * row.u);
      EXPECT_NEAR(e.real(), sign * row.c, 1e-14) << row.u;
      EXPECT_NEAR(e.imag(), sign * row.s, 1e-14) << row.u;
    }
  }
  // Towards infinity: (1 + i) / 2 within 1 / (pi u).
  for (const double u : {1e3, 1e6, 1e9}) {
    const std::complex<double> e = core::fresnel(u);
    EXPECT_LE(std::abs(e - std::complex<double>(0.5, 0.5)), 1.0 / (std::numbers::pi * u) * 1.0001) << u;
  }
  // Continuous where the series hands over to the continued fraction.
  EXPECT_LT(std::abs(core::fresnel(std::nextafter(1.5, 0.0)) - core::fresnel(1.5)), 1e-15);
}

// The clothoid integral over arcs, clothoids from rest, through inflections, almost arcs
// and tight spirals, both turning directions: within 1e-14 of the quadrature (relative to
// the unit chord), with no large phase and no cancellation anywhere.
TEST(Fresnel, TheClothoidIntegralIsItsQuadratureEverywhere) {
  double worst = 0.0;
  int cases = 0;
  for (const double a : {0.0, 1e-14, 1e-7, 1e-3, 0.05, 0.7, 3.0, 20.0, 400.0, 5000.0}) {
    for (const double b : {0.0, 1e-9, 0.04, 0.3, 2.0, 6.283185307179586, 15.0, 200.0, 3000.0}) {
      for (const double sa : {1.0, -1.0}) {
        for (const double sb : {1.0, -1.0}) {
          const std::complex<double> got = core::clothoid_integral(sa * a, sb * b);
          const std::complex<double> want = quadrature(sa * a, sb * b);
          const double error = std::abs(got - want);
          worst = std::max(worst, error);
          ++cases;
          EXPECT_LT(error, 1e-14) << "a " << sa * a << " b " << sb * b;
        }
      }
    }
    // Through the inflection at its middle (theta = a (x - 1/2)^2 / 2 - a / 8) and near it.
    for (const double shift : {-0.5, -0.4999, -0.3}) {
      const std::complex<double> got = core::clothoid_integral(a, shift * a);
      EXPECT_LT(std::abs(got - quadrature(a, shift * a)), 1e-14) << "a " << a << " b " << shift * a;
    }
  }
  std::printf("%d cases, worst |F - quadrature| %.2e\n", cases, worst);
}

// The planar clothoid of a NaturalCurve is the closed form: no step, and within 1e-12 m of
// the same natural equations integrated by the Magnus method (a torsion of 1e-300 1/m, which
// moves nothing, takes that path) at 1e-12 m, from a start frame anywhere.
TEST(Fresnel, TheCurvesClosedFormIsTheIntegratedCurve) {
  core::FrenetFrame start;
  start.p = Vector3d(0.4, -0.1, 0.3);
  start.R = Eigen::AngleAxisd(1.1, Vector3d(-1, 2, 0.5).normalized()).toRotationMatrix();
  struct Case {
    double k0, k1, length;
  };
  for (const Case& c : {Case{0.0, 20.0, 1.0}, Case{20.0, -40.0, 1.0}, Case{-5.0, 300.0, 0.4},
                        Case{12.0, 1e-6, 0.5}, Case{1e-6, 1e-6, 2.0}}) {
    auto closed = core::NaturalCurve::build(start, c.length, {c.k0, c.k1}, {});
    auto integrated = core::NaturalCurve::build(start, c.length, {c.k0, c.k1}, {1e-300}, 1e-12);
    ASSERT_TRUE(closed && integrated);
    EXPECT_EQ(closed->steps(), 0u);
    EXPECT_GT(integrated->steps(), 0u);
    double worst = 0.0;
    for (int i = 0; i <= 100; ++i) {
      const double s = c.length * i / 100.0;
      const core::FrenetFrame f = closed->frame_at(s), g = integrated->frame_at(s);
      worst = std::max(worst, (f.p - g.p).norm());
      EXPECT_LT((f.R - g.R).norm(), 1e-11) << s;
      EXPECT_NEAR(std::abs(f.B().dot(start.B())), 1.0, 1e-15) << "planar";
    }
    EXPECT_LT(worst, 1e-12) << c.k0 << " " << c.k1;
    // The curvature measured on the positions is kappa0 + kappa1 s.
    const double h = 1e-4;
    for (const double s : {0.1 * c.length, 0.5 * c.length, 0.9 * c.length}) {
      const Vector3d pm = closed->frame_at(s - h).p, p0 = closed->frame_at(s).p, pp = closed->frame_at(s + h).p;
      const Vector3d d1 = (pp - pm) / (2 * h), d2 = (pp - 2 * p0 + pm) / (h * h);
      const double measured = d1.cross(d2).dot(start.B()) / std::pow(d1.norm(), 3);  // signed about B
      EXPECT_NEAR(measured, c.k0 + c.k1 * s, 1e-4 * (1.0 + std::abs(c.k0) + std::abs(c.k1))) << s;
    }
  }
}

}  // namespace
}  // namespace geotraj::test
