// Thesis Chapter 5: geometric constraints at a key frame become parametric constraints,
// the derivatives d^k p / du^k (k = 1..4) of the curve p(u) at the frame, per side.
//
// Frames and units: every vector is in the world frame W; p in [m]; u is the dimensionless
// segment parameter, so d^k p/du^k is in [m]. kappa, tau in [1/m]; derivatives with respect
// to u in [1/m] per unit u.
#pragma once

#include <array>
#include <cmath>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"

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

/// The tangent scale |dp/du| [m] of one side of a frame: `tangent_scale`, except on the
/// leaving side, which takes `leave_tangent_scale` when given. validate_path fills both
/// from the chord lengths where the request gives none; 1 m only for an unvalidated frame.
inline double side_scale(const KeyFrame& frame, bool leaving) {
  const double scale = frame.tangent_scale.value_or(1.0);
  return leaving ? frame.leave_tangent_scale.value_or(scale) : scale;
}

/// The Chapter 5 conversion of one side, generic in the scalar type `S` of the tangent
/// scale, so that an optimiser can differentiate the end derivatives with respect to the
/// scale (automatic differentiation, S = a dual number); core itself uses S = double.
/// Given the side's unit tangent T and normal N (after the cusp and inflection flips) and
/// its scale [m], fills d[k] = d^(k+1) p/du^(k+1) [m] for k < the returned order (1 to 4),
/// by (5.3), (5.10), (5.20) and (5.22) as documented on the functions above. The frame's
/// data are doubles; only the scale varies. d[k] for k >= order is left untouched.
/// Precondition: the frame passed validate_path (kappa > 0 wherever tau or a derivative is given).
namespace detail {

// The formulas of (5.10), (5.20) and (5.22), generic in the scalar type S; the public
// functions above and side_derivatives below are their only callers.
template <class S>
using Vec3 = Eigen::Matrix<S, 3, 1>;

template <class S>
Vec3<S> second_derivative(const Vec3<S>& p_u, double kappa, const Eigen::Vector3d& N) {
  return N.cast<S>() * (p_u.squaredNorm() * kappa);  // (5.10)
}

// tau [1/m] and kappa_du [1/m per u] may be null (not given).
template <class S>
Vec3<S> third_derivative(const Vec3<S>& p_u, const Vec3<S>& p_uu, const double* tau, const S* kappa_du) {
  using std::pow;
  using std::sqrt;
  const Vec3<S> C = p_u.cross(p_uu);  // (5.17)
  const S C2 = C.squaredNorm();
  Vec3<S> p_uuu = Vec3<S>::Zero();
  if (tau) {
    // Row (5.14): tau = a0 . p_uuu with a0 = C / |C|^2. Its minimum-norm solution is
    // tau a0 / |a0|^2 = tau C.
    p_uuu += C * *tau;
  }
  if (kappa_du) {
    // Row (5.19): kappa_du kappa |p_u|^6 = a1 . p_uuu with a1 = C x p_u. Since p_u is
    // perpendicular to p_uu (5.10), kappa |p_u|^3 = |C|, so the left side is
    // kappa_du |C| |p_u|^3. a1 is orthogonal to a0, so the pseudo-inverse of the
    // two-row system (5.20) is the sum of each row's minimum-norm solution.
    const Vec3<S> a1 = C.cross(p_u);
    const S kappa = sqrt(C2) / pow(p_u.norm(), 3);                // (5.4)
    const S rhs = *kappa_du * kappa * pow(p_u.squaredNorm(), 3);  // (5.19)
    p_uuu += a1 * (rhs / a1.squaredNorm());
  }
  return p_uuu;
}

template <class S>
Vec3<S> fourth_derivative(const Vec3<S>& p_u, const Vec3<S>& p_uu, const Vec3<S>& p_uuu, double tau, const S& tau_du) {
  const Vec3<S> C = p_u.cross(p_uu);
  const S C2 = C.squaredNorm();
  const S rhs = tau_du * C2 + 2.0 * tau * C.dot(p_u.cross(p_uuu));  // (5.22)
  return C * (rhs / C2);  // minimum-norm solution of C . p_uuuu = rhs
}

}  // namespace detail

/// The Chapter 5 conversion of one side, generic in the scalar type `S` of the tangent
/// scale, so that an optimiser can differentiate the end derivatives with respect to the
/// scale (automatic differentiation, S = a dual number); core itself uses S = double.
/// Given the side's unit tangent T and normal N (after the cusp and inflection flips) and
/// its scale [m], fills d[k] = d^(k+1) p/du^(k+1) [m] for k < the returned order (1 to 4),
/// by (5.3), (5.10), (5.20) and (5.22) as documented on the functions above. The frame's
/// data are doubles; only the scale varies. d[k] for k >= order is left untouched.
/// Precondition: the frame passed validate_path (kappa > 0 wherever tau or a derivative is given).
template <class S>
int side_derivatives(const KeyFrame& f, DerivativeConvention convention, const Eigen::Vector3d& T,
                     const Eigen::Vector3d& N, const S& scale, std::array<detail::Vec3<S>, 4>& d) {
  d[0] = T.cast<S>() * scale;  // (5.3)
  if (!f.kappa) return 1;
  d[1] = detail::second_derivative<S>(d[0], *f.kappa, N);  // (5.10)
  if (!f.tau && !f.kappa_d) return 2;
  if (!(*f.kappa > 0.0)) return 2;  // C = 0: the rows of (5.20) vanish (only a zero reaches here)
  // d/du = |dp/du| d/ds at the frame (chain rule), |dp/du| = scale.
  const S per_u = convention == DerivativeConvention::kPerArcLength ? scale : S(1.0);
  const double* tau = f.tau ? &*f.tau : nullptr;
  const S kappa_du = f.kappa_d ? S(*f.kappa_d * per_u) : S(0.0);
  d[2] = detail::third_derivative<S>(d[0], d[1], tau, f.kappa_d ? &kappa_du : nullptr);  // (5.20)
  if (!f.tau_d) return 3;
  d[3] = detail::fourth_derivative<S>(d[0], d[1], d[2], *f.tau, S(*f.tau_d * per_u));  // (5.22)
  return 4;
}

/// Converts one validated key frame (see validate_path) into its two sides.
/// Cusp: the leaving side uses -T (and so B inverts) and its own scale (side_scale).
/// Inflection: the leaving side uses -N.
/// Each side meets the frame's kappa, kappa', tau, tau' as measured along increasing u on
/// that side. Under kPerArcLength, kappa' and tau' are per metre and become per u by the
/// factor |dp/du| (d/du = |dp/du| d/ds).
FrameConstraints convert_frame(const KeyFrame& frame, DerivativeConvention convention);

/// Validates `spec` and converts every frame. Field paths as in validate_path. A path of
/// pieces (pieces.hpp) is built, and its joins' constraints are what its curves give there.
Expected<std::vector<FrameConstraints>> convert_path(const PathSpec& spec);

}  // namespace geotraj::core
