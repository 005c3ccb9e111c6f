// Chapter 4's vocabulary of local shapes (thesis 4.3-4.4, Tables 4.1-4.5, Figs. 4.10-4.27).
// Planar forms by their implicit equations f(x, y) = 0 and their curvature (4.4); a key
// frame's local curve, the curve its constraints give around it, integrated forward and
// backward from the frame by its natural equations (natural.hpp). Units: metres, 1/m, 1/m^2;
// frames in W as in natural.hpp (R = [T N B]).
#pragma once

#include "core/error.hpp"
#include "core/geometry/natural.hpp"

namespace geotraj::core {

/// The partial derivatives of an implicit planar curve f(x, y) = 0 at a point.
struct ImplicitPartials {
  double fx = 0.0, fy = 0.0, fxx = 0.0, fxy = 0.0, fyy = 0.0;
};

/// Signed curvature [1/m] of f(x, y) = 0 (4.4):
///   (fxx fy^2 - 2 fxy fx fy + fyy fx^2) / (fx^2 + fy^2)^(3/2); infinite at a singular point
///   (fx = fy = 0) where the numerator is not 0, NaN where both vanish.
double implicit_curvature(const ImplicitPartials& f);

/// The parabola y - a x^2 = 0 at x (4.5): -2a / (1 + 4 a^2 x^2)^(3/2); |kappa| is largest,
/// 2|a|, at the origin (Table 4.1).
double parabola_curvature(double a, double x);

/// The ellipse x^2/a^2 + y^2/b^2 - 1 = 0 at (x, y) on it (4.10).
double ellipse_curvature(double a, double b, double x, double y);

/// The cusp a y^2 - x^3 = 0 at (x, y) on it (4.13): unbounded towards the origin (Table 4.2).
double cusp_curvature(double a, double x, double y);

/// What a key frame gives of its local shape (kappa' and tau' per metre of arc). A spatial
/// saddle (4.4.3) is tau = 0 with tau' != 0: both branches leave the osculating plane on
/// the side of kappa tau'.
struct LocalConstraints {
  double kappa = 0.0;    ///< [1/m], >= 0 along N
  double tau = 0.0;      ///< [1/m]
  double kappa_d = 0.0;  ///< [1/m^2]
  double tau_d = 0.0;    ///< [1/m^2]
  bool cusp = false;        ///< the tangent inverts on the leaving side (5.6.2)
  bool inflection = false;  ///< the normal inverts on the leaving side (5.6.1)
};

/// A frame's local curve: two branches from the frame's point, each a curve from its natural
/// equations truncated at first order in s (kappa(s) = kappa + kappa' s, tau(s) = tau + tau' s).
///   forward  (s > 0): from [T N B] (with a cusp from [-T N -B], with an inflection from
///            [T -N -B]), kappa + kappa' s, tau + tau' s;
///   backward (s < 0), traced away from the frame: from [-T N -B], kappa - kappa' s,
///            tau - tau' s (torsion does not depend on the direction of travel; kappa'
///            does). With a cusp both branches leave the point towards -T, as y^2 = x^3's do.
struct LocalCurve {
  NaturalCurve forward;
  NaturalCurve backward;
};

/// The local curve of `frame` (its R orthonormal, det +1) under `c`, each branch
/// `half_length` [m] long, within 1e-9 m. Errors as NaturalCurve::build's (`lengthM`,
/// `curvature`, `torsion`, `start`).
Expected<LocalCurve> local_curve(const FrenetFrame& frame, const LocalConstraints& c, double half_length);

}  // namespace geotraj::core
