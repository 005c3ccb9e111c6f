// The POLYNOMIAL blend (thesis App. B.2, Eq. B.5) held in Bernstein (Bezier) form: the
// lowest-degree polynomial that meets derivatives 0..n0 at u = 0 and 0..n1 at u = 1 has
// degree n0 + n1 + 1, and its Bernstein coefficients follow from the end derivatives in
// closed form (no linear solve). Evaluation by de Casteljau, which is numerically stable
// on [0, 1] and yields every derivative from the same pass.
#pragma once

#include <array>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace geotraj::core {

/// Derivatives of a curve at one parameter value: jet[0] = p, jet[k] = d^k p/du^k [m].
using Jet = std::array<Eigen::Vector3d, 5>;

inline constexpr int kMaxJetOrder = 4;
inline constexpr int kMaxBezierDegree = 9;  // n0 = n1 = 4

/// A vector-valued polynomial segment on u in [0, 1] in Bernstein form.
struct BezierSegment {
  int degree = 1;
  std::array<Eigen::Vector3d, kMaxBezierDegree + 1> b{};  ///< control points [m]
  /// Hodographs, pre-scaled for evaluation: h[k][i] = C(d-k, i) d!/(d-k)! Delta^k b_i,
  /// i.e. the degree d-k control points of d^k p/du^k times their binomial coefficient.
  /// Computed once by hermite_bezier.
  std::array<std::array<Eigen::Vector3d, kMaxBezierDegree + 1>, kMaxJetOrder + 1> h{};
};

/// Binomial coefficient C(n, k), as a double.
constexpr double binomial(int n, int k) {
  double r = 1.0;
  for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
  return r;
}

/// d! / (d - k)!: the factor between the k-th derivative of a degree-d Bezier curve and the
/// k-th forward differences of its control points.
constexpr double falling_factorial(int d, int k) {
  double r = 1.0;
  for (int i = 0; i < k; ++i) r *= d - i;
  return r;
}

/// The control points b_0..b_d (d = n0 + n1 + 1) of the lowest-degree polynomial with the
/// given end derivatives (App. B.2 in Bernstein form): start[k] = d^k p/du^k (0) for
/// k = 0..n0 and end[k] at u = 1 for k = 0..n1, from
///   p^(k)(0) = d!/(d-k)! sum_j (-1)^(k-j) C(k,j) b_j      (forward differences)
///   p^(k)(1) = d!/(d-k)! sum_j (-1)^j C(k,j) b_{d-j}      (backward differences).
/// Linear in the end data. Generic in the vector type V (an Eigen 3-vector of double, or of a
/// dual number for automatic differentiation); entries above d are left untouched.
/// Preconditions: 0 <= n0, n1 <= 4.
template <class V>
void hermite_control_points(const std::array<V, kMaxJetOrder + 1>& start, int n0,
                            const std::array<V, kMaxJetOrder + 1>& end, int n1,
                            std::array<V, kMaxBezierDegree + 1>& b) {
  const int d = n0 + n1 + 1;  // App. B.2: n0 + n1 + 2 conditions
  for (int k = 0; k <= n0; ++k) {
    V acc = start[k] / falling_factorial(d, k);
    for (int j = 0; j < k; ++j) acc -= b[j] * (((k - j) % 2 ? -1.0 : 1.0) * binomial(k, j));
    b[k] = acc;
  }
  for (int k = 0; k <= n1; ++k) {
    V acc = end[k] / falling_factorial(d, k);
    for (int j = 0; j < k; ++j) acc -= b[d - j] * ((j % 2 ? -1.0 : 1.0) * binomial(k, j));
    b[d - k] = acc * (k % 2 ? -1.0 : 1.0);
  }
}

/// Hermite data at both ends: start[k] = d^k p/du^k (0) for k = 0..n0, end[k] likewise at
/// u = 1 for k = 0..n1. Degree n0 + n1 + 1. Preconditions: 0 <= n0, n1 <= 4.
BezierSegment hermite_bezier(const Jet& start, int n0, const Jet& end, int n1);

/// Fills jet[0..max_order] at u in [0, 1]. Orders above the degree are zero. Each order is
/// a Bernstein sum of its hodograph, evaluated by Horner's rule in u/(1-u) (u <= 1/2) or
/// (1-u)/u (u > 1/2): O(d) per order, with the stability of the Bernstein basis.
void evaluate(const BezierSegment& seg, double u, int max_order, Jet& jet);

/// The Bernstein sum  sum_i c_i u^i (1-u)^(m-i)  of degree m, with c_i already multiplied
/// by C(m, i) (as BezierSegment::h); see evaluate.
Eigen::Vector3d bernstein_sum(const Eigen::Vector3d* c, int m, double u);

}  // namespace geotraj::core
