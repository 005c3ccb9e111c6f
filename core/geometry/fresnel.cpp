// The Fresnel integrals and the planar clothoid in closed form. See fresnel.hpp.
#include "core/geometry/fresnel.hpp"

#include <cmath>
#include <limits>
#include <numbers>

namespace geotraj::core {

namespace {

using Complex = std::complex<double>;
constexpr double kPi = std::numbers::pi;
// Below this whole turn [rad] the clothoid integral is the Taylor series of exp(i theta).
constexpr double kSmallTurn = 0.25;
// E(u) for |u| < kTableEnd from a table at steps of kTableStep and the small turn from the
// nearest entry; beyond it from the continued fraction (9 terms at u = 4, 2 at u = 100;
// 48 at u = 1.5, which the table keeps out of the evaluations).
constexpr double kTableEnd = 4.0;
constexpr int kTablePerUnit = 32;
constexpr int kTableSize = static_cast<int>(kTableEnd) * kTablePerUnit + 1;

// G(u) = g(u) + i f(u), u >= 1.5: E(u) = (1 + i) / 2 - G(u) exp(i pi u^2 / 2).
// With z = (1 - i) sqrt(pi) u / 2, (1 + i) / 2 - E(u) = (1 + i) / 2 erfc(z) and
// e^(z^2) erfc(z) sqrt(pi) = 2 z K, K the even part of Laplace's continued fraction
// (A&S 7.1.14) with 2 z^2 = -i pi u^2:
//   K = 1 / (b0 + a1 / (b1 + a2 / (b2 + ...))),  b_k = 1 - i pi u^2 + 4 k, a_k = -(2k - 1) 2k,
// so G(u) = u K. Evaluated by Lentz's method.
Complex auxiliary(double u) {
  constexpr double kTiny = 1e-300;
  const Complex b0(1.0, -kPi * u * u);
  Complex f = b0, c = b0, d = 0.0;
  for (int k = 1; k < 200; ++k) {
    const double a = -static_cast<double>((2 * k - 1) * (2 * k));
    const Complex b = b0 + 4.0 * k;
    d = b + a * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + a / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const Complex delta = c * d;
    f *= delta;
    if (std::abs(delta - 1.0) < 4e-16) break;  // a few units of rounding: below, it would not stop
  }
  return u / f;
}

// E(u) for |u| < 1.5: sum_n (i pi / 2)^n u^(2n+1) / (n! (2n + 1)) (its largest term about 7).
Complex fresnel_series(double u) {
  const Complex step(0.0, 0.5 * kPi * u * u);
  Complex term = u, sum = u;
  for (int n = 1; n < 60; ++n) {
    term *= step / static_cast<double>(n);
    const Complex part = term / static_cast<double>(2 * n + 1);
    sum += part;
    if (std::abs(part) < 1e-17 * std::abs(sum)) break;
  }
  return sum;
}

// int_0^1 exp(i theta(x)) dx, theta = x (b + h x), h = a / 2, |b| + |h| <= kSmallTurn:
// sum_n i^n / n! int_0^1 theta^n dx with int_0^1 theta^n = sum_k C(n, k) b^(n-k) h^k / (n + k + 1),
// as many terms as (|b| + |h|)^n / n! needs to fall below 1e-17 (at most 14).
Complex small_turn(double a, double b) {
  constexpr int kMaxTerms = 14;
  const double h = 0.5 * a, t = std::abs(b) + std::abs(h);
  double bp[kMaxTerms + 1], hp[kMaxTerms + 1];
  bp[0] = hp[0] = 1.0;
  for (int n = 1; n <= kMaxTerms; ++n) {
    bp[n] = bp[n - 1] * b;
    hp[n] = hp[n - 1] * h;
  }
  double re = 0.0, im = 0.0, bound = 1.0, inverse_factorial = 1.0;
  for (int n = 0; n <= kMaxTerms && bound >= 1e-17; ++n) {
    double moment = 0.0, binomial = 1.0;
    for (int k = 0; k <= n; ++k) {
      moment += binomial * bp[n - k] * hp[k] / (n + k + 1);
      binomial = binomial * (n - k) / (k + 1);
    }
    const double term = moment * inverse_factorial;
    switch (n % 4) {  // i^n
      case 0: re += term; break;
      case 1: im += term; break;
      case 2: re -= term; break;
      default: im -= term; break;
    }
    inverse_factorial /= n + 1;
    bound *= t / (n + 1);
  }
  return {re, im};
}

// E(u_j) and exp(i pi u_j^2 / 2) at u_j = j / kTablePerUnit, 0 <= u_j <= kTableEnd, once.
struct FresnelTable {
  Complex value[kTableSize];
  Complex turn[kTableSize];
};
const FresnelTable& table() {
  static const FresnelTable t = [] {
    FresnelTable made;
    for (int j = 0; j < kTableSize; ++j) {
      const double u = static_cast<double>(j) / kTablePerUnit;
      const double phase = 0.5 * kPi * u * u;
      made.turn[j] = Complex(std::cos(phase), std::sin(phase));
      made.value[j] = u < 1.5 ? fresnel_series(u) : Complex(0.5, 0.5) - auxiliary(u) * made.turn[j];
    }
    return made;
  }();
  return t;
}

}  // namespace

Complex fresnel(double u) {
  const double v = std::abs(u);
  if (v < kTableEnd) {
    // E(v) = E(u_j) + int_{u_j}^{v} exp(i pi t^2 / 2) dt, t = u_j + d x: a turn of
    // pi u_j d x + pi d^2 x^2 / 2 (at most 0.2 rad) from the nearest entry.
    const FresnelTable& t = table();
    const int j = static_cast<int>(std::lround(v * kTablePerUnit));
    const double uj = static_cast<double>(j) / kTablePerUnit, d = v - uj;
    const Complex e = t.value[j] + t.turn[j] * d * small_turn(kPi * d * d, kPi * uj * d);
    return u < 0.0 ? -e : e;
  }
  const double phase = 0.5 * kPi * v * v;
  const Complex e = Complex(0.5, 0.5) - auxiliary(v) * Complex(std::cos(phase), std::sin(phase));
  return u < 0.0 ? -e : e;
}

Complex clothoid_integral(double a, double b) {
  if (a < 0.0) return std::conj(clothoid_integral(-a, -b));
  if (std::abs(b) + 0.5 * a <= kSmallTurn) return small_turn(a, b);
  if (a < 1e-30) {  // an arc to rounding: (exp(i b) - 1) / (i b), |b| > kSmallTurn
    const double half = std::sin(0.5 * b);
    return {std::sin(b) / b, 2.0 * half * half / b};
  }
  // Completing the square: b x + a x^2 / 2 = pi u^2 / 2 - b^2 / (2a), u = (b + a x) / r.
  const double r = std::sqrt(kPi * a);
  const double u0 = b / r, u1 = (a + b) / r, k = std::sqrt(kPi / a);
  const double turn = b + 0.5 * a;  // pi (u1^2 - u0^2) / 2
  const Complex end(std::cos(turn), std::sin(turn));
  if (u0 >= kTableEnd) return k * (auxiliary(u0) - auxiliary(u1) * end);
  if (u1 <= -kTableEnd) return k * (auxiliary(-u1) * end - auxiliary(-u0));
  // The ends on either side of the inflection, or one of them near it: the phase b^2 / 2a
  // is at most the turn from the inflection, which the curve makes.
  const double phase = -0.5 * b * b / a;
  return k * Complex(std::cos(phase), std::sin(phase)) * (fresnel(u1) - fresnel(u0));
}

}  // namespace geotraj::core
