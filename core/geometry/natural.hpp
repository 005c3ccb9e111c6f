// Curves from their natural equations (thesis 2.4, Eqs. 2.34-2.35; 4.4.1, Eqs. 4.17-4.21):
// a curve given by its curvature kappa(s) and torsion tau(s) along its arc length s, placed
// by the Frenet frame it starts from. Frames and units: positions in W [m]; a Frenet frame
// is R = [T N B] (columns: tangent, principal normal, binormal, right-handed); kappa [1/m],
// tau [1/m], their s-derivatives [1/m^2], ...
//
// The Frenet-Serret equations (2.34) are a left-invariant ODE on SE(3): with g = (R, p),
//   dR/ds = R [w(s)]x,  dp/ds = R e1,   w(s) = (tau(s), 0, kappa(s))  (the Darboux vector in
// the moving frame), i.e. dg/ds = g xi(s), xi(s) = (v = e1, w(s)) in se(3). Instead of the
// thesis's first-order Euler steps (2.35, error O(ds)):
//  - where kappa and tau are constant (a line, an arc, a helix) the solution is the
//    exponential of SE(3), in closed form: g(s) = g(0) exp(s xi), exact to rounding for any
//    length (a 100-turn helix in one step);
//  - where kappa is linear in s and tau is 0 (the planar clothoid) the frame turns about
//    B by theta(s) = kappa0 s + kappa1 s^2 / 2 and the point is a Fresnel integral, in
//    closed form (fresnel.hpp), to rounding for any length;
//  - elsewhere (kappa, tau polynomials in s: a clothoid, any profile) the sixth-order Magnus
//    integrator on SE(3) (three Gauss-Legendre nodes per step, Blanes, Casas and Ros 2000),
//    whose steps stay on SE(3) (R orthonormal, |dp/ds| = 1: the parameter is the arc length
//    exactly), steps chosen by step doubling so the whole curve is within `tolerance` (1e-9 m
//    by default) of the exact solution.
// Helix by radius and pitch and back: kappa = r / (r^2 + l^2), tau = l / (r^2 + l^2)
// (4.18-4.19), r = kappa / (kappa^2 + tau^2), l = tau / (kappa^2 + tau^2) (4.20-4.21), with
// l = h / 2 pi for the pitch h per turn (positive: right-handed).
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/geometry/bezier.hpp"

namespace geotraj::core {

/// A Frenet frame on a curve, in W: origin p [m] and R = [T N B].
struct FrenetFrame {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d T() const { return R.col(0); }
  Eigen::Vector3d N() const { return R.col(1); }
  Eigen::Vector3d B() const { return R.col(2); }
};

/// The value at s of the polynomial sum_i c[i] s^i, or of its d-th derivative in s.
double polynomial_at(const std::vector<double>& c, double s, int derivative = 0);

/// A helix's curvature and torsion from its radius r > 0 [m] and pitch h per turn [m]
/// (signed: positive right-handed) (4.18-4.19).
struct CurvatureTorsion {
  double kappa = 0.0;  ///< [1/m]
  double tau = 0.0;    ///< [1/m]
};
CurvatureTorsion helix_curvature_torsion(double radius, double pitch);

/// A helix's radius and pitch per turn from its curvature kappa > 0 and torsion tau (4.20-4.21).
struct RadiusPitch {
  double radius = 0.0;  ///< [m]
  double pitch = 0.0;   ///< per turn [m], signed as tau
};
RadiusPitch helix_radius_pitch(double kappa, double tau);

/// The closed form for constant kappa and tau: the frame at arc length s from `start`,
/// start exp(s xi) on SE(3). Exact to rounding for any s (s < 0 runs backwards).
FrenetFrame advance_constant(const FrenetFrame& start, double kappa, double tau, double s);

/// The most polynomial coefficients a profile may have (degree 7).
inline constexpr std::size_t kMaxProfileCoefficients = 8;
/// The most integration steps one curve may take.
inline constexpr std::size_t kMaxNaturalSteps = 100'000;
/// The most its Frenet frame may turn over one curve, int sqrt(kappa^2 + tau^2) ds [rad]
/// (10,000 turns).
inline constexpr double kMaxNaturalTurning = 2e4 * 3.141592653589793;

/// A curve from its natural equations, integrated once (the steps' frames kept) and then
/// evaluated anywhere in O(log n) (one Magnus step from the step below s). Copyable value.
class NaturalCurve {
 public:
  /// The curve of arc length `length` [m] from `start` (R orthonormal, det +1, to 1e-9)
  /// with kappa(s) = sum kappa[i] s^i [1/m^(i+1)] and tau(s) likewise (empty: 0), within
  /// `tolerance` [m] of the exact solution over its whole length. Errors (field names
  /// relative: `lengthM`, `curvature`, `torsion`, `start`): length not finite or <= 0,
  /// coefficients not finite or more than kMaxProfileCoefficients, a start frame that is not
  /// a rotation, a curve that turns more than kMaxNaturalTurning or needs more than
  /// kMaxNaturalSteps steps.
  static Expected<NaturalCurve> build(const FrenetFrame& start, double length, std::vector<double> kappa,
                                      std::vector<double> tau, double tolerance = 1e-9);

  double length() const { return length_; }
  const FrenetFrame& start() const { return frames_.front(); }
  const FrenetFrame& end() const { return frames_.back(); }
  /// The frame at arc length s, clamped to [0, length].
  FrenetFrame frame_at(double s) const;
  /// kappa(s), tau(s) [1/m] as given (the profile, not measured).
  double kappa_at(double s, int derivative = 0) const { return polynomial_at(kappa_, s, derivative); }
  double tau_at(double s, int derivative = 0) const { return polynomial_at(tau_, s, derivative); }
  /// p and its first four derivatives in s at s (jet[k] = d^k p / ds^k), from the frame and
  /// the profile's derivatives: p' = T, p'' = kappa N, p''' = -kappa^2 T + kappa' N +
  /// kappa tau B, p'''' = -3 kappa kappa' T + (kappa'' - kappa^3 - kappa tau^2) N +
  /// (2 kappa' tau + kappa tau') B.
  Jet jet_at(double s) const;
  /// Integration steps taken (0 for a closed form: constant kappa and tau, or the planar
  /// clothoid).
  std::size_t steps() const { return form_ == Form::kIntegrated ? nodes_.size() - 1 : 0; }

 private:
  enum class Form { kConstant, kClothoid, kIntegrated };
  NaturalCurve() = default;
  double length_ = 0.0;
  std::vector<double> kappa_, tau_;
  Form form_ = Form::kIntegrated;
  std::vector<double> nodes_;         // arc length of each step's start, then the end
  std::vector<FrenetFrame> frames_;   // the frame at each node
};

}  // namespace geotraj::core
