// The TRAPEZOIDAL blend (thesis App. B, Eqs. B.6-B.9, after Tesar and Matthew), as
// docs/thesis-math.md reads the garbled B.7-B.9: for one axis of one segment, the n-th
// derivative is piecewise linear with 2n + 2 breakpoints u_0 < u_1 <= ... <= u_{2n+1}:
// 0 at u_0, ramps to A_1 over [u_0, u_1], from A_{j-1} to A_j over [u_{2j-2}, u_{2j-1}],
// holds A_j until u_{2j}, and ramps from A_n back to 0 over [u_{2n}, u_{2n+1}]. Integrating
// n times from the start state (singularity functions <u - u_k>^m / m!) gives the lower
// derivatives; the levels A_1..A_n follow from the n end conditions on derivatives 0..n-1.
#pragma once

#include <array>
#include <span>
#include <string>

#include <tl/expected.hpp>

namespace geotraj::core {

inline constexpr int kMaxTrapezoidOrder = 5;  // meets 4th-order constraints at both ends

/// One axis of one segment; u in [0, 1].
struct TrapezoidAxis {
  int n = 2;                                             ///< order: the shaped derivative
  std::array<double, 2 * kMaxTrapezoidOrder + 2> u{};    ///< breakpoints u_0..u_{2n+1}
  std::array<double, kMaxTrapezoidOrder + 1> c{};        ///< ramp heights c_1..c_{n+1}
  std::array<double, kMaxTrapezoidOrder> start{};        ///< d^k x/du^k (0), k = 0..n-1
  std::array<double, kMaxTrapezoidOrder> end{};          ///< d^k x/du^k (1), k = 0..n-1
};

/// Uniform breakpoints u_k = k / (2n + 1), k = 0..2n+1 (thesis Eq. B.10 for n = 4).
std::array<double, 2 * kMaxTrapezoidOrder + 2> uniform_breakpoints(int n);

/// Builds the order-n trapezoid that starts with derivatives `start[0..n-1]` at u = 0 and
/// ends with `end[0..n-1]` at u = 1, its n-th derivative zero at both ends.
/// Preconditions: 1 <= n <= 5; breakpoints.size() == 2n + 2, ordered, in [0, 1], u_0 < u_1.
/// Error (a sentence) if the end conditions cannot be met with these breakpoints.
tl::expected<TrapezoidAxis, std::string> make_trapezoid(int n, std::span<const double> breakpoints,
                                                        std::span<const double> start,
                                                        std::span<const double> end);

/// Fills out[0..max_order] with d^k x/du^k (u). Derivative n + 1 is the ramp slope (zero on
/// holds); derivatives above n + 1 are zero almost everywhere.
void evaluate(const TrapezoidAxis& axis, double u, int max_order, double* out);

}  // namespace geotraj::core
