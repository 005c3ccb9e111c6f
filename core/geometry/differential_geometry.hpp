// Differential geometry of a parametric curve from its derivatives (thesis 2.2.3, 2.3,
// Eqs. 5.4, 5.11, 5.15, 5.21), with no assumption that p' and p'' are perpendicular.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/geometry/bezier.hpp"

namespace geotraj::core {

/// The Frenet apparatus at one point. Units: speed [m per u]; kappa, tau [1/m];
/// *_du per unit u, *_ds per metre of arc ([1/m^2]).
struct LocalGeometry {
  double speed = 0.0;        ///< |dp/du|
  bool regular = false;      ///< speed > 0: T is defined
  Eigen::Vector3d T = Eigen::Vector3d::Zero();
  double kappa = 0.0;        ///< |p' x p''| / |p'|^3 (5.4)
  bool has_normal = false;   ///< kappa > 0: N, B, tau and the derivatives are defined
  Eigen::Vector3d N = Eigen::Vector3d::Zero();
  Eigen::Vector3d B = Eigen::Vector3d::Zero();
  double tau = 0.0;          ///< (p' x p'') . p''' / |p' x p''|^2 (5.11)
  double kappa_du = 0.0, kappa_ds = 0.0;  ///< (5.15)
  double tau_du = 0.0, tau_ds = 0.0;      ///< (5.21)
};

/// Relative size of |p' x p''| / (|p'| |p''|) below which the curve is taken as straight
/// (curvature zero, normal undefined): a few hundred rounding errors.
inline constexpr double kStraightSine = 1e-13;

/// The Frenet apparatus from jet[1..4] (jet[0] unused). `p_uu_noise` [m] is the rounding
/// level of the evaluated d2p/du2 (see segment_noise): where the part of d2p/du2
/// perpendicular to dp/du is below it, the curve is taken as straight (kappa = 0, no normal).
LocalGeometry local_geometry(const Jet& jet, double p_uu_noise = 0.0);

}  // namespace geotraj::core
