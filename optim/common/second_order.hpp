// Second-order forward-mode automatic differentiation in N local variables: a value with its
// exact gradient and Hessian. The optimisers' terms each depend on a few variables only (a
// tangent-scale segment on its two end scales, a jerk-timing grid point on three squared
// speeds), so their exact Hessians are sums of small dense blocks, which this type carries.
// (Ceres's nested Jet<Jet<double, N>, N> would do the same, but core's templates mix the
// scalar with double, e.g. S(1.0) and S * double, which a nested Jet does not accept.)
#pragma once

#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Core>

namespace geotraj::optim::detail {

/// Index of (r, c), c <= r, in a lower triangle stored by rows.
constexpr int tri(int r, int c) { return r * (r + 1) / 2 + c; }

template <int N>
struct SecondOrder {
  static constexpr int kHessian = N * (N + 1) / 2;

  double f = 0.0;                  ///< value
  std::array<double, N> g{};       ///< gradient
  std::array<double, kHessian> h{};  ///< Hessian, lower triangle: (r, c) at tri(r, c)

  SecondOrder() = default;
  SecondOrder(double value) : f(value) {}  // NOLINT(google-explicit-constructor): constants

  /// The variable number k (0 <= k < N) at `x`.
  static SecondOrder variable(double x, int k) {
    SecondOrder r(x);
    r.g[static_cast<std::size_t>(k)] = 1.0;
    return r;
  }

  /// phi(*this) from phi, phi', phi'' at f (chain rule to second order).
  SecondOrder chain(double f0, double f1, double f2) const {
    SecondOrder r(f0);
    for (int i = 0; i < N; ++i) r.g[i] = f1 * g[i];
    for (int i = 0; i < N; ++i)
      for (int j = 0; j <= i; ++j) r.h[tri(i, j)] = f1 * h[tri(i, j)] + f2 * g[i] * g[j];
    return r;
  }

  friend SecondOrder operator+(SecondOrder x, const SecondOrder& y) {
    x.f += y.f;
    for (int i = 0; i < N; ++i) x.g[i] += y.g[i];
    for (int i = 0; i < kHessian; ++i) x.h[i] += y.h[i];
    return x;
  }
  friend SecondOrder operator-(SecondOrder x) {
    x.f = -x.f;
    for (double& v : x.g) v = -v;
    for (double& v : x.h) v = -v;
    return x;
  }
  friend SecondOrder operator-(const SecondOrder& x, const SecondOrder& y) { return x + (-y); }
  friend SecondOrder operator*(double c, SecondOrder x) {
    x.f *= c;
    for (double& v : x.g) v *= c;
    for (double& v : x.h) v *= c;
    return x;
  }
  friend SecondOrder operator*(const SecondOrder& x, double c) { return c * x; }
  friend SecondOrder operator*(const SecondOrder& x, const SecondOrder& y) {
    SecondOrder r(x.f * y.f);
    for (int i = 0; i < N; ++i) r.g[i] = x.f * y.g[i] + y.f * x.g[i];
    for (int i = 0; i < N; ++i)
      for (int j = 0; j <= i; ++j)
        r.h[tri(i, j)] = x.f * y.h[tri(i, j)] + y.f * x.h[tri(i, j)] + x.g[i] * y.g[j] + y.g[i] * x.g[j];
    return r;
  }
  friend SecondOrder reciprocal(const SecondOrder& x) {
    const double inv = 1.0 / x.f;
    return x.chain(inv, -inv * inv, 2.0 * inv * inv * inv);
  }
  friend SecondOrder operator/(const SecondOrder& x, const SecondOrder& y) { return x * reciprocal(y); }
  SecondOrder& operator+=(const SecondOrder& y) { return *this = *this + y; }
  SecondOrder& operator-=(const SecondOrder& y) { return *this = *this - y; }
  SecondOrder& operator*=(const SecondOrder& y) { return *this = *this * y; }
  SecondOrder& operator/=(const SecondOrder& y) { return *this = *this / y; }

  // Comparisons by value (core's templates branch on them).
  friend bool operator<(const SecondOrder& x, const SecondOrder& y) { return x.f < y.f; }
  friend bool operator>(const SecondOrder& x, const SecondOrder& y) { return x.f > y.f; }
  friend bool operator<=(const SecondOrder& x, const SecondOrder& y) { return x.f <= y.f; }
  friend bool operator>=(const SecondOrder& x, const SecondOrder& y) { return x.f >= y.f; }
  friend bool operator==(const SecondOrder& x, const SecondOrder& y) { return x.f == y.f; }
  friend bool operator!=(const SecondOrder& x, const SecondOrder& y) { return x.f != y.f; }

  friend SecondOrder sqrt(const SecondOrder& x) {
    const double r = std::sqrt(x.f);
    return x.chain(r, 0.5 / r, -0.25 / (r * x.f));
  }
  friend SecondOrder pow(const SecondOrder& x, double p) {
    const double r = std::pow(x.f, p - 2.0);
    return x.chain(r * x.f * x.f, p * r * x.f, p * (p - 1.0) * r);
  }
  friend SecondOrder exp(const SecondOrder& x) {
    const double e = std::exp(x.f);
    return x.chain(e, e, e);
  }
  friend SecondOrder log(const SecondOrder& x) { return x.chain(std::log(x.f), 1.0 / x.f, -1.0 / (x.f * x.f)); }
  friend SecondOrder abs(const SecondOrder& x) { return x.f < 0.0 ? -x : x; }
};

}  // namespace geotraj::optim::detail

// Eigen vectors of SecondOrder (as ceres does for its Jet).
namespace Eigen {
template <int N>
struct NumTraits<geotraj::optim::detail::SecondOrder<N>> : GenericNumTraits<double> {
  using Real = geotraj::optim::detail::SecondOrder<N>;
  using NonInteger = Real;
  using Nested = Real;
  using Literal = Real;
  static Real dummy_precision() { return Real(1e-12); }
  static Real epsilon() { return Real(std::numeric_limits<double>::epsilon()); }
  static Real highest() { return Real(std::numeric_limits<double>::max()); }
  static Real lowest() { return Real(std::numeric_limits<double>::lowest()); }
  static int digits10() { return NumTraits<double>::digits10(); }
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    ReadCost = 1 + N + Real::kHessian,
    AddCost = 1 + N + Real::kHessian,
    MulCost = 3 * (1 + N + Real::kHessian),
    RequireInitialization = 1
  };
};
template <int N, typename BinaryOp>
struct ScalarBinaryOpTraits<geotraj::optim::detail::SecondOrder<N>, double, BinaryOp> {
  using ReturnType = geotraj::optim::detail::SecondOrder<N>;
};
template <int N, typename BinaryOp>
struct ScalarBinaryOpTraits<double, geotraj::optim::detail::SecondOrder<N>, BinaryOp> {
  using ReturnType = geotraj::optim::detail::SecondOrder<N>;
};
}  // namespace Eigen
