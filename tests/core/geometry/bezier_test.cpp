// The POLYNOMIAL blend (App. B.2) in Bernstein form: hermite_bezier meets its end data, and
// evaluate's derivatives agree with central differences of the derivative below.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "core/geometry/bezier.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::BezierSegment;
using core::Jet;
using core::kMaxJetOrder;

Jet random_jet(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  Jet jet;
  for (int k = 0; k <= kMaxJetOrder; ++k) jet[k] = scale * Vector3d(d(rng), d(rng), d(rng)) * std::pow(3.0, k);
  return jet;
}

double falling(int d, int k) {
  double r = 1.0;
  for (int i = 0; i < k; ++i) r *= d - i;
  return r;
}

/// Bound on |d^k p/du^k| over [0, 1]: d!/(d-k)! max|Delta^k b| <= d!/(d-k)! 2^k max|b|.
double derivative_bound(const BezierSegment& seg, int k) {
  double largest = 0.0;
  for (int i = 0; i <= seg.degree; ++i) largest = std::max(largest, seg.b[i].cwiseAbs().maxCoeff());
  return k > seg.degree ? 0.0 : falling(seg.degree, k) * std::pow(2.0, k) * largest;
}

TEST(Bezier, HermiteMeetsEndDataExactly) {
  std::mt19937_64 rng(kPropertySeed);
  for (int n0 = 0; n0 <= kMaxJetOrder; ++n0) {
    for (int n1 = 0; n1 <= kMaxJetOrder; ++n1) {
      SCOPED_TRACE("n0 = " + std::to_string(n0) + ", n1 = " + std::to_string(n1));
      const Jet start = random_jet(rng, 1.0), end = random_jet(rng, 1.0);
      const BezierSegment seg = core::hermite_bezier(start, n0, end, n1);
      EXPECT_EQ(seg.degree, n0 + n1 + 1);
      Jet at0, at1;
      core::evaluate(seg, 0.0, kMaxJetOrder, at0);
      core::evaluate(seg, 1.0, kMaxJetOrder, at1);
      // 1e-12 relative to the data: the construction is exact up to a few roundings.
      for (int k = 0; k <= n0; ++k) EXPECT_TRUE(VecNear(at0[k], start[k], 1e-12 * start[k].norm())) << "start " << k;
      for (int k = 0; k <= n1; ++k) EXPECT_TRUE(VecNear(at1[k], end[k], 1e-12 * end[k].norm())) << "end " << k;
    }
  }
}

TEST(Bezier, CubicHermiteMatchesPowerBasis) {
  // App. B.4: p(u) = p0 + p0' u + (3(p1 - p0) - 2 p0' - p1') u^2 + (2(p0 - p1) + p0' + p1') u^3.
  Jet start{}, end{};
  for (auto* j : {&start, &end})
    for (auto& v : *j) v.setZero();
  start[0] = {0.5, -1, 2};
  start[1] = {1, 2, -3};
  end[0] = {2, 1, 0};
  end[1] = {-1, 0, 4};
  const BezierSegment seg = core::hermite_bezier(start, 1, end, 1);
  const Vector3d a2 = 3 * (end[0] - start[0]) - 2 * start[1] - end[1];
  const Vector3d a3 = 2 * (start[0] - end[0]) + start[1] + end[1];
  for (const double u : {0.0, 0.1, 0.37, 0.5, 0.9, 1.0}) {
    Jet jet;
    core::evaluate(seg, u, 3, jet);
    EXPECT_TRUE(VecNear(jet[0], start[0] + start[1] * u + a2 * u * u + a3 * u * u * u, 1e-14)) << u;
    EXPECT_TRUE(VecNear(jet[1], start[1] + 2 * a2 * u + 3 * a3 * u * u, 1e-13)) << u;
    EXPECT_TRUE(VecNear(jet[2], 2 * a2 + 6 * a3 * u, 1e-13)) << u;
    EXPECT_TRUE(VecNear(jet[3], 6 * a3, 1e-13)) << u;
  }
}

TEST(Bezier, OrdersAboveDegreeAreZero) {
  std::mt19937_64 rng(kPropertySeed + 1);
  const BezierSegment seg = core::hermite_bezier(random_jet(rng, 1.0), 0, random_jet(rng, 1.0), 1);  // quadratic
  ASSERT_EQ(seg.degree, 2);
  Jet jet;
  core::evaluate(seg, 0.3, kMaxJetOrder, jet);
  EXPECT_EQ(jet[3], Vector3d::Zero());
  EXPECT_EQ(jet[4], Vector3d::Zero());
}

// Central differences: (p^(k)(u + h) - p^(k)(u - h)) / 2h = p^(k+1)(u) + h^2/6 p^(k+3)(xi).
// Step h = 1e-5; tolerance = h^2/6 * bound(k + 3) (truncation) + 64 eps bound(k) / h
// (rounding of the two evaluations), with the control-polygon bounds above.
TEST(Bezier, DerivativesMatchCentralDifferences) {
  constexpr double h = 1e-5;
  constexpr double eps = std::numeric_limits<double>::epsilon();
  std::mt19937_64 rng(kPropertySeed + 2);
  std::uniform_real_distribution<double> ud(h, 1.0 - h);
  for (int n0 = 0; n0 <= kMaxJetOrder; ++n0) {
    for (int n1 = 0; n1 <= kMaxJetOrder; ++n1) {
      const BezierSegment seg = core::hermite_bezier(random_jet(rng, 1.0), n0, random_jet(rng, 1.0), n1);
      for (int trial = 0; trial < 5; ++trial) {
        const double u = ud(rng);
        Jet lo, mid, hi;
        core::evaluate(seg, u - h, kMaxJetOrder, lo);
        core::evaluate(seg, u, kMaxJetOrder, mid);
        core::evaluate(seg, u + h, kMaxJetOrder, hi);
        for (int k = 0; k < kMaxJetOrder; ++k) {
          const double tol = h * h / 6 * derivative_bound(seg, k + 3) + 64 * eps * derivative_bound(seg, k) / h;
          EXPECT_TRUE(VecNear((hi[k] - lo[k]) / (2 * h), mid[k + 1], tol))
              << "degree " << seg.degree << ", derivative " << k + 1 << " at u = " << u;
        }
      }
    }
  }
}

}  // namespace
}  // namespace geotraj::test
