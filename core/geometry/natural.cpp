// Curves from their natural equations. See natural.hpp.
#include "core/geometry/natural.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "core/geometry/fresnel.hpp"

namespace geotraj::core {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// An element of se(3) in the moving frame: linear part v [1 or m], angular part w [rad].
struct Twist {
  Vector3d v = Vector3d::Zero();
  Vector3d w = Vector3d::Zero();
  Twist operator+(const Twist& o) const { return {v + o.v, w + o.w}; }
  Twist operator-(const Twist& o) const { return {v - o.v, w - o.w}; }
  Twist operator*(double c) const { return {v * c, w * c}; }
};

// The Lie bracket of se(3): [(v1, w1), (v2, w2)] = (w1 x v2 - w2 x v1, w1 x w2).
Twist bracket(const Twist& a, const Twist& b) { return {a.w.cross(b.v) - b.w.cross(a.v), a.w.cross(b.w)}; }

Matrix3d hat(const Vector3d& w) {
  Matrix3d W;
  W << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return W;
}

// g exp(xi): R exp([w]x) and p + R V v with V = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2,
// t = |w| (series below 1e-2: their first omitted terms are below 1e-20).
FrenetFrame compose_exp(const FrenetFrame& g, const Twist& xi) {
  const double t = xi.w.norm();
  const double t2 = t * t;
  double a = 0.0, b = 0.0, c = 0.0;  // sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3
  if (t < 1e-2) {
    a = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0));
    b = 0.5 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0)));
    c = (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))) / 6.0;
  } else {
    a = std::sin(t) / t;
    b = (1.0 - std::cos(t)) / t2;
    c = (t - std::sin(t)) / (t2 * t);
  }
  const Matrix3d W = hat(xi.w);
  const Matrix3d W2 = W * W;
  const Matrix3d E = Matrix3d::Identity() + a * W + b * W2;
  const Vector3d Vv = xi.v + b * W * xi.v + c * W2 * xi.v;
  return FrenetFrame{g.p + g.R * Vv, g.R * E};
}

// The Frenet-Serret twist at s (2.34): v = e1, w = (tau, 0, kappa).
Twist frenet_twist(const std::vector<double>& kappa, const std::vector<double>& tau, double s) {
  return {Vector3d::UnitX(), Vector3d(polynomial_at(tau, s), 0.0, polynomial_at(kappa, s))};
}

// One sixth-order Magnus step of length h from s (Blanes, Casas, Ros 2000): the twist at the
// three Gauss-Legendre nodes s + (1/2 -+ sqrt(15)/10) h, s + h/2, then
//   a1 = h A2, a2 = sqrt(15) h / 3 (A3 - A1), a3 = 10 h / 3 (A3 - 2 A2 + A1),
//   C1 = {a1, a2}, C2 = -1/60 {a1, 2 a3 + C1},
//   Omega = a1 + a3 / 12 + 1/240 {-20 a1 - a3 + C1, a2 + C2},
// and g exp(Omega). The method is written for Y' = A Y; the moving frame's g' = g xi is its
// transpose, so every bracket is reversed: {X, Y} = [Y, X]. For constant twists a2 = a3 = 0:
// Omega = h xi, the closed form.
FrenetFrame magnus_step(const FrenetFrame& g, const std::vector<double>& kappa, const std::vector<double>& tau,
                        double s, double h) {
  const double d = std::sqrt(15.0) / 10.0;
  const Twist A1 = frenet_twist(kappa, tau, s + (0.5 - d) * h);
  const Twist A2 = frenet_twist(kappa, tau, s + 0.5 * h);
  const Twist A3 = frenet_twist(kappa, tau, s + (0.5 + d) * h);
  const Twist a1 = A2 * h;
  const Twist a2 = (A3 - A1) * (std::sqrt(15.0) * h / 3.0);
  const Twist a3 = (A3 - A2 * 2.0 + A1) * (10.0 * h / 3.0);
  const auto rb = [](const Twist& x, const Twist& y) { return bracket(y, x); };
  const Twist C1 = rb(a1, a2);
  const Twist C2 = rb(a1, a3 * 2.0 + C1) * (-1.0 / 60.0);
  const Twist omega = a1 + a3 * (1.0 / 12.0) + rb(a1 * -20.0 - a3 + C1, a2 + C2) * (1.0 / 240.0);
  return compose_exp(g, omega);
}

// The planar clothoid (kappa = kappa0 + kappa1 s, tau = 0) at s from `start`: the frame
// turned about B by theta = kappa0 s + kappa1 s^2 / 2, the point s (Re F T0 + Im F N0) on
// from p0 with F the clothoid integral (fresnel.hpp).
FrenetFrame advance_clothoid(const FrenetFrame& start, double kappa0, double kappa1, double s) {
  const std::complex<double> chord = clothoid_integral(kappa1 * s * s, kappa0 * s) * s;
  const double theta = kappa0 * s + 0.5 * kappa1 * s * s;
  const double c = std::cos(theta), sn = std::sin(theta);
  Matrix3d turn;
  turn << c, -sn, 0.0, sn, c, 0.0, 0.0, 0.0, 1.0;
  return FrenetFrame{start.p + start.R.col(0) * chord.real() + start.R.col(1) * chord.imag(), start.R * turn};
}

// The index of the last coefficient that is not 0 (-1 for none): the polynomial's degree.
int degree(const std::vector<double>& c) {
  for (std::size_t i = c.size(); i-- > 0;)
    if (c[i] != 0.0) return static_cast<int>(i);
  return -1;
}

// R back onto SO(3) (rounding accumulates over many steps): through the unit quaternion.
void orthonormalize(FrenetFrame& f) { f.R = Eigen::Quaterniond(f.R).normalized().toRotationMatrix(); }

}  // namespace

double polynomial_at(const std::vector<double>& c, double s, int derivative) {
  double value = 0.0;
  for (std::size_t i = c.size(); i-- > static_cast<std::size_t>(std::max(derivative, 0));) {
    double factor = 1.0;  // i (i - 1) ... (i - derivative + 1)
    for (int k = 0; k < derivative; ++k) factor *= static_cast<double>(i) - k;
    value = value * s + c[i] * factor;
  }
  return value;
}

CurvatureTorsion helix_curvature_torsion(double radius, double pitch) {
  const double l = pitch / (2.0 * std::numbers::pi);
  const double d = radius * radius + l * l;
  return {radius / d, l / d};
}

RadiusPitch helix_radius_pitch(double kappa, double tau) {
  const double d = kappa * kappa + tau * tau;
  return {kappa / d, 2.0 * std::numbers::pi * tau / d};
}

FrenetFrame advance_constant(const FrenetFrame& start, double kappa, double tau, double s) {
  return compose_exp(start, Twist{Vector3d::UnitX() * s, Vector3d(tau, 0.0, kappa) * s});
}

Expected<NaturalCurve> NaturalCurve::build(const FrenetFrame& start, double length, std::vector<double> kappa,
                                           std::vector<double> tau, double tolerance) {
  Violations v;
  if (!std::isfinite(length) || !(length > 0.0))
    v.push_back({"lengthM", "must be a finite length > 0 m, got " + number(length)});
  for (const auto& [name, c] : {std::pair<const char*, const std::vector<double>*>{"curvature", &kappa},
                                {"torsion", &tau}}) {
    if (c->size() > kMaxProfileCoefficients)
      v.push_back({name, "has " + std::to_string(c->size()) + " coefficients, at most " +
                             std::to_string(kMaxProfileCoefficients) + " (degree 7)"});
    for (std::size_t i = 0; i < c->size(); ++i)
      if (!std::isfinite((*c)[i])) v.push_back({std::string(name) + "[" + std::to_string(i) + "]", "must be finite"});
  }
  const Matrix3d RtR = start.R.transpose() * start.R;
  if (!start.p.allFinite() || !start.R.allFinite() || !RtR.isIdentity(1e-9) || !(start.R.determinant() > 0.0))
    v.push_back({"start", "must be a finite position and a right-handed orthonormal frame [T N B]"});
  if (!(tolerance > 0.0)) v.push_back({"tolerance", "must be > 0 m, got " + number(tolerance)});
  if (!v.empty()) return tl::make_unexpected(std::move(v));

  // The frame's total turn, int |w(s)| ds (1,024 midpoints): a curve that turns more than
  // kMaxNaturalTurning is refused before it is integrated.
  double turning = 0.0;
  for (int i = 0; i < 1024; ++i) {
    const double s = length * (i + 0.5) / 1024.0;
    turning += std::hypot(polynomial_at(kappa, s), polynomial_at(tau, s)) * length / 1024.0;
  }
  if (!(turning <= kMaxNaturalTurning))
    return tl::make_unexpected(Violations{unattainable(
        "curvature", "the curve's frame turns " + number(turning, 6) + " rad over " + number(length, 6) +
                         " m, more than " + number(kMaxNaturalTurning) + " rad: shorten it or lower its curvature and torsion")});

  NaturalCurve curve;
  curve.length_ = length;
  curve.kappa_ = std::move(kappa);
  curve.tau_ = std::move(tau);
  const int kappa_degree = degree(curve.kappa_), tau_degree = degree(curve.tau_);
  curve.form_ = kappa_degree <= 0 && tau_degree <= 0   ? Form::kConstant
                : kappa_degree == 1 && tau_degree < 0 ? Form::kClothoid
                                                      : Form::kIntegrated;
  curve.nodes_ = {0.0};
  curve.frames_ = {start};
  if (curve.form_ != Form::kIntegrated) {  // a closed form: the end frame only
    curve.nodes_.push_back(length);
    curve.frames_.push_back(curve.frame_at(length));
    return curve;
  }
  // Step doubling: one step of h against two of h / 2; the difference (the position's plus
  // the frame's turn times the length still to go, which it moves the rest of the curve by)
  // estimates the single step's error (the halves' is 64 times smaller). A step is kept when
  // that is within the tolerance's share of its length: frame_at evaluates a point inside a
  // step with one step from its start. The node keeps the halves' frame.
  double s = 0.0;
  double h = std::min(length, 0.1 / std::max(1.0, std::abs(curve.kappa_at(0.0)) + std::abs(curve.tau_at(0.0))));
  FrenetFrame g = start;
  while (s < length) {
    if (curve.nodes_.size() > kMaxNaturalSteps)
      return tl::make_unexpected(Violations{unattainable(
          "curvature", "the curve needs more than " + std::to_string(kMaxNaturalSteps) +
                           " integration steps to be within " + number(tolerance) + " m: shorten it or lower its curvature and torsion")});
    h = std::min(h, length - s);
    const FrenetFrame one = magnus_step(g, curve.kappa_, curve.tau_, s, h);
    const FrenetFrame half = magnus_step(g, curve.kappa_, curve.tau_, s, 0.5 * h);
    FrenetFrame two = magnus_step(half, curve.kappa_, curve.tau_, s + 0.5 * h, 0.5 * h);
    const double turn = Eigen::AngleAxisd(one.R.transpose() * two.R).angle();
    const double error = (one.p - two.p).norm() + turn * (length - s - h);
    const double allowed = tolerance * h / length;
    if (error <= allowed || h <= length * 1e-12) {
      orthonormalize(two);
      s = (length - s - h) <= length * 1e-15 ? length : s + h;
      g = two;
      curve.nodes_.push_back(s);
      curve.frames_.push_back(g);
    }
    const double grow = error > 0.0 ? 0.9 * std::pow(allowed / error, 1.0 / 7.0) : 2.0;
    h *= std::clamp(grow, 0.2, 2.0);
  }
  return curve;
}

FrenetFrame NaturalCurve::frame_at(double s) const {
  s = std::clamp(s, 0.0, length_);
  if (form_ == Form::kConstant) return advance_constant(frames_.front(), kappa_at(0.0), tau_at(0.0), s);
  if (form_ == Form::kClothoid) return advance_clothoid(frames_.front(), kappa_at(0.0), kappa_at(0.0, 1), s);
  // The step whose start is the last node at or below s.
  const auto it = std::upper_bound(nodes_.begin(), nodes_.end(), s);
  const std::size_t k = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, (it - nodes_.begin()) - 1));
  if (k + 1 >= nodes_.size()) return frames_.back();
  const double h = s - nodes_[k];
  return h > 0.0 ? magnus_step(frames_[k], kappa_, tau_, nodes_[k], h) : frames_[k];
}

Jet NaturalCurve::jet_at(double s) const {
  s = std::clamp(s, 0.0, length_);
  const FrenetFrame f = frame_at(s);
  const double k = kappa_at(s), k1 = kappa_at(s, 1), k2 = kappa_at(s, 2);
  const double t = tau_at(s), t1 = tau_at(s, 1);
  const Vector3d T = f.T(), N = f.N(), B = f.B();
  Jet jet{};
  jet[0] = f.p;
  jet[1] = T;
  jet[2] = k * N;
  jet[3] = -k * k * T + k1 * N + k * t * B;
  jet[4] = -3.0 * k * k1 * T + (k2 - k * k * k - k * t * t) * N + (2.0 * k1 * t + k * t1) * B;
  return jet;
}

}  // namespace geotraj::core
