// Rest-to-rest speed profiles over the arc length of one portion of a path (thesis 6.3.2.4,
// Eqs. 6.11-6.13 with the erratum of 6.13; the double S of Biagiotti & Melchiorri,
// "Trajectory Planning for Automatic Machines and Robots", 3.4). A profile is a value: a
// list of pieces of constant jerk. Units: time [s], arc length s [m], speed [m/s],
// acceleration [m/s^2], jerk [m/s^3]. The arc length is measured along the portion from its
// start; the profile knows nothing about the curve.
#pragma once

#include <cstddef>
#include <vector>

#include "core/error.hpp"

namespace geotraj::core {

/// One piece of constant jerk, from time t0 until the next piece's t0 (the last piece until
/// the profile's duration). Within it, with dt = t - t0:
///   s = s0 + v0 dt + a0 dt^2 / 2 + j dt^3 / 6,  v = v0 + a0 dt + j dt^2 / 2,  a = a0 + j dt.
/// The acceleration may jump between pieces (trapezoids); s and v are continuous.
struct ProfilePiece {
  double t0 = 0.0;  ///< start time [s]
  double s0 = 0.0;  ///< arc length at t0 [m]
  double v0 = 0.0;  ///< speed at t0 [m/s]
  double a0 = 0.0;  ///< tangential acceleration at t0 [m/s^2]
  double j = 0.0;   ///< jerk over the piece [m/s^3]
};

/// A rest-to-rest motion over `length` metres in `duration` seconds: v = 0 at both ends.
/// Pieces are ordered by t0, the first at t0 = 0; pieces of zero length are left out. A
/// profile of a zero-length portion has no pieces and a zero duration.
struct SpeedProfile {
  std::vector<ProfilePiece> pieces;
  double duration = 0.0;  ///< T [s]
  double length = 0.0;    ///< L = s(T) [m]
};

/// The motion at one instant.
struct ProfileState {
  double s = 0.0;  ///< arc length from the portion's start [m]
  double v = 0.0;  ///< speed ds/dt [m/s], >= 0
  double a = 0.0;  ///< tangential acceleration d2s/dt2 [m/s^2]
  double j = 0.0;  ///< jerk [m/s^3]
};

/// The state at time t [s]. Inside [0, T] the piece containing t (at a piece boundary, the
/// later piece: its one-sided acceleration); at t = T, s = L and v = 0 exactly. Outside
/// [0, T] the motion is at rest: s = 0 before, s = L after, v = a = j = 0. O(log pieces).
ProfileState evaluate(const SpeedProfile& profile, double t);

/// Streaming position in a profile: evaluate(profile, t, cursor) is O(1) amortised for
/// non-decreasing t (it walks forward from the last piece used) and correct for any t.
struct ProfileCursor {
  std::size_t piece = 0;
};

/// As evaluate(profile, t), using and updating `cursor`.
ProfileState evaluate(const SpeedProfile& profile, double t, ProfileCursor& cursor);

/// Largest speed [m/s], largest |acceleration| [m/s^2] and largest |jerk| [m/s^3] of the
/// profile (exact: the speed's interior extrema, where a = 0 inside a piece, are included).
double peak_speed(const SpeedProfile& profile);
double peak_acceleration(const SpeedProfile& profile);
double peak_jerk(const SpeedProfile& profile);

/// The same motion `c` >= 1 times slower: s_c(t) = s(t / c), so every piece starts at c t0
/// with speed v0 / c, acceleration a0 / c^2 and jerk j / c^3, and the duration is c T. Along
/// a path every derivative of the pose (and of the joints that follow it) scales the same
/// way: velocities 1 / c, accelerations 1 / c^2, jerks 1 / c^3.
SpeedProfile time_scaled(SpeedProfile profile, double c);

/// Trapezoidal speed for a given duration (thesis Eqs. 6.11-6.13). With t_b = f T:
///   v_max = L / (T - t_b)  (6.11),  a_max = v_max / t_b  (6.12),
///   v(t) = a_max t for t < t_b;  v_max between;  a_max (T - t) for t > T - t_b  (6.13).
/// Deviation: 6.13 prints "a_max" for the first ramp and "v_max - a_max t" for the last;
/// the erratum above is what integrates to L (docs: thesis-notes.md).
/// length L >= 0 [m], duration T > 0 [s], ramp fraction f = t_b / T in (0, 0.5] (0.5: a
/// triangle). Errors name `length`, `durationS`, `rampFraction`.
Expected<SpeedProfile> trapezoid_profile(double length, double duration, double ramp_fraction);

/// S-curve for a given duration: the same ramps of length t_b = f T and the same
/// v_max = L / (T - t_b), with a triangular acceleration over each ramp (continuous
/// acceleration, bounded jerk): a_peak = 2 v_max / t_b at the middle of a ramp,
/// |jerk| = 4 v_max / t_b^2. Each ramp covers v_max t_b / 2, so s(T) = v_max (T - t_b) = L.
/// Same arguments and errors as trapezoid_profile.
Expected<SpeedProfile> scurve_profile(double length, double duration, double ramp_fraction);

/// Minimum-time trapezoid under |v| <= v_max [m/s] and |a| <= a_max [m/s^2]: ramps of
/// v_max / a_max and a cruise when L >= v_max^2 / a_max, else a triangle with peak speed
/// sqrt(L a_max). Errors name `length`, `maxSpeed`, `maxAcceleration`.
Expected<SpeedProfile> min_time_trapezoid(double length, double v_max, double a_max);

/// The fastest scurve_profile(length, T, f) whose speed stays within v_max [m/s] and whose
/// acceleration stays within a_max [m/s^2] (for a minimum-time S-curve without a jerk
/// limit). Its peaks are v = L / ((1 - f) T) and a = 2 L / (f (1 - f) T^2), so
///   T = max(L / ((1 - f) v_max), sqrt(2 L / (f (1 - f) a_max))).
/// A zero length gives the empty profile (zero duration). Errors name `length`,
/// `rampFraction`, `maxSpeed`, `maxAcceleration`.
Expected<SpeedProfile> min_time_scurve(double length, double ramp_fraction, double v_max, double a_max);

/// The grid profile of a timing optimiser with its acceleration steps smoothed out, so that
/// the jerk is finite at any sampling rate and the motion starts and ends with zero
/// acceleration. Input: N >= 2 intervals, interval i lasting dt_i > 0 [s] at the constant
/// acceleration u_i [m/s^2] (a profile whose acceleration steps at the grid points T_i, the
/// sums of the dt before i), and the length L > 0 [m] they cover from rest to rest.
/// Output: each step u_{i-1} -> u_i (u_{-1} = u_N = 0: the rests) replaced by a linear ramp
/// of jerk (u_i - u_{i-1}) / (2 h_i) over a window [T_i - h_i, T_i + h_i]:
///   interior points  h_i = min(dt_{i-1}, dt_i) / 2   (windows never overlap),
///   the rests        h_0 = dt_0 / 4, h_N = dt_{N-1} / 4,
/// the rests' windows taking the whole motion later by h_0 and longer by h_0 + h_N (at the
/// rests the jerk is then u_0 / (dt_0 / 2), the j_0 of time_optimal_jerk.hpp; inside, the
/// jerk is the j_i there, (u_i - u_{i-1}) / tau_i, where neighbouring intervals last alike,
/// and up to twice it where one lasts much longer). A linear ramp centred on the step keeps
/// the speed at both ends of its window exactly (so the speed at every grid point is the
/// grid's: no drift along the path) and moves the position by (u_i - u_{i-1}) h_i^2 / 6;
/// the profile is then scaled by L / s(T') so that it ends after exactly L (a relative change
/// of the order of (dt / T)^2). Constant jerk pieces, the acceleration continuous and zero at
/// both ends. Errors (field `motion`): the inputs are not as stated, or the speed turns
/// negative inside a window (a grid too coarse for its accelerations).
Expected<SpeedProfile> continuous_acceleration_profile(const std::vector<double>& dt, const std::vector<double>& u,
                                                       double length);

/// Minimum-time double S (seven phases, rest to rest; Biagiotti & Melchiorri 3.4) under
/// v_max, a_max and |jerk| <= j_max [m/s^3]. Cases: v_max reached or not (then the peak
/// speed v_lim < v_max and there is no cruise), and a_max reached or not (then each
/// acceleration phase is a triangle of jerk +-j_max). Rest to rest the cases are closed
/// forms (no iteration): with T_j = a_max / j_max,
///   v_max reached:  T_a = T_j + v_max / a_max if v_max j_max >= a_max^2, else
///                   T_j = sqrt(v_max / j_max), T_a = 2 T_j;  T_v = L / v_max - T_a >= 0;
///   otherwise:      T_a = (a_max^2 / j_max + sqrt(a_max^4 / j_max^2 + 4 a_max L)) / (2 a_max)
///                   if T_a >= 2 T_j, else T_j = cbrt(L / (2 j_max)), T_a = 2 T_j;  T_v = 0.
/// Errors name `length`, `maxSpeed`, `maxAcceleration`, `maxJerk`.
Expected<SpeedProfile> min_time_double_s(double length, double v_max, double a_max, double j_max);

/// The durations T [s] of min_time_trapezoid and min_time_double_s for valid arguments
/// (finite, length >= 0, limits > 0), without building the profile: no allocation, for
/// ranking many candidates (the slowest joint of a joint move).
double min_time_trapezoid_duration(double length, double v_max, double a_max);
double min_time_double_s_duration(double length, double v_max, double a_max, double j_max);

}  // namespace geotraj::core
