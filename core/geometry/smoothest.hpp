// The smoothest reading of unspecified constraints (UnspecifiedConstraints::kSmoothest).
//
// Every segment is a degree 9 polynomial, so its ten Bernstein coefficients are fixed by the
// derivatives 0..4 at both ends (App. B.2 with n0 = n1 = 4). At each side of each key frame
// the request fixes some of them through the rows of Chapter 5:
//   p'    = scale T                                        (5.3)   always
//   p''   = scale^2 kappa N                                (5.10)  kappa given
//   B . p''  = 0,  B . p''' = 0                                    a normal without kappa
//   tau   = a0 . p'''                                      (5.14)  tau given
//   kappa' kappa |p'|^6 = a1 . p'''                        (5.19)  kappa' given
//   tau' |C|^2 + 2 tau C . (p' x p''') = C . p''''         (5.22)  tau' given (linear in p''')
// Once p' is known each row is linear in the unknown derivatives. What no row fixes is
// chosen to minimise the jerk energy of the whole path,
//   E = sum over segments of  integral_0^1 |d3p/du3|^2 du   [m^2],
// a quadratic in the unknowns: one sparse symmetric positive definite solve (Eigen's
// SimplicialLDLT on a Jacobi-scaled system), O(frames), no iteration.
//
// What stays fixed, and why:
// - The tangential parts T . p'', T . p''', T . p'''' are 0, as in the thesis's
//   minimum-norm solutions. They change only the speed of the parameter, not the geometry,
//   and an energy in u buys its smoothness by slowing the parameter when they are free
//   (|dp/du| falls towards 0 before a bend and the curvature there rises).
// - Across a frame where nothing breaks the curve (no cusp, inflection or stop) the two
//   sides are tied by the beta-constraints of 3.3 (Barsky's geometric continuity) with
//   beta1 = scale_leave / scale_approach:
//     p''_L   = beta1^2 p''_A + beta2 p'_A
//     p'''_L  = beta1^3 p'''_A + 3 beta1 beta2 p''_A + beta3 p'_A
//     p''''_L = beta1^4 p''''_A + 6 beta1^2 beta2 p'''_A + (4 beta1 beta3 + 3 beta2^2) p''_A + beta4 p'_A.
//   beta2 and beta3 multiply the unknown p''_A and p'''_A, which would make the problem
//   bilinear: they are fixed at 0; beta4 multiplies p'_A, a tangential part, so it is 0 too.
//   The curve is then G4 at the frame (C4 after the linear change of parameter
//   u_L = beta1 u_A), for any two tangent scales.
// - A normal given without a curvature fixes the osculating plane at the frame: the curve
//   bends in it (B . p'' = 0) and the plane does not turn there (B . p''' = 0, so tau = 0
//   at the frame). With B . p''' free, the curvature, free too, can be small at such a frame
//   and tau = B . p''' / (kappa |p'|^3) large: path C's last frame had kappa 0.98 and tau
//   1244 1/m (a FRENET tool spins with it); with the row its segment's peak |tau| is 113 1/m.
// - At a cusp, an inflection or a stop the sides are independent (the tangent, the normal,
//   or the motion breaks there anyway).
#pragma once

#include <vector>

#include "core/error.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/key_frame.hpp"

namespace geotraj::core {

/// Fills every side of `frames` (the Chapter 5 conversion of the validated `spec`) up to
/// the 4th derivative by the smoothest reading above; every side gets order 4. Frames and
/// units as in constraints.hpp (world frame, [m], per unit u). The given rows hold exactly
/// (up to rounding): only free components change.
/// `energy_order` r selects the energy integral |d^r p/du^r|^2 du (2, 3 or 4; 3 is the
/// reading's definition, the others are kept for comparison).
Expected<void> fill_smoothest(const PathSpec& spec, std::vector<FrameConstraints>& frames, int energy_order = 3);

/// Fills every side up to the 4th derivative with zeros above what the frame fixes (the
/// thesis's reading); every side gets order 4.
void fill_thesis_zeros(std::vector<FrameConstraints>& frames);

/// The energy sum over segments of integral_0^1 |d^r p/du^r|^2 du [m^2] of the degree 9
/// path whose end derivatives are `frames` (every side of order 4). r in 2..4.
double path_energy(const PathSpec& spec, const std::vector<FrameConstraints>& frames, int energy_order = 3);

}  // namespace geotraj::core
