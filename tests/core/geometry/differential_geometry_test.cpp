// local_geometry: the Frenet apparatus from a jet, against closed forms (helix, parabola,
// twisted cubic), central differences of kappa and tau, and the straight/singular cases.
#include <cmath>

#include <gtest/gtest.h>

#include "core/geometry/differential_geometry.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::Jet;
using core::LocalGeometry;

/// Helix (r cos wu, r sin wu, c w u): jet at u.
Jet helix_jet(double r, double c, double w, double u) {
  const double s = std::sin(w * u), co = std::cos(w * u);
  Jet j;
  j[0] = {r * co, r * s, c * w * u};
  j[1] = w * Vector3d(-r * s, r * co, c);
  j[2] = w * w * Vector3d(-r * co, -r * s, 0);
  j[3] = w * w * w * Vector3d(r * s, -r * co, 0);
  j[4] = w * w * w * w * Vector3d(r * co, r * s, 0);
  return j;
}

TEST(LocalGeometry, HelixClosedForm) {
  const double r = 0.2, c = 0.05, w = 2.5;
  const double rc = r * r + c * c;
  for (const double u : {0.0, 0.3, 1.7}) {
    const LocalGeometry g = core::local_geometry(helix_jet(r, c, w, u));
    const double t = w * u;
    ASSERT_TRUE(g.regular && g.has_normal);
    EXPECT_NEAR(g.speed, w * std::sqrt(rc), 1e-15);
    EXPECT_NEAR(g.kappa, r / rc, 1e-13);
    EXPECT_NEAR(g.tau, c / rc, 1e-13);
    EXPECT_NEAR(g.kappa_du, 0.0, 1e-12);
    EXPECT_NEAR(g.tau_du, 0.0, 1e-12);
    EXPECT_TRUE(VecNear(g.T, Vector3d(-r * std::sin(t), r * std::cos(t), c) / std::sqrt(rc), 1e-15));
    EXPECT_TRUE(VecNear(g.N, Vector3d(-std::cos(t), -std::sin(t), 0), 1e-15));
    EXPECT_TRUE(VecNear(g.B, Vector3d(c * std::sin(t), -c * std::cos(t), r) / std::sqrt(rc), 1e-15));
  }
}

// Parabola (u, a u^2, 0): p' and p'' are not perpendicular (the general form of (5.15)).
// kappa = 2a / g^(3/2), dkappa/du = -24 a^3 u / g^(5/2), g = 1 + 4 a^2 u^2.
TEST(LocalGeometry, ParabolaCurvatureDerivative) {
  const double a = 1.5;
  for (const double u : {-0.7, 0.0, 0.4, 2.0}) {
    Jet j;
    j[0] = {u, a * u * u, 0};
    j[1] = {1, 2 * a * u, 0};
    j[2] = {0, 2 * a, 0};
    j[3] = j[4] = Vector3d::Zero();
    const LocalGeometry g = core::local_geometry(j);
    const double gg = 1 + 4 * a * a * u * u;
    ASSERT_TRUE(g.has_normal);
    EXPECT_NEAR(g.kappa, 2 * a / std::pow(gg, 1.5), 1e-14) << u;
    EXPECT_NEAR(g.kappa_du, -24 * a * a * a * u / std::pow(gg, 2.5), 1e-13) << u;
    EXPECT_NEAR(g.kappa_ds, g.kappa_du / std::sqrt(gg), 1e-15) << u;
    EXPECT_EQ(g.tau, 0.0);
    EXPECT_TRUE(VecNear(g.B, Vector3d(0, 0, 1), 1e-15));
  }
}

// Twisted cubic (u, u^2, u^3): tau = 12 / f, dtau/du = -12 f' / f^2 with
// f = |p' x p''|^2 = 36u^4 + 36u^2 + 4; kappa = sqrt(f) / g^(3/2), g = 1 + 4u^2 + 9u^4.
Jet twisted_cubic(double u) {
  Jet j;
  j[0] = {u, u * u, u * u * u};
  j[1] = {1, 2 * u, 3 * u * u};
  j[2] = {0, 2, 6 * u};
  j[3] = {0, 0, 6};
  j[4] = Vector3d::Zero();
  return j;
}

TEST(LocalGeometry, TwistedCubicClosedForm) {
  for (const double u : {-1.0, 0.0, 0.3, 1.2}) {
    const LocalGeometry g = core::local_geometry(twisted_cubic(u));
    const double f = 36 * std::pow(u, 4) + 36 * u * u + 4, df = 144 * std::pow(u, 3) + 72 * u;
    const double gg = 1 + 4 * u * u + 9 * std::pow(u, 4), dg = 8 * u + 36 * std::pow(u, 3);
    EXPECT_NEAR(g.tau, 12 / f, 1e-14) << u;
    EXPECT_NEAR(g.tau_du, -12 * df / (f * f), 1e-13) << u;
    EXPECT_NEAR(g.kappa, std::sqrt(f) / std::pow(gg, 1.5), 1e-14) << u;
    const double dkappa = 0.5 * df / std::sqrt(f) / std::pow(gg, 1.5) - 1.5 * std::sqrt(f) * dg / std::pow(gg, 2.5);
    EXPECT_NEAR(g.kappa_du, dkappa, 1e-13) << u;
    EXPECT_NEAR(g.tau_ds * g.speed, g.tau_du, 1e-14) << u;
  }
}

// kappa_du and tau_du against central differences of kappa and tau along the twisted cubic.
// Step h = 1e-5: truncation h^2/6 |kappa'''| ~ 1e-10 * O(10), rounding eps/h ~ 1e-11.
TEST(LocalGeometry, DerivativesMatchCentralDifferences) {
  constexpr double h = 1e-5, tol = 1e-8;
  for (const double u : {-0.8, -0.1, 0.25, 0.9}) {
    const LocalGeometry lo = core::local_geometry(twisted_cubic(u - h));
    const LocalGeometry mid = core::local_geometry(twisted_cubic(u));
    const LocalGeometry hi = core::local_geometry(twisted_cubic(u + h));
    EXPECT_NEAR((hi.kappa - lo.kappa) / (2 * h), mid.kappa_du, tol) << u;
    EXPECT_NEAR((hi.tau - lo.tau) / (2 * h), mid.tau_du, tol) << u;
  }
}

TEST(LocalGeometry, StraightAndSingularPoints) {
  Jet j;
  for (auto& v : j) v.setZero();
  j[1] = {1, 2, 2};
  EXPECT_TRUE(core::local_geometry(j).regular);
  EXPECT_FALSE(core::local_geometry(j).has_normal);  // p'' = 0
  EXPECT_EQ(core::local_geometry(j).kappa, 0.0);

  j[2] = 3.0 * j[1];  // p'' parallel to p': still straight
  EXPECT_FALSE(core::local_geometry(j).has_normal);

  j[2] = {1e-6, 0, 0};  // a genuine bend below the stated rounding level of p''
  EXPECT_TRUE(core::local_geometry(j).has_normal);
  EXPECT_FALSE(core::local_geometry(j, 1e-5).has_normal);

  j[1].setZero();  // a singular point: no tangent
  EXPECT_FALSE(core::local_geometry(j).regular);
  EXPECT_FALSE(core::local_geometry(j).has_normal);
}

}  // namespace
}  // namespace geotraj::test
