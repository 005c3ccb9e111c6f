#include "core/geometry/trapezoid.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "core/error.hpp"

namespace geotraj::core {

namespace {

constexpr double kFactorial[] = {1.0, 1.0, 2.0, 6.0, 24.0, 120.0, 720.0, 5040.0};

// m-fold integral from 0 of the unit ramp R(u) that is 0 before a, rises linearly to 1 at
// b and stays 1 (singularity functions, Eq. B.6):
//   J_m(u) = (<u - a>^(m+1) - <u - b>^(m+1)) / ((m + 1)! (b - a)).
// Evaluated without cancellation: on the ramp x^(m+1)/(b - a) with x < b - a, after it
// (x^(m+1) - y^(m+1)) / (x - y) = sum_i x^i y^(m-i), which also covers b = a (a step).
double ramp_integral(int m, double u, double a, double b) {
  const double x = u - a;
  if (x <= 0.0) return 0.0;
  const double y = u - b;
  if (y < 0.0) {
    double xm = x;
    for (int i = 0; i < m; ++i) xm *= x;
    return xm / ((b - a) * kFactorial[m + 1]);
  }
  double y_pow[kMaxTrapezoidOrder + 2];
  y_pow[0] = 1.0;
  for (int k = 1; k <= m; ++k) y_pow[k] = y_pow[k - 1] * y;
  double sum = 0.0, x_pow = 1.0;
  for (int i = 0; i <= m; ++i) {
    sum += x_pow * y_pow[m - i];
    x_pow *= x;
  }
  return sum / kFactorial[m + 1];
}

// Slope of the unit ramp (derivative n + 1 of the profile): 1/(b - a) on [a, b).
double ramp_slope(double u, double a, double b) { return (u >= a && u < b && b > a) ? 1.0 / (b - a) : 0.0; }

// Taylor polynomial of the start state for derivative q: sum_k start[q+k] u^k / k!.
double start_part(const TrapezoidAxis& t, int q, double u) {
  double sum = 0.0, uk = 1.0;
  for (int k = 0; q + k < t.n; ++k) {
    sum += t.start[q + k] * uk / kFactorial[k];
    uk *= u;
  }
  return sum;
}

}  // namespace

std::array<double, 2 * kMaxTrapezoidOrder + 2> uniform_breakpoints(int n) {
  GEOTRAJ_CHECK(n >= 1 && n <= kMaxTrapezoidOrder);
  std::array<double, 2 * kMaxTrapezoidOrder + 2> u{};
  for (int k = 0; k <= 2 * n + 1; ++k) u[k] = static_cast<double>(k) / (2 * n + 1);  // (B.10)
  return u;
}

tl::expected<TrapezoidAxis, std::string> make_trapezoid(int n, std::span<const double> breakpoints,
                                                        std::span<const double> start,
                                                        std::span<const double> end) {
  GEOTRAJ_CHECK(n >= 1 && n <= kMaxTrapezoidOrder);
  GEOTRAJ_CHECK(breakpoints.size() == static_cast<std::size_t>(2 * n + 2));
  GEOTRAJ_CHECK(start.size() >= static_cast<std::size_t>(n) && end.size() >= static_cast<std::size_t>(n));
  TrapezoidAxis t;
  t.n = n;
  std::copy(breakpoints.begin(), breakpoints.end(), t.u.begin());
  std::copy(start.begin(), start.begin() + n, t.start.begin());
  std::copy(end.begin(), end.begin() + n, t.end.begin());

  // Ramp r = 1..n+1 spans [u_{2r-2}, u_{2r-1}] and has height c_r = A_r - A_{r-1}
  // (A_0 = 0, c_{n+1} = -A_n). End condition on derivative q = 0..n-1 at u = 1:
  //   sum_r c_r J_{n-q}(1; r) = end[q] - sum_k start[q+k] / k!     (B.7, B.9)
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxTrapezoidOrder, kMaxTrapezoidOrder> M(n, n);
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxTrapezoidOrder, 1> rhs(n);
  for (int q = 0; q < n; ++q) {
    rhs(q) = end[q] - start_part(t, q, 1.0);
    for (int j = 1; j <= n; ++j) {
      const int m = n - q;  // derivative q is the m-fold integral of derivative n
      const double own = ramp_integral(m, 1.0, t.u[2 * j - 2], t.u[2 * j - 1]);
      const double next = ramp_integral(m, 1.0, t.u[2 * j], t.u[2 * j + 1]);
      M(q, j - 1) = own - next;
    }
  }
  const Eigen::FullPivLU<decltype(M)> lu(M);
  if (lu.rank() < n || lu.rcond() < 1e-13) {
    return tl::unexpected(std::string("these breakpoints cannot meet the end conditions (the level equations are singular)"));
  }
  auto A = lu.solve(rhs).eval();
  A += lu.solve((rhs - M * A).eval());  // one step of iterative refinement
  double prev = 0.0;
  for (int j = 0; j < n; ++j) {
    t.c[j] = A(j) - prev;
    prev = A(j);
  }
  t.c[n] = -prev;
  return t;
}

void evaluate(const TrapezoidAxis& t, double u, int max_order, double* out) {
  const int n = t.n;
  const bool backward = u > 0.5;  // integrate from the nearer end: exact at u = 0 and u = 1
  const double w = 1.0 - u;
  for (int q = 0; q <= max_order; ++q) {
    double v = 0.0;
    if (q <= n && !backward) {
      v = start_part(t, q, u);
      for (int r = 1; r <= n + 1; ++r) v += t.c[r - 1] * ramp_integral(n - q, u, t.u[2 * r - 2], t.u[2 * r - 1]);
    } else if (q <= n) {
      // Taylor from the end state, plus the ramps integrated from u = 1 backwards:
      // x^(q)(u) = sum_k end[q+k] (u-1)^k/k! - (-1)^(n-q) sum_r c_r J_(n-q)(1-u; 1-b_r, 1-a_r)
      double uk = 1.0;
      for (int k = 0; q + k < n; ++k) {
        v += t.end[q + k] * uk / kFactorial[k];
        uk *= -w;
      }
      const double sign = (n - q) % 2 ? -1.0 : 1.0;
      for (int r = 1; r <= n + 1; ++r)
        v -= sign * t.c[r - 1] * ramp_integral(n - q, w, 1.0 - t.u[2 * r - 1], 1.0 - t.u[2 * r - 2]);
    } else if (q == n + 1) {
      for (int r = 1; r <= n + 1; ++r) v += t.c[r - 1] * ramp_slope(u, t.u[2 * r - 2], t.u[2 * r - 1]);
    }
    out[q] = v;
  }
}

}  // namespace geotraj::core
