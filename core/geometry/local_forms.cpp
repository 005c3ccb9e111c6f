// Chapter 4's local shapes. See local_forms.hpp.
#include "core/geometry/local_forms.hpp"

#include <cmath>
#include <utility>

namespace geotraj::core {

double implicit_curvature(const ImplicitPartials& f) {
  const double num = f.fxx * f.fy * f.fy - 2.0 * f.fxy * f.fx * f.fy + f.fyy * f.fx * f.fx;
  const double g2 = f.fx * f.fx + f.fy * f.fy;
  return num / (g2 * std::sqrt(g2));  // (4.4)
}

double parabola_curvature(double a, double x) {
  // f = y - a x^2: fx = -2 a x, fy = 1, fxx = -2 a (4.5).
  return implicit_curvature({-2.0 * a * x, 1.0, -2.0 * a, 0.0, 0.0});
}

double ellipse_curvature(double a, double b, double x, double y) {
  // f = A x^2 + B y^2 - 1, A = 1/a^2, B = 1/b^2 (4.10).
  const double A = 1.0 / (a * a), B = 1.0 / (b * b);
  return implicit_curvature({2.0 * A * x, 2.0 * B * y, 2.0 * A, 0.0, 2.0 * B});
}

double cusp_curvature(double a, double x, double y) {
  // f = a y^2 - x^3: fx = -3 x^2, fy = 2 a y, fxx = -6 x, fyy = 2 a (4.13).
  return implicit_curvature({-3.0 * x * x, 2.0 * a * y, -6.0 * x, 0.0, 2.0 * a});
}

Expected<LocalCurve> local_curve(const FrenetFrame& frame, const LocalConstraints& c, double half_length) {
  FrenetFrame ahead = frame;
  if (c.cusp) ahead.R.col(0) = -frame.R.col(0);
  if (c.inflection) ahead.R.col(1) = -frame.R.col(1);
  ahead.R.col(2) = ahead.R.col(0).cross(ahead.R.col(1));
  FrenetFrame behind = frame;
  behind.R.col(0) = -frame.R.col(0);
  behind.R.col(2) = -frame.R.col(2);
  auto forward = NaturalCurve::build(ahead, half_length, {c.kappa, c.kappa_d}, {c.tau, c.tau_d});
  if (!forward) return tl::unexpected(std::move(forward.error()));
  auto backward = NaturalCurve::build(behind, half_length, {c.kappa, -c.kappa_d}, {c.tau, -c.tau_d});
  if (!backward) return tl::unexpected(std::move(backward.error()));
  return LocalCurve{std::move(*forward), std::move(*backward)};
}

}  // namespace geotraj::core
