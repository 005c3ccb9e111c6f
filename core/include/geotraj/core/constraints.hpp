// Thesis Chapter 5: geometric constraints at a key frame become parametric constraints,
// the derivatives d^k p / du^k (k = 1..4) of the curve p(u) at the frame, per side.
//
// Frames and units: every vector is in the world frame W; p in [m]; u is the dimensionless
// segment parameter, so d^k p/du^k is in [m]. kappa, tau in [1/m]; derivatives with respect
// to u in [1/m] per unit u.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geotraj/core/error.hpp"
#include "geotraj/core/key_frame.hpp"

namespace geotraj::core {

/// The parametric constraints on one side of a key frame.
struct SideConstraints {
  /// d[k] = d^(k+1) p / du^(k+1) [m], k = 0..3; meaningful for k < order.
  std::array<Eigen::Vector3d, 4> d{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                   Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  /// Highest derivative that the given constraints fix: 1 (tangent only) to 4 (tau').
  int order = 1;
  /// The side's Frenet frame: T and N after the cusp and inflection flips, B = T x N.
  Eigen::Vector3d T = Eigen::Vector3d::UnitX();
  Eigen::Vector3d N = Eigen::Vector3d::Zero();  ///< zero when the frame has no normal
};

/// Both sides of one key frame. They differ at cusps (T inverts) and inflections (N inverts).
struct FrameConstraints {
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();  ///< position [m]
  SideConstraints approach;
  SideConstraints leave;
};

/// Thesis Eq. (5.10): d2p/du2 = |dp/du|^2 kappa N, with dp/du perpendicular to d2p/du2.
/// p_u [m], kappa [1/m], N unit. Returns [m].
Eigen::Vector3d second_derivative(const Eigen::Vector3d& p_u, double kappa, const Eigen::Vector3d& N);

/// Thesis Eqs. (5.14), (5.19), (5.20): the minimum-norm d3p/du3 that meets
///   tau = a0 . p_uuu                          (5.14), a0 = C / |C|^2, C = p_u x p_uu
///   kappa_du kappa |p_u|^6 = a1 . p_uuu       (5.19), a1 = C x p_u
/// for the rows given (tau and/or kappa_du); a0 and a1 are orthogonal, so the pseudo-inverse
/// is the sum of the rows' projections. kappa_du is d kappa/du [1/m per u].
/// Precondition: C != 0 (kappa > 0 at a regular point).
Eigen::Vector3d third_derivative(const Eigen::Vector3d& p_u, const Eigen::Vector3d& p_uu,
                                 std::optional<double> tau, std::optional<double> kappa_du);

/// Thesis Eq. (5.22): the minimum-norm d4p/du4 that meets
///   tau_du |C|^2 + 2 tau C . (p_u x p_uuu) = C . p_uuuu.
/// tau [1/m], tau_du = d tau/du [1/m per u]. Precondition: C != 0.
Eigen::Vector3d fourth_derivative(const Eigen::Vector3d& p_u, const Eigen::Vector3d& p_uu,
                                  const Eigen::Vector3d& p_uuu, double tau, double tau_du);

/// Converts one validated key frame (see validate_path) into its two sides.
/// Cusp: the leaving side uses -T (and so B inverts). Inflection: the leaving side uses -N.
/// Each side meets the frame's kappa, kappa', tau, tau' as measured along increasing u on
/// that side. Under kPerArcLength, kappa' and tau' are per metre and become per u by the
/// factor |dp/du| (d/du = |dp/du| d/ds).
FrameConstraints convert_frame(const KeyFrame& frame, DerivativeConvention convention);

/// Validates `spec` and converts every frame. Field paths as in validate_path.
Expected<std::vector<FrameConstraints>> convert_path(const PathSpec& spec);

}  // namespace geotraj::core
