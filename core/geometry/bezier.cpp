#include "core/geometry/bezier.hpp"

#include "core/error.hpp"

namespace geotraj::core {

using Eigen::Vector3d;

BezierSegment hermite_bezier(const Jet& start, int n0, const Jet& end, int n1) {
  GEOTRAJ_CHECK(n0 >= 0 && n0 <= kMaxJetOrder && n1 >= 0 && n1 <= kMaxJetOrder);
  BezierSegment seg;
  const int d = n0 + n1 + 1;  // App. B.2: n0 + n1 + 2 conditions
  seg.degree = d;
  hermite_control_points(start, n0, end, n1, seg.b);
  const auto& b = seg.b;
  // Hodographs d!/(d-k)! Delta^k b, then scaled by their binomial coefficients.
  seg.h[0] = b;
  for (int k = 1; k <= kMaxJetOrder && k <= d; ++k) {
    for (int i = 0; i <= d - k; ++i) seg.h[k][i] = (d - k + 1) * (seg.h[k - 1][i + 1] - seg.h[k - 1][i]);
  }
  // The end points of hodograph k are the end derivatives themselves: take the data, not its
  // rounded differences, so that the ends are exact (C(d-k, 0) = C(d-k, d-k) = 1).
  for (int k = 1; k <= n0; ++k) seg.h[k][0] = start[k];
  for (int k = 1; k <= n1; ++k) seg.h[k][d - k] = end[k];
  for (int k = 0; k <= kMaxJetOrder && k <= d; ++k) {
    for (int i = 0; i <= d - k; ++i) seg.h[k][i] *= binomial(d - k, i);
  }
  return seg;
}

Vector3d bernstein_sum(const Vector3d* c, int m, double u) {
  if (m == 0) return c[0];
  const double v = 1.0 - u;
  Vector3d acc;
  double scale;  // (1-u)^m or u^m
  if (u <= 0.5) {
    const double r = u / v;  // in [0, 1]
    acc = c[m];
    for (int i = m - 1; i >= 0; --i) acc = acc * r + c[i];
    scale = v;
  } else {
    const double r = v / u;  // in [0, 1)
    acc = c[0];
    for (int i = 1; i <= m; ++i) acc = acc * r + c[i];
    scale = u;
  }
  double p = scale;
  for (int i = 1; i < m; ++i) p *= scale;
  return p * acc;
}

void evaluate(const BezierSegment& seg, double u, int max_order, Jet& jet) {
  const int d = seg.degree;
  for (int k = 0; k <= max_order; ++k) {
    jet[k] = k <= d ? bernstein_sum(seg.h[k].data(), d - k, u) : Vector3d::Zero();
  }
}

}  // namespace geotraj::core
