// Translational motion along a path, u = f(t) (thesis 6.3.2, 7.2.9). The path is split
// into portions between rests (start, end, every cusp and every frame with `stop`: the
// speed is zero there, 6.3.2.5); each portion moves rest to rest along its arc length with
// its own speed profile (speed_profile.hpp). A MotionSampler then turns the plan into
// samples at the cycle rate: by default each sample lands where the profile puts it along
// the arc (kArcLength); the thesis's interpolators (6.3, 6.5, 6.9, 6.15) are available for
// comparison. Positions, velocities and accelerations are in the world frame W of the path:
// [m], [m/s], [m/s^2]; time [s].
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "core/error.hpp"
#include "core/geometry/path.hpp"
#include "core/motion/speed_profile.hpp"

namespace geotraj::core {

/// The shape of each portion's speed profile.
enum class ProfileShape {
  kTrapezoidal,  ///< constant acceleration ramps (thesis 6.11-6.13; min-time trapezoid)
  kSCurve,       ///< continuous acceleration, bounded jerk (double S when minimum-time)
};

/// How a sample's path parameter u follows from its time.
enum class TimeParameterization {
  kArcLength,           ///< u(s(t)) exactly: s(t) from the profile, u(s) by Newton
  kLinear,              ///< u linear in time over each portion (thesis Eq. 6.3)
  kSmooth,              ///< u = u_i + q(t/T) (u_f - u_i), q the quintic 10x^3 - 15x^4 + 6x^5 (6.4, 6.5)
  kTaylorFirstOrder,    ///< u_{k+1} = u_k + v(t) dt / |p'(u_k)|  (6.9)
  kTaylorSecondOrder,   ///< u_{k+1} = u_k + u_t dt + u_tt dt^2 / 2 with (6.8), (6.14)  (6.15)
};

/// What the operator asks of the motion. JSON names in brackets (field paths of errors are
/// `motion.<jsonName>`).
struct MotionSpec {
  /// Total move time [s] (durationS), >= 0. 0: as fast as the limits allow (then maxSpeed
  /// and maxAcceleration are required, and maxJerk for the S-curve). With a duration > 0
  /// the limits are not used.
  double duration_s = 0.0;
  ProfileShape profile = ProfileShape::kTrapezoidal;
  /// t_b / T_i of each portion's ramps (rampFraction), in (0, 0.5]; used with a duration.
  double ramp_fraction = 0.15;
  bool ramp_fraction_given = false;  ///< the request gave rampFraction (refused with ramp_time_s)
  /// Every ramp's time [s] (rampTimeS, Table 6.2's RampTime), > 0, instead of the fraction:
  /// all portions share one peak speed v = L / (T - n t_b) for n portions (rests between
  /// them), portion i lasting T_i = L_i / v + t_b. Used with a duration only.
  std::optional<double> ramp_time_s;
  /// Samples per second (cycleRateHz), in (0, 1e5] [Hz]. The thesis uses 100 Hz.
  double cycle_rate_hz = 100.0;
  TimeParameterization time_parameterization = TimeParameterization::kArcLength;
  /// Multiplies every speed (speedScale), in (0, 1]: the duration is divided by it, the
  /// minimum-time limits become v_max s, a_max s^2, j_max s^3 (the same motion, slower).
  double speed_scale = 1.0;
  /// Multiplies every acceleration and jerk limit of a minimum-time timing (joint and
  /// Cartesian), in (0, 1], the velocity limits unchanged: Execute's acceleration reserve
  /// (planner::reserve_room), so that a motion whose pace a speed limit sets keeps it. Not
  /// on the wire.
  double acceleration_scale = 1.0;
  std::optional<double> max_speed;         ///< [m/s] (maxSpeed), > 0
  std::optional<double> max_acceleration;  ///< [m/s^2] (maxAcceleration), > 0: tangential and centripetal
  std::optional<double> max_jerk;          ///< [m/s^3] (maxJerk), > 0: tangential
  /// The tool's angular speed |omega| [rad/s] (maxAngularSpeed) and angular acceleration
  /// |alpha| [rad/s^2] (maxAngularAcceleration), > 0: imposed by the time-optimal timing
  /// (time_optimal.hpp) and a straight line's minimum time (moves.hpp).
  std::optional<double> max_angular_speed;
  std::optional<double> max_angular_acceleration;
};

/// Largest cycle rate [Hz] and largest number of samples of one plan (bounds the work).
inline constexpr double kMaxCycleRateHz = 1e5;
inline constexpr double kMaxMotionSamples = 1e9;

/// The sample grid at the cycle rate, one rule for every motion (a path's, a move's, a
/// time-optimal one): t_k = k / rate for k = 0 .. floor(T rate + 1e-9), plus one sample at
/// exactly T when the grid does not land on it; when it lands (to 1e-9 of a period) its last
/// sample is taken at exactly T. Precondition: T rate < kMaxMotionSamples.
std::size_t grid_sample_count(double duration_s, double rate_hz);
/// Time of sample k of `count` on that grid [s]: k / rate, the last one exactly at T.
double grid_time(std::size_t k, std::size_t count, double duration_s, double rate_hz);

/// What sets a motion's time.
enum class MotionTiming {
  kProfile,  ///< the profile: durationS, or (durationS 0) the minimum-time trapezoid or
             ///< S-curve through maxSpeed, maxAcceleration (and maxJerk)
  kLimits,   ///< the limits: a time-optimal timing or a joint move, whose time is the result
};

/// Checks every field of `spec` on its own (finite numbers, ranges above) and, timed by its
/// profile, the combinations that need no path (duration 0 needs maxSpeed and
/// maxAcceleration, named on `motion.durationS`; the minimum-time S-curve needs maxJerk, named
/// on `motion.maxJerk`; rampTimeS needs a duration). Timed by the limits, those combinations
/// do not apply. Field paths are `motion.durationS`, `motion.rampFraction`, ... Empty when
/// all is well.
Violations validate_motion(const MotionSpec& spec, MotionTiming timing = MotionTiming::kProfile);

/// One rest-to-rest part of the motion.
struct MotionPortion {
  double u_start = 0.0;  ///< global path parameter of the starting rest (an integer: a frame)
  double u_end = 0.0;    ///< global u of the ending rest (M for the end of the path)
  double s_start = 0.0;  ///< arc length of the path at u_start [m]
  double length = 0.0;   ///< arc length of the portion [m]
  double t_start = 0.0;  ///< time of the starting rest [s]
  /// Largest curvature on the portion [1/m] (minimum-time plans only; 0 otherwise): the
  /// centripetal speed cap is sqrt(a_max / kappa_max).
  double kappa_max = 0.0;
  SpeedProfile profile;  ///< over [0, profile.duration], s from 0 to length

  double t_end() const { return t_start + profile.duration; }
};

/// A timed motion along a path: a value, sampled by MotionSampler.
struct MotionPlan {
  MotionSpec spec;
  std::vector<MotionPortion> portions;  ///< in path order, back to back in time
  double duration_s = 0.0;              ///< total time [s], after speedScale
  /// Samples at t_k = k / rate for k = 0 .. floor(duration * rate + 1e-9), plus one final
  /// sample at exactly t = duration when the grid does not land on it; when it lands (to
  /// 1e-9 of a period), the last grid sample is taken at exactly t = duration.
  std::size_t sample_count = 0;
  double peak_speed = 0.0;         ///< largest profile speed over the portions [m/s]
  double peak_acceleration = 0.0;  ///< largest |tangential acceleration| of the profiles [m/s^2]
};

/// Plans the motion along `path`.
///  - Portions: rests at u = 0, at every frame k with `cusp` or `stop` (frame k sits at
///    global u = k) and at the end (u = M; for a closed path the end is back at frame 0).
///  - With a duration D: portion i gets T_i = (D / speedScale) L_i / L, so that every
///    portion reaches the SAME peak speed v_max = L / ((D / speedScale)(1 - f)) with the
///    ramp-fraction profiles (trapezoid 6.11-6.13 or S-curve).
///  - With D = 0: the minimum-time trapezoid or double S under v = min(maxSpeed,
///    sqrt(maxAcceleration / kappa_max)), maxAcceleration (tangential) and maxJerk, where
///    kappa_max is the largest curvature on the portion (sampled at 200 points per segment,
///    each segment's largest sample refined by golden section). The centripetal bound
///    kappa v^2 <= a_max (thesis 7.3.4.1) is thus enforced as a speed CAP OVER THE WHOLE
///    PORTION: conservative where the curvature is lower. Tangential and centripetal parts
///    are bounded separately (the magnitude of the total may reach sqrt(2) a_max).
/// Errors: validate_motion's, and `motion.durationS` when the sample count would exceed
/// kMaxMotionSamples or the path has zero length.
Expected<MotionPlan> plan_motion(const Path& path, const MotionSpec& spec);

/// One sample of the motion. Frame W, SI units.
struct MotionSample {
  double t = 0.0;              ///< time [s]
  double u = 0.0;              ///< global path parameter in [0, M]
  double s = 0.0;              ///< arc length from the path's start at u [m]
  std::size_t segment = 0;     ///< segment the sample was evaluated on
  std::size_t portion = 0;     ///< index of the portion in MotionPlan::portions
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();  ///< position [m]
  Eigen::Vector3d v_W = Eigen::Vector3d::Zero();  ///< velocity [m/s]
  Eigen::Vector3d a_W = Eigen::Vector3d::Zero();  ///< acceleration [m/s^2]
  double speed = 0.0;          ///< |v_W| [m/s]; 0 at rests (except kLinear, 6.3)
  /// Path acceleration d2s/dt2 [m/s^2] (the profile's tangential acceleration for
  /// kArcLength): what the tool's angular acceleration needs (orientation_at).
  double s_ddot = 0.0;
};

/// Streams the samples of a plan (a workspace: no heap allocation per sample). `path` and
/// `plan` must outlive the sampler and be the ones the plan was made from.
///
/// kArcLength: s*(t) from the portion's profile; u solves s(u) = s* by Newton warm-started
/// from the previous sample (ds/du = |dp/du|, thesis 2.36), to |s(u) - s*| <= 1e-12 m.
/// s(u) is carried from the previous sample by 6-point Gauss-Legendre over panels of at
/// most 1/64 in u, split at trapezoid breakpoints, and re-anchored at every frame to the
/// path's adaptive segment lengths; Newton's short corrections (|du| <= 1e-3 on a
/// polynomial segment) use the two-point Hermite rule on ds/du and d2s/du2, whose jets are
/// at hand. Velocity and acceleration are analytic (2.29-2.31):
///   u_t = v / |p'|  (6.8),  u_tt = a / |p'| - v^2 (p' . p'') / |p'|^4  (6.14),
///   v_W = p' u_t,  a_W = p'' u_t^2 + p' u_tt.
/// kLinear / kSmooth: u(t) per portion from 6.3 / 6.5, u_t and u_tt of that map.
/// kTaylorFirstOrder / kTaylorSecondOrder: u steps with 6.9 / 6.15 using the profile's v, a
/// at the current sample time and the curve at the current u; clamped at the portion's end;
/// a sample at or after the portion's end time is put at the rest; a sample in a later
/// portion restarts from that portion's starting rest. v_W, a_W are the chain rule above
/// with the profile's v, a at the stepped u.
/// A sample at a rest between portions belongs to the later portion (its one-sided
/// acceleration); the last sample is the final rest with v_W = a_W = 0.
class MotionSampler {
 public:
  MotionSampler(const Path& path, const MotionPlan& plan);

  /// Writes the next sample and returns true, or returns false after the last one.
  bool next(MotionSample& sample);
  /// Writes the sample at time t [s] (live execution: t off the grid). Times must not
  /// decrease from one call to the next (a smaller t is taken as the previous one; the
  /// Taylor parameterisations step from the previous sample); t at or after the duration is
  /// the final rest. Do not mix with next() without reset().
  void at(double t, MotionSample& sample);
  /// Starts again from t = 0.
  void reset();
  /// Index of the next sample.
  std::size_t index() const { return k_; }

 private:
  struct Point {
    std::size_t segment = 0;
    double u_local = 0.0;
  };
  double time_of(std::size_t k) const;
  void sample(double t, bool last, MotionSample& out);
  Point point_in_portion(double u) const;
  double arc_length_to(const Point& q) const;
  void enter_portion(std::size_t i);
  double solve_arc_length(double s_target, double u_guess);

  const Path* path_;
  const MotionPlan* plan_;
  double period_ = 0.0;
  std::size_t k_ = 0;
  std::size_t portion_ = 0;
  ProfileCursor cursor_;
  // Anchor of the arc-length integration: the last accepted point and its arc length.
  Point anchor_;
  double anchor_s_ = 0.0;
  double u_ = 0.0;       // current global u
  double t_prev_ = 0.0;  // time of the previous sample (Taylor steps)
  Jet jet_{};            // jet at the current u
};

}  // namespace geotraj::core
