// The TRAPEZOIDAL blend (App. B, Tesar and Matthew): make_trapezoid meets the end conditions
// on derivatives 0..n-1 with a zero n-th derivative at both ends, for the breakpoints of
// Eqs. (B.10), (B.11) and (B.13) and random ones, and evaluate's derivatives agree with
// central differences of the derivative below.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/trapezoid.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::kMaxTrapezoidOrder;
using core::TrapezoidAxis;

using Values = std::vector<double>;

/// Derivatives 0..max_order of `axis` at u.
std::array<double, kMaxTrapezoidOrder + 2> eval(const TrapezoidAxis& axis, double u) {
  std::array<double, kMaxTrapezoidOrder + 2> out{};
  core::evaluate(axis, u, axis.n + 1, out.data());
  return out;
}

/// Largest magnitude in the problem: end data and the trapezoid's ramp heights.
double magnitude(const TrapezoidAxis& axis, const Values& start, const Values& end) {
  double m = 1.0;
  for (double v : start) m = std::max(m, std::abs(v));
  for (double v : end) m = std::max(m, std::abs(v));
  for (int r = 0; r <= axis.n; ++r) m = std::max(m, std::abs(axis.c[r]));
  return m;
}

/// Meets start and end on derivatives 0..n-1; the n-th derivative is 0 at both ends.
/// Tolerance 1e-12 relative to the problem's magnitude (a 5x5 solve with one refinement).
void ExpectMeetsEnds(int n, const Values& breakpoints, const Values& start, const Values& end) {
  SCOPED_TRACE("order " + std::to_string(n));
  const auto axis = core::make_trapezoid(n, breakpoints, start, end);
  ASSERT_TRUE(axis) << axis.error();
  ASSERT_EQ(axis->n, n);
  const double tol = 1e-12 * magnitude(*axis, start, end);
  const auto at0 = eval(*axis, 0.0), at1 = eval(*axis, 1.0);
  for (int k = 0; k < n; ++k) {
    EXPECT_NEAR(at0[k], start[k], tol) << "derivative " << k << " at u = 0";
    EXPECT_NEAR(at1[k], end[k], tol) << "derivative " << k << " at u = 1";
  }
  EXPECT_NEAR(at0[n], 0.0, tol) << "derivative " << n << " at u = 0";
  EXPECT_NEAR(at1[n], 0.0, tol) << "derivative " << n << " at u = 1";
}

Values uniform(int n) {
  const auto u = core::uniform_breakpoints(n);
  return Values(u.begin(), u.begin() + 2 * n + 2);
}

Values random_values(std::mt19937_64& rng, int n) {
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  Values v(n);
  for (int k = 0; k < n; ++k) v[k] = d(rng) * std::pow(3.0, k);
  return v;
}

// (B.10), printed to 3 digits for n = 4.
TEST(Trapezoid, UniformBreakpointsAreB10) {
  const Printed printed[] = {"0", "0.111", "0.222", "0.333", "0.444", "0.556", "0.667", "0.778", "0.889", "1.00"};
  const Values u = uniform(4);
  ASSERT_EQ(u.size(), 10u);
  for (std::size_t k = 0; k < u.size(); ++k) EXPECT_NEAR(u[k], printed[k].value, printed[k].tol) << k;
  EXPECT_EQ(u.front(), 0.0);
  EXPECT_EQ(u.back(), 1.0);
}

TEST(Trapezoid, UniformMeetsEndsForEveryOrder) {
  std::mt19937_64 rng(kPropertySeed);
  for (int n = 1; n <= kMaxTrapezoidOrder; ++n) {
    for (int trial = 0; trial < 10; ++trial) ExpectMeetsEnds(n, uniform(n), random_values(rng, n), random_values(rng, n));
  }
}

// Table 5.1 and Figure 5.2: the x constraints met by a 3rd-order trapezoid, whose 3rd
// derivative is zero at both ends, as the table prints.
TEST(Trapezoid, Table5_1) { ExpectMeetsEnds(3, uniform(3), {-1.0, -6.0, -30.0}, {2.0, 3.0, -20.0}); }

// (B.11): the hand-tuned breakpoints of Appendix B for the 4th-order trapezoid.
const Values kB11 = {0, 0.02, 0.24, 0.26, 0.49, 0.51, 0.74, 0.76, 0.98, 1.00};

TEST(Trapezoid, B11MeetsEnds) {
  std::mt19937_64 rng(kPropertySeed + 1);
  for (int trial = 0; trial < 20; ++trial) ExpectMeetsEnds(4, kB11, random_values(rng, 4), random_values(rng, 4));
}

// (B.13): per-axis breakpoints on the path's second segment, u in [1, 2]; shifted by -1 to
// the segment's local u in [0, 1].
TEST(Trapezoid, B13MeetsEnds) {
  const Values printed[] = {
      {1.0, 1.02, 1.34, 1.36, 1.69, 1.71, 1.84, 1.86, 1.98, 2.00},  // x
      {1.0, 1.02, 1.24, 1.26, 1.49, 1.51, 1.74, 1.86, 1.98, 2.00},  // y
      {1.0, 1.02, 1.14, 1.16, 1.39, 1.41, 1.74, 1.86, 1.98, 2.00},  // z
  };
  std::mt19937_64 rng(kPropertySeed + 2);
  for (const auto& global : printed) {
    Values local(global.size());
    std::transform(global.begin(), global.end(), local.begin(), [](double u) { return u - 1.0; });
    ASSERT_TRUE(std::is_sorted(local.begin(), local.end()));
    for (int trial = 0; trial < 10; ++trial) ExpectMeetsEnds(4, local, random_values(rng, 4), random_values(rng, 4));
  }
}

TEST(Trapezoid, RandomBreakpointsMeetEnds) {
  std::mt19937_64 rng(kPropertySeed + 3);
  std::uniform_real_distribution<double> ud(0.0, 1.0);
  for (int n = 1; n <= kMaxTrapezoidOrder; ++n) {
    for (int trial = 0; trial < 20; ++trial) {
      Values u(2 * n + 2);
      for (auto& v : u) v = ud(rng);
      std::sort(u.begin(), u.end());
      u.front() = 0.0;
      u.back() = 1.0;
      u[1] = std::max(u[1], 0.05);  // the first ramp needs a width
      std::sort(u.begin(), u.end());
      ExpectMeetsEnds(n, u, random_values(rng, n), random_values(rng, n));
    }
  }
}

// u_k == u_{k+1}: a ramp of zero width is a step of the n-th derivative.
TEST(Trapezoid, ZeroWidthInteriorRampsMeetEnds) {
  std::mt19937_64 rng(kPropertySeed + 4);
  const Values order3 = {0, 0.1, 0.3, 0.3, 0.6, 0.6, 0.9, 1.0};
  const Values order4 = {0, 0.05, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 0.95, 1.0};
  const Values order2 = {0, 0.2, 0.5, 0.5, 0.8, 1.0};
  for (int trial = 0; trial < 10; ++trial) {
    ExpectMeetsEnds(2, order2, random_values(rng, 2), random_values(rng, 2));
    ExpectMeetsEnds(3, order3, random_values(rng, 3), random_values(rng, 3));
    ExpectMeetsEnds(4, order4, random_values(rng, 4), random_values(rng, 4));
  }
  // The n-th derivative steps at the zero-width ramp and is continuous below it.
  const auto axis = core::make_trapezoid(3, order3, Values{0, 1, 0}, Values{1, 0, -1});
  ASSERT_TRUE(axis) << axis.error();
  const auto before = eval(*axis, 0.3 - 1e-9), after = eval(*axis, 0.3 + 1e-9);
  EXPECT_NEAR(after[3] - before[3], axis->c[1], 1e-6 * std::abs(axis->c[1]));
  EXPECT_NEAR(after[2], before[2], 1e-6);
}

TEST(Trapezoid, SingularBreakpointsAreAnError) {
  // Ramps 2 and 3 are the same step at u = 0.5, so level A_2 (which rises with ramp 2 and
  // falls with ramp 3) has no effect: its column of the level equations vanishes.
  const Values degenerate = {0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 1.0};
  const auto axis = core::make_trapezoid(3, degenerate, Values{0, 0, 0}, Values{1, 0, 0});
  ASSERT_FALSE(axis);
  EXPECT_NE(axis.error().find("singular"), std::string::npos) << axis.error();
}

// Central differences of derivative k against derivative k + 1 at random u at least h away
// from every breakpoint (derivative n + 1 jumps there). Between breakpoints derivative n is
// linear, so derivative k is a polynomial and the truncation error is h^2/6 |d^(k+3)|, zero
// unless k + 3 <= n + 1. Step h = 1e-6; tolerance = h^2/6 M_(k+3) + 64 eps M_k / h, with
// M_j the largest |d^j| over a fine grid, doubled.
TEST(Trapezoid, DerivativesMatchCentralDifferences) {
  constexpr double h = 1e-6;
  constexpr double eps = std::numeric_limits<double>::epsilon();
  std::mt19937_64 rng(kPropertySeed + 5);
  std::uniform_real_distribution<double> ud(0.0, 1.0);
  for (int n = 1; n <= kMaxTrapezoidOrder; ++n) {
    for (const Values& bp : {uniform(n), n == 4 ? kB11 : uniform(n)}) {
      const auto axis = core::make_trapezoid(n, bp, random_values(rng, n), random_values(rng, n));
      ASSERT_TRUE(axis) << axis.error();
      std::array<double, kMaxTrapezoidOrder + 4> M{};  // M[j] = 0 above n + 1
      for (int i = 0; i <= 1000; ++i) {
        const auto v = eval(*axis, i / 1000.0);
        for (int j = 0; j <= n + 1; ++j) M[j] = std::max(M[j], 2 * std::abs(v[j]));
      }
      for (int trial = 0; trial < 20; ++trial) {
        const double u = ud(rng);
        if (std::any_of(bp.begin(), bp.end(), [&](double b) { return std::abs(u - b) <= 2 * h; })) continue;
        const auto lo = eval(*axis, u - h), mid = eval(*axis, u), hi = eval(*axis, u + h);
        for (int k = 0; k <= n; ++k) {
          const double tol = h * h / 6 * M[k + 3] + 64 * eps * std::max(M[k], 1.0) / h;
          EXPECT_NEAR((hi[k] - lo[k]) / (2 * h), mid[k + 1], tol) << "order " << n << ", derivative " << k + 1
                                                                   << " at u = " << u;
        }
      }
    }
  }
}

TEST(Trapezoid, DerivativesAboveSlopeAreZero) {
  const auto axis = core::make_trapezoid(2, uniform(2), Values{0, 1}, Values{1, 1});
  ASSERT_TRUE(axis) << axis.error();
  double out[5];
  core::evaluate(*axis, 0.3, 4, out);
  EXPECT_EQ(out[4], 0.0);
}

}  // namespace
}  // namespace geotraj::test
