// Chapter 4's local shapes (core/geometry/local_forms.hpp; Tables 4.1-4.3 are golden tests,
// tests/core/golden/chapter4_test.cpp): the ellipse's curvature; a frame's local curve: a helix where kappa and tau are constant
// (4.20-4.21), continued smoothly through the frame by its backward branch, the same shape
// wherever the frame is, the cusp's and the inflection's branches, and the spatial saddle
// (4.4.3, Figs. 4.22-4.25, 7.26).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/geometry/local_forms.hpp"

namespace geotraj::core {
namespace {

using Eigen::Vector3d;

TEST(LocalForms, TheEllipsesCurvatureIsTheCirclesWhereItIsOne) {
  EXPECT_NEAR(ellipse_curvature(0.2, 0.2, 0.2, 0.0), 5.0, 1e-12);
  // At the end of the major axis: a / b^2.
  EXPECT_NEAR(ellipse_curvature(2.0, 1.0, 2.0, 0.0), 2.0, 1e-12);
  EXPECT_NEAR(ellipse_curvature(2.0, 1.0, 0.0, 1.0), 0.25, 1e-12);
}

FrenetFrame some_frame() {
  FrenetFrame f;
  f.p = Vector3d(0.3, -0.2, 0.5);
  f.R = Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  return f;
}

TEST(LocalForms, AFramesLocalCurveWithConstantCurvatureAndTorsionIsAHelixThroughIt) {
  const FrenetFrame f = some_frame();
  LocalConstraints c;
  c.kappa = 12.0;
  c.tau = 5.0;
  auto local = local_curve(f, c, 0.3);
  ASSERT_TRUE(local);
  for (const double s : {0.05, 0.15, 0.3}) {
    // Forward is the closed form ahead, backward the closed form behind: one helix.
    EXPECT_LE((local->forward.frame_at(s).p - advance_constant(f, c.kappa, c.tau, s).p).norm(), 1e-12);
    EXPECT_LE((local->backward.frame_at(s).p - advance_constant(f, c.kappa, c.tau, -s).p).norm(), 1e-12);
  }
  // Its radius and pitch (4.20-4.21).
  const RadiusPitch rp = helix_radius_pitch(c.kappa, c.tau);
  const Vector3d axis = (c.tau * f.T() + c.kappa * f.B()).normalized();
  const Vector3d centre = f.p + rp.radius * f.N();
  for (const double s : {0.1, 0.2}) {
    for (const Vector3d& q : {local->forward.frame_at(s).p, local->backward.frame_at(s).p}) {
      const Vector3d d = q - centre;
      EXPECT_NEAR((d - d.dot(axis) * axis).norm(), rp.radius, 1e-12);
    }
  }
}

TEST(LocalForms, TheSameConstraintsGiveTheSameShapeWhereverTheFrameIs) {
  LocalConstraints c;
  c.kappa = 8.0;
  c.kappa_d = 40.0;
  c.tau = -3.0;
  c.tau_d = 10.0;
  const FrenetFrame a = some_frame();
  FrenetFrame b;  // the world axes at the origin
  auto la = local_curve(a, c, 0.2);
  auto lb = local_curve(b, c, 0.2);
  ASSERT_TRUE(la && lb);
  for (const double s : {0.05, 0.1, 0.2}) {
    // a's curve in a's frame is b's curve in the world.
    EXPECT_LE((a.R.transpose() * (la->forward.frame_at(s).p - a.p) - lb->forward.frame_at(s).p).norm(), 1e-9);
    EXPECT_LE((a.R.transpose() * (la->backward.frame_at(s).p - a.p) - lb->backward.frame_at(s).p).norm(), 1e-9);
  }
  // The curvature along each branch is the given one moved by kappa' per metre of arc:
  // larger ahead, smaller behind.
  EXPECT_NEAR(lb->forward.kappa_at(0.1), 12.0, 1e-12);
  EXPECT_NEAR(lb->backward.kappa_at(0.1), 4.0, 1e-12);
}

TEST(LocalForms, ACuspsBranchesLeaveOnOneSideAndAnInflectionsBendApart) {
  const FrenetFrame f = some_frame();
  LocalConstraints c;
  c.kappa = 10.0;
  c.cusp = true;
  auto cusp = local_curve(f, c, 0.05);
  ASSERT_TRUE(cusp);
  EXPECT_LT((cusp->forward.frame_at(0.01).p - f.p).dot(f.T()), 0.0);
  EXPECT_LT((cusp->backward.frame_at(0.01).p - f.p).dot(f.T()), 0.0);
  c.cusp = false;
  c.inflection = true;
  auto inflection = local_curve(f, c, 0.05);
  ASSERT_TRUE(inflection);
  // Ahead it bends towards -N, behind towards +N: the normal inverts at the frame.
  EXPECT_LT((inflection->forward.frame_at(0.05).p - f.p).dot(f.N()), 0.0);
  EXPECT_GT((inflection->backward.frame_at(0.05).p - f.p).dot(f.N()), 0.0);
  EXPECT_GT((inflection->forward.frame_at(0.05).p - f.p).dot(f.T()), 0.0);
}

// The spatial saddle (4.4.3): torsion 0 at the frame with a derivative tau'. The torsion
// changes sign through the frame (Fig. 4.23: negative approaching, positive leaving, for
// tau' > 0), so the curve leaves its osculating plane on the same side ahead and behind, the
// side of kappa tau' (both branches' height along B grows as kappa tau' s^4 / 24: 16 times
// from s to 2s; Figs. 4.22 and 4.24, one per sign of tau'). At a point with torsion the
// branches leave on opposite sides instead (kappa tau s^3 / 6, 8 times from s to 2s).
TEST(LocalForms, ASaddlesBranchesLeaveTheOsculatingPlaneOnOneSide) {
  const FrenetFrame f = some_frame();
  const auto height = [&](const NaturalCurve& branch, double s) { return (branch.frame_at(s).p - f.p).dot(f.B()); };
  for (const double tau_d : {200.0, -200.0}) {
    LocalConstraints c;
    c.kappa = 10.0;
    c.tau_d = tau_d;
    auto saddle = local_curve(f, c, 0.05);
    ASSERT_TRUE(saddle);
    // Approaching (the backward branch, traced away: tau(sigma) = -tau' sigma) the torsion
    // has the sign of -tau', leaving that of tau'.
    EXPECT_LT(saddle->backward.tau_at(0.02) * tau_d, 0.0);
    EXPECT_GT(saddle->forward.tau_at(0.02) * tau_d, 0.0);
    for (const NaturalCurve* branch : {&saddle->forward, &saddle->backward}) {
      const double h1 = height(*branch, 0.01), h2 = height(*branch, 0.02);
      EXPECT_GT(h1 * tau_d, 0.0) << "on the side of kappa tau'";
      EXPECT_NEAR(h1, c.kappa * tau_d * std::pow(0.01, 4) / 24.0, 0.05 * std::abs(h1));
      EXPECT_NEAR(h2 / h1, 16.0, 0.5);
    }
  }
  LocalConstraints twisted;
  twisted.kappa = 10.0;
  twisted.tau = 5.0;
  auto regular = local_curve(f, twisted, 0.05);
  ASSERT_TRUE(regular);
  EXPECT_GT(height(regular->forward, 0.01), 0.0);
  EXPECT_LT(height(regular->backward, 0.01), 0.0);
  EXPECT_NEAR(height(regular->forward, 0.02) / height(regular->forward, 0.01), 8.0, 0.3);
}

}  // namespace
}  // namespace geotraj::core
