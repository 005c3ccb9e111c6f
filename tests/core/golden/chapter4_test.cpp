// Chapter 4's tables, asserted from the engine: Tables 4.1-4.3 (the parabola's, the cusp's
// and the inflection's curvature, tangents and normals) from the implicit curvature (4.4)
// and, independently, from the parametric forms' jets through the engine's differential
// geometry; Tables 4.4 and 4.5 (a helix's radius and pitch from its curvature and torsion,
// 4.20-4.21, and back, 4.18-4.19).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/local_forms.hpp"
#include "core/geometry/natural.hpp"

namespace geotraj::core {
namespace {

using Eigen::Vector3d;

// The jet of the planar parametric curve (x(u), y(u), 0) given its derivatives.
Jet planar_jet(double x, double y, double xu, double yu, double xuu, double yuu, double xuuu, double yuuu) {
  Jet jet{};
  jet[0] = Vector3d(x, y, 0.0);
  jet[1] = Vector3d(xu, yu, 0.0);
  jet[2] = Vector3d(xuu, yuu, 0.0);
  jet[3] = Vector3d(xuuu, yuuu, 0.0);
  jet[4] = Vector3d::Zero();
  return jet;
}

TEST(Chapter4, Table41ParabolasAreMostCurvedAtTheOrigin) {
  const double a_values[] = {0.05, 1.0, 5.0, 25.0};
  const double kappa_max[] = {0.1, 2.0, 10.0, 50.0};  // Table 4.1
  for (int i = 0; i < 4; ++i) {
    const double a = a_values[i];
    EXPECT_NEAR(std::abs(parabola_curvature(a, 0.0)), kappa_max[i], 1e-15 * kappa_max[i]);
    for (const double x : {-1.0, -0.3, 0.2, 0.7}) {
      // x(u) = u, y(u) = a u^2 (Table 4.1's parametric form) through the engine.
      const LocalGeometry g = local_geometry(planar_jet(x, a * x * x, 1.0, 2.0 * a * x, 0.0, 2.0 * a, 0.0, 0.0));
      EXPECT_NEAR(g.kappa, std::abs(parabola_curvature(a, x)), 1e-12 * g.kappa);
      EXPECT_LT(g.kappa, kappa_max[i]);
    }
  }
}

TEST(Chapter4, Table42CuspsAreUnboundedlyCurvedAndTheirTangentInverts) {
  for (const double a : {0.05, 1.0, 5.0, 25.0}) {  // Table 4.2: |kappa_max| infinite
    double previous = 0.0;
    for (const double u : {0.5, 0.1, 0.01, 0.001}) {
      // x(u) = a u^2, y(u) = a u^3 (4.14).
      const LocalGeometry g =
          local_geometry(planar_jet(a * u * u, a * u * u * u, 2 * a * u, 3 * a * u * u, 2 * a, 6 * a * u, 0.0, 6 * a));
      EXPECT_NEAR(g.kappa, std::abs(cusp_curvature(a, a * u * u, a * u * u * u)), 1e-9 * g.kappa) << a << " " << u;
      EXPECT_GT(g.kappa, 5.0 * previous) << "grows without bound towards the cusp";
      previous = g.kappa;
      // The two branches, u > 0 and u < 0, leave the cusp along the same tangent line in
      // opposite directions of travel: dx/du = 2 a u changes sign.
      const LocalGeometry other = local_geometry(
          planar_jet(a * u * u, -a * u * u * u, -2 * a * u, 3 * a * u * u, 2 * a, -6 * a * u, 0.0, 6 * a));
      EXPECT_LT(g.T.x() * other.T.x(), 0.0);
    }
  }
}

TEST(Chapter4, Table43TheNormalInvertsThroughAnInflection) {
  struct Row {
    double u, T[2], N[2];
  };
  const Row table[] = {{-0.5, {0.8, 0.6}, {0.6, -0.8}},
                       {-0.1, {0.9996, 0.03}, {0.03, -0.9996}},
                       {0.1, {0.9996, 0.03}, {-0.03, 0.9996}},
                       {0.5, {0.8, 0.6}, {-0.6, 0.8}}};  // Table 4.3, y = x^3
  for (const Row& r : table) {
    const double u = r.u;
    const LocalGeometry g = local_geometry(planar_jet(u, u * u * u, 1.0, 3 * u * u, 0.0, 6 * u, 0.0, 6.0));
    ASSERT_TRUE(g.has_normal);
    for (int k = 0; k < 2; ++k) {
      EXPECT_NEAR(g.T[k], r.T[k], 5e-4) << u;  // printed to 4 decimals (0.03 to 2)
      EXPECT_NEAR(g.N[k], r.N[k], 5e-4) << u;
    }
  }
}

// Tables 4.4 and 4.5: kappa, tau -> r, l (l = pitch / 2 pi), to the tables' four decimals.
TEST(Chapter4, Tables44And45HelixRadiusAndPitch) {
  struct Row {
    double kappa, tau, r, l;
  };
  const Row rows[] = {{1, 1, 0.5, 0.5},       {2, 1, 0.4, 0.2},       {5, 1, 0.1923, 0.0385},
                      {1, 2, 0.2, 0.4},       {1, 5, 0.0385, 0.1923}};
  for (const Row& row : rows) {
    const RadiusPitch rp = helix_radius_pitch(row.kappa, row.tau);
    EXPECT_NEAR(rp.radius, row.r, 5e-5) << row.kappa << " " << row.tau;
    EXPECT_NEAR(rp.pitch / (2.0 * std::numbers::pi), row.l, 5e-5) << row.kappa << " " << row.tau;
    const CurvatureTorsion back = helix_curvature_torsion(rp.radius, rp.pitch);  // (4.18-4.19)
    EXPECT_NEAR(back.kappa, row.kappa, 1e-12);
    EXPECT_NEAR(back.tau, row.tau, 1e-12);
  }
}

}  // namespace
}  // namespace geotraj::core
