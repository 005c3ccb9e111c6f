#include "core/geometry/differential_geometry.hpp"

#include <cmath>

namespace geotraj::core {

using Eigen::Vector3d;

LocalGeometry local_geometry(const Jet& jet, double p_uu_noise) {
  const Vector3d& p1 = jet[1];
  const Vector3d& p2 = jet[2];
  const Vector3d& p3 = jet[3];
  const Vector3d& p4 = jet[4];
  LocalGeometry g;
  g.speed = p1.norm();
  if (!(g.speed > 0.0)) return g;  // a singular point: no tangent
  g.regular = true;
  g.T = p1 / g.speed;

  const Vector3d C = p1.cross(p2);  // (5.17)
  const double c = C.norm();
  const double p2n = p2.norm();
  if (!(p2n > 0.0) || c <= kStraightSine * g.speed * p2n || c <= p_uu_noise * g.speed) return g;  // straight: kappa = 0

  const double v3 = g.speed * g.speed * g.speed;
  g.kappa = c / v3;  // (5.4)
  g.has_normal = true;
  g.B = C / c;
  g.N = g.B.cross(g.T);
  const double c2 = c * c;
  g.tau = C.dot(p3) / c2;  // (5.11)

  const Vector3d C_u = p1.cross(p3);  // d/du (p' x p'') = p' x p'''
  const double CdC = C.dot(C_u);
  // (5.15) in general form: d/du (|C| / |p'|^3).
  g.kappa_du = CdC / (c * v3) - 3.0 * g.kappa * p1.dot(p2) / (g.speed * g.speed);
  // (5.21): d/du (C . p''' / |C|^2); the term C_u . p''' vanishes.
  g.tau_du = C.dot(p4) / c2 - 2.0 * g.tau * CdC / c2;
  g.kappa_ds = g.kappa_du / g.speed;  // d/ds = (d/du) / |dp/du|
  g.tau_ds = g.tau_du / g.speed;
  return g;
}

}  // namespace geotraj::core
