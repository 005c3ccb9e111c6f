// Arc length s(u) = integral of |dp/du| du (thesis Eq. 2.36), by adaptive Gauss-Kronrod
// (7-point Gauss, 15-point Kronrod) quadrature, and its inverse u(s) by safeguarded Newton.
#pragma once

#include <functional>

#include "core/geometry/path.hpp"

namespace geotraj::core {

/// Requested accuracy of the quadrature, relative to the integral.
inline constexpr double kArcLengthRelTol = 1e-12;

/// Adaptive G7-K15 integral of f over [a, b] to rel_tol (relative to the integral's
/// magnitude), with at most max_intervals subintervals.
double integrate_gk15(const std::function<double(double)>& f, double a, double b,
                      double rel_tol = kArcLengthRelTol, int max_intervals = 2000);

/// Arc length of one segment between local parameters u0 <= u1 [m]. Trapezoid segments are
/// split at their breakpoints, where |dp/du| may lose smoothness.
double segment_arc_length(const Segment& segment, double u0, double u1,
                          double rel_tol = kArcLengthRelTol);

/// s(u) along the whole path [m]; u in [0, M].
double arc_length_at(const Path& path, double u);

/// u(s): the global parameter where the arc length is s [m] (clamped to [0, L]), to
/// |s(u) - s| <= 1e-12 L; Newton on s(u) - s with ds/du = |dp/du|, safeguarded by bisection.
double parameter_at(const Path& path, double s);

}  // namespace geotraj::core
