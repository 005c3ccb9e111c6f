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
