// The Fresnel integrals and the planar clothoid in closed form (thesis 2.4: the natural
// equations kappa(s) = kappa0 + kappa1 s, tau = 0 integrate to Fresnel integrals).
//
// A planar curve whose curvature is linear in its arc length s turns by
//   theta(s) = kappa0 s + kappa1 s^2 / 2   [rad]
// and its point, in the plane of its start frame (T0, N0), is
//   p(s) = p0 + s Re(F) T0 + s Im(F) N0,   F = clothoid_integral(kappa1 s^2, kappa0 s),
//   clothoid_integral(a, b) = int_0^1 exp(i (b x + a x^2 / 2)) dx.
// Completing the square turns F into a difference of Fresnel integrals
// E(u) = C(u) + i S(u) = int_0^u exp(i pi t^2 / 2) dt at u = b / sqrt(pi a) and
// (a + b) / sqrt(pi a). Evaluated naively that difference loses every digit where the curve
// is close to an arc (a -> 0) and its phase grows as b^2 / a; here it is evaluated so that
// no large phase and no cancellation appears:
//  - E(u) for |u| < 1.5 by its power series, beyond it as E(u) = (1 + i) / 2 - G(u)
//    exp(i pi u^2 / 2) with the auxiliary G = g + i f from the even part of Laplace's
//    continued fraction for erfc (A&S 7.1.14), evaluated by Lentz's method;
//  - where both ends lie beyond 1.5 on one side, F = sqrt(pi / a) (G(u0) - G(u1)
//    exp(i (b + a / 2))): the completed square's phase cancels exactly;
//  - where the whole turn is small (|b| + |a| / 2 <= 0.1 rad), the Taylor series of
//    exp(i theta) integrated term by term.
// Relative error about 1e-15 of the unit chord (measured against long-double quadrature in
// the tests). Written here because neither the C++ library nor Boost.Math has the Fresnel
// integrals, and Debian's libcerf exposes them only through C99 complex numbers.
#pragma once

#include <complex>

namespace geotraj::core {

/// The Fresnel integrals E(u) = C(u) + i S(u) = int_0^u exp(i pi t^2 / 2) dt (any finite u).
std::complex<double> fresnel(double u);

/// int_0^1 exp(i (b x + a x^2 / 2)) dx for finite a and b [rad]: the chord, per unit of
/// length, of the planar clothoid that turns by b x + a x^2 / 2 (see above).
std::complex<double> clothoid_integral(double a, double b);

}  // namespace geotraj::core
