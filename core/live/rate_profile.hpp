// A jerk-limited change of one rate: the 1-D building block of live execution (a speed
// factor along a fixed path) and jogging (one joint velocity).
//
// A value v (a path's speed factor [1], or a joint velocity [rad/s or m/s]) moves from the
// state (v0, a0 = dv/dt) to v1 at rest (a = 0) with |dv/dt| <= a_max and |d2v/dt2| <= j_max,
// in the least time: at most three phases of constant jerk (jerk d j_max, acceleration held at
// d a_p, jerk -d j_max), with d the direction that v must go once a0 has been brought to zero.
// This is the velocity interface of a third-order (jerk-limited) 1-D motion, as in Ruckig
// (Berscheid and Kroeger, RSS 2021), reduced to the case that live execution needs: target
// acceleration zero and no velocity bound.
//
// Phases with d = +1 (mirror v and a for d = -1), a_p the peak acceleration:
//   phase 1  a: a0 -> a_p   duration |a_p - a0| / j_max   dv1 = (a0 + a_p) |a_p - a0| / (2 j_max)
//   phase 2  a = a_p        duration dv2 / a_p           dv2 = v1 - v0 - dv1 - dv3
//   phase 3  a: a_p -> 0    duration a_p / j_max          dv3 = a_p^2 / (2 j_max)
// a_p = a_max when dv2 >= 0 there, else a_p = sqrt(j_max (v1 - v0) + a0^2 / 2) and no phase 2.
// The integral x(t) = int_0^t v is carried too (a path's nominal time, a joint's position).
#pragma once

#include <array>
#include <cstddef>
#include <utility>

namespace geotraj::core {

/// The state of a rate profile at one time.
struct RateState {
  double x = 0.0;  ///< int v dt from the profile's start [unit of v times s]
  double v = 0.0;  ///< the rate
  double a = 0.0;  ///< dv/dt [unit of v per s]
  double j = 0.0;  ///< d2v/dt2 [unit of v per s^2] (the phase's constant jerk)
};

/// A jerk-limited change of a rate (see the file comment); after its last phase v stays at
/// the target with a = 0.
class RateProfile {
 public:
  /// v at rest: v(t) = v0 for every t.
  explicit RateProfile(double v0 = 0.0);
  /// From (v0, a0) to v1 at rest, |a| <= max(a_max, |a0|), |jerk| <= j_max (a_max, j_max
  /// finite and > 0). An a0 beyond a_max (the limit lowered meanwhile) is brought back
  /// within it by the first phase.
  static RateProfile plan(double v0, double a0, double v1, double a_max, double j_max);

  /// The state t [s] after the start (t >= 0; beyond the end, v = target, a = 0).
  RateState at(double t) const;
  /// Time to reach the target [s].
  double duration() const { return duration_; }
  /// The target value.
  double target() const { return end_.v; }
  /// x at the end of the last phase.
  double distance() const { return end_.x; }
  /// The smallest and largest v over the profile.
  std::pair<double, double> range() const;
  double min_value() const { return range().first; }
  double max_value() const { return range().second; }

 private:
  struct Phase {
    double duration = 0.0;
    double jerk = 0.0;
  };
  static RateState advance(const RateState& s, double jerk, double dt);

  RateState start_;
  std::array<Phase, 3> phases_{};
  std::array<RateState, 3> phase_start_{};
  std::size_t count_ = 0;
  RateState end_;
  double duration_ = 0.0;
};

}  // namespace geotraj::core
