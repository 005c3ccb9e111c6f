// Closed forms through the whole pipeline (build_path, achieved_geometry, analyze): a helix,
// a circle, a straight line, and the arc length of a straight segment.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "core/geometry/analysis.hpp"
#include "core/geometry/arc_length.hpp"
#include "core/geometry/path.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::BlendMethod;
using core::DerivativeConvention;

const BlendMethod kBlends[] = {BlendMethod::kPolynomial, BlendMethod::kTrapezoidal};
const char* blend_name(BlendMethod b) { return b == BlendMethod::kPolynomial ? "polynomial" : "trapezoid"; }

// ---------------------------------------------------------------------------------------
// Helix p(t) = (r cos t, r sin t, c t): kappa = r / (r^2 + c^2), tau = c / (r^2 + c^2),
// both constant (kappa' = tau' = 0). Key frames at t_i = i dt with the exact Frenet frame;
// one segment spans dt, so |dp/du| = dt sqrt(r^2 + c^2) is the tangent scale.

struct Helix {
  double r = 0.2, c = 0.05, dt = 1.1;
  double rc() const { return r * r + c * c; }
  double kappa() const { return r / rc(); }
  double tau() const { return c / rc(); }
  double speed() const { return dt * std::sqrt(rc()); }
  Vector3d p(double t) const { return {r * std::cos(t), r * std::sin(t), c * t}; }
  Vector3d T(double t) const { return Vector3d(-r * std::sin(t), r * std::cos(t), c) / std::sqrt(rc()); }
  Vector3d N(double t) const { return {-std::cos(t), -std::sin(t), 0}; }
  Vector3d B(double t) const { return Vector3d(c * std::sin(t), -c * std::cos(t), r) / std::sqrt(rc()); }
};

core::PathSpec helix_spec(const Helix& h, int frames, DerivativeConvention convention, BlendMethod blend) {
  std::vector<core::KeyFrame> f;
  for (int i = 0; i < frames; ++i) {
    const double t = i * h.dt;
    f.push_back(Frame(h.p(t), h.T(t)).normal(h.N(t)).binormal(h.B(t)).curvature(h.kappa()).torsion(h.tau())
                    .curvature_derivative(0).torsion_derivative(0).scale(h.speed()));
  }
  return make_spec(f, convention, blend);
}

TEST(ClosedForm, HelixFramesHaveHelixGeometry) {
  const Helix h;
  for (const auto convention : {DerivativeConvention::kPerArcLength, DerivativeConvention::kPerParameter}) {
    for (const auto blend : kBlends) {
      SCOPED_TRACE(blend_name(blend));
      const core::Path path = build_or_fail(helix_spec(h, 4, convention, blend));
      const auto achieved = core::achieved_geometry(path);
      ASSERT_EQ(achieved.size(), 4u);
      for (std::size_t i = 0; i < achieved.size(); ++i) {
        const double t = static_cast<double>(i) * h.dt;
        for (const auto& side : {achieved[i].approach, achieved[i].leave}) {
          if (!side) continue;
          SCOPED_TRACE("frame " + std::to_string(i));
          ASSERT_TRUE(side->has_normal);
          EXPECT_NEAR(side->speed, h.speed(), 1e-9);
          EXPECT_NEAR(side->kappa, h.kappa(), 1e-9 * h.kappa());
          EXPECT_NEAR(side->tau, h.tau(), 1e-9 * h.tau());
          EXPECT_NEAR(side->kappa_ds, 0.0, 1e-9);
          EXPECT_NEAR(side->tau_ds, 0.0, 1e-9);
          EXPECT_TRUE(VecNear(side->T, h.T(t), 1e-9));
          EXPECT_TRUE(VecNear(side->N, h.N(t), 1e-9));
          EXPECT_TRUE(VecNear(side->B, h.B(t), 1e-9));
        }
        EXPECT_TRUE(VecNear(achieved[i].p_W, h.p(t), 1e-12));
      }
      const auto err = core::closed_loop_error(path, achieved);
      EXPECT_LT(err.max_error, 1e-9) << err.worst_field;
    }
  }
}

// ---------------------------------------------------------------------------------------
// Circle of radius R in a tilted plane, closed, four frames a quarter turn apart, tau = 0
// given: every derivative lies in the plane, so the whole curve is planar (tau = 0 along it,
// constant binormal) and the frames have kappa = 1/R.

struct Circle {
  double R = 0.5;
  Vector3d center{0.3, -0.1, 0.8};
  Vector3d e1 = Vector3d(1, 1, 0).normalized();
  Vector3d e2 = Vector3d(-1, 1, 1).normalized();
  Vector3d normal() const { return e1.cross(e2); }
  Vector3d p(double t) const { return center + R * (std::cos(t) * e1 + std::sin(t) * e2); }
  Vector3d T(double t) const { return -std::sin(t) * e1 + std::cos(t) * e2; }
  Vector3d N(double t) const { return -(std::cos(t) * e1 + std::sin(t) * e2); }
};

TEST(ClosedForm, CircleIsPlanarWithConstantCurvature) {
  const Circle c;
  ASSERT_NEAR(c.e1.dot(c.e2), 0.0, 1e-15);
  for (const auto blend : kBlends) {
    SCOPED_TRACE(blend_name(blend));
    std::vector<core::KeyFrame> frames;
    for (int i = 0; i < 4; ++i) {
      const double t = i * std::numbers::pi / 2;
      frames.push_back(Frame(c.p(t), c.T(t)).normal(c.N(t)).curvature(1 / c.R).torsion(0).scale(c.R * std::numbers::pi / 2));
    }
    const core::Path path = build_or_fail(make_spec(frames, DerivativeConvention::kPerArcLength, blend, /*closed=*/true));
    ASSERT_EQ(path.segment_count(), 4u);
    const auto achieved = core::achieved_geometry(path);
    for (const auto& a : achieved) {
      for (const auto& side : {a.approach, a.leave}) {
        ASSERT_TRUE(side && side->has_normal);
        EXPECT_NEAR(side->kappa, 1 / c.R, 1e-9);
        EXPECT_NEAR(side->tau, 0.0, 1e-9);
        EXPECT_TRUE(VecNear(side->B, c.normal(), 1e-9));
      }
    }
    EXPECT_LT(core::closed_loop_error(path, achieved).max_error, 1e-9);
    for (const auto& pt : core::analyze(path, 401)) {
      EXPECT_NEAR((pt.p_W - c.center).dot(c.normal()), 0.0, 1e-12) << "u = " << pt.u;
      ASSERT_TRUE(pt.geometry.has_normal) << "u = " << pt.u;
      EXPECT_NEAR(pt.geometry.tau, 0.0, 1e-9) << "u = " << pt.u;
      EXPECT_TRUE(VecNear(pt.geometry.B, c.normal(), 1e-9)) << "u = " << pt.u;
    }
  }
}

// ---------------------------------------------------------------------------------------
// Three collinear frames with the tangent along the line and different tangent scales (so
// d2p/du2 is not zero, but along the line): the curve stays on the line, its curvature is 0
// everywhere and analyze reports no normal.

TEST(ClosedForm, StraightLineHasNoCurvature) {
  const Vector3d origin(0.3, -0.2, 0.1), d = Vector3d(1, 2, 2) / 3.0;
  for (const auto blend : kBlends) {
    SCOPED_TRACE(blend_name(blend));
    const core::Path path = build_or_fail(make_spec(
        {Frame(origin, d).scale(0.7), Frame(origin + 1.0 * d, d).scale(1.3), Frame(origin + 2.5 * d, d).scale(2.0)},
        DerivativeConvention::kPerArcLength, blend));
    for (const auto& pt : core::analyze(path, 1001)) {
      const Vector3d off = (pt.p_W - origin) - (pt.p_W - origin).dot(d) * d;
      EXPECT_LT(off.norm(), 1e-12) << "u = " << pt.u;
      EXPECT_TRUE(pt.geometry.regular) << "u = " << pt.u;
      EXPECT_FALSE(pt.geometry.has_normal) << "u = " << pt.u << ", kappa = " << pt.geometry.kappa;
      EXPECT_EQ(pt.geometry.kappa, 0.0) << "u = " << pt.u;
    }
    EXPECT_LT(core::closed_loop_error(path, core::achieved_geometry(path)).max_error, 1e-9);
  }
}

// ---------------------------------------------------------------------------------------
// A straight segment whose tangents point along it with tangent scale = its length d: the
// blend is p(u) = p0 + u (p1 - p0), so the arc length is d (1e-12 relative).

TEST(ClosedForm, StraightSegmentArcLengthIsDistance) {
  const Vector3d p0(0.1, 0.2, 0.3), p1 = p0 + Vector3d(0.3, -0.4, 1.2);
  const double d = (p1 - p0).norm();
  const Vector3d T = (p1 - p0) / d;
  struct Variant {
    const char* name;
    BlendMethod blend;
    bool with_zero_curvature;
  };
  for (const Variant v : {Variant{"cubic", BlendMethod::kPolynomial, false}, Variant{"quintic", BlendMethod::kPolynomial, true},
                          Variant{"trapezoid", BlendMethod::kTrapezoidal, false},
                          Variant{"trapezoid, kappa = 0", BlendMethod::kTrapezoidal, true}}) {
    SCOPED_TRACE(v.name);
    Frame a(p0, T), b(p1, T);
    a.scale(d);
    b.scale(d);
    if (v.with_zero_curvature) {
      a.curvature(0);
      b.curvature(0);
    }
    const core::Path path = build_or_fail(make_spec({a, b}, DerivativeConvention::kPerArcLength, v.blend));
    EXPECT_NEAR(path.length(), d, 1e-12 * d);
    EXPECT_NEAR(core::arc_length_at(path, 0.37), 0.37 * d, 1e-12 * d);
    EXPECT_NEAR(core::parameter_at(path, 0.61 * d), 0.61, 1e-12);
    EXPECT_TRUE(VecNear(core::evaluate(path, 0.37)[0], p0 + 0.37 * (p1 - p0), 1e-15));
  }
}

}  // namespace
}  // namespace geotraj::test
