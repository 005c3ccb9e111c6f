#include "core/motion/speed_profile.hpp"
#include "core/format.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace geotraj::core {

namespace {

// Appends pieces of constant jerk and integrates the state exactly across each one.
struct Builder {
  SpeedProfile profile;
  double t = 0.0, s = 0.0, v = 0.0, a = 0.0;

  // A piece of duration dt [s] and jerk j [m/s^3]; zero-length pieces are left out.
  void add(double dt, double j) {
    if (!(dt > 0.0)) return;
    profile.pieces.push_back({t, s, v, a, j});
    s += dt * (v + dt * (a / 2 + dt * j / 6));
    v += dt * (a + dt * j / 2);
    a += dt * j;
    t += dt;
  }
  // A piece that starts with acceleration a0 (a jump from the previous piece's end).
  void add_with_acceleration(double dt, double a0, double j) {
    a = a0;
    add(dt, j);
  }
  SpeedProfile finish(double length) {
    profile.duration = t;
    profile.length = length;
    return std::move(profile);
  }
};


void check_length(double length, Violations& v) {
  if (!std::isfinite(length) || length < 0.0)
    v.push_back({"length", "must be a finite arc length >= 0 m, got " + number(length)});
}

void check_positive(const char* field, double x, const char* unit, Violations& v) {
  if (!std::isfinite(x) || !(x > 0.0))
    v.push_back({field, std::string("must be finite and > 0 ") + unit + ", got " + number(x)});
}

Violations check_timed(double length, double duration, double f) {
  Violations v;
  check_length(length, v);
  check_positive("durationS", duration, "s", v);
  if (!std::isfinite(f) || !(f > 0.0) || f > 0.5)
    v.push_back({"rampFraction", "must be in (0, 0.5] (ramp time over move time), got " + number(f)});
  return v;
}

ProfileState state_in(const SpeedProfile& p, std::size_t i, double t) {
  const ProfilePiece& q = p.pieces[i];
  const double dt = t - q.t0;
  ProfileState st;
  st.s = q.s0 + dt * (q.v0 + dt * (q.a0 / 2 + dt * q.j / 6));
  st.v = q.v0 + dt * (q.a0 + dt * q.j / 2);
  st.a = q.a0 + dt * q.j;
  st.j = q.j;
  // Rounding must not leave the profile's range: 0 <= s <= L, v >= 0.
  st.s = std::clamp(st.s, 0.0, p.length);
  st.v = std::max(st.v, 0.0);
  if (t >= p.duration) {
    st.s = p.length;  // rest to rest: exact at the end
    st.v = 0.0;
  }
  return st;
}

}  // namespace

ProfileState evaluate(const SpeedProfile& profile, double t, ProfileCursor& cursor) {
  const auto& pcs = profile.pieces;
  if (pcs.empty() || !(t >= 0.0)) return {};  // before the start (also NaN): at rest at s = 0
  if (t > profile.duration) return {profile.length, 0.0, 0.0, 0.0};
  if (cursor.piece >= pcs.size() || pcs[cursor.piece].t0 > t) {
    // Going back in time: binary search for the last piece with t0 <= t.
    const auto it = std::upper_bound(pcs.begin(), pcs.end(), t,
                                     [](double x, const ProfilePiece& q) { return x < q.t0; });
    cursor.piece = static_cast<std::size_t>(it - pcs.begin()) - 1;
  }
  while (cursor.piece + 1 < pcs.size() && pcs[cursor.piece + 1].t0 <= t) ++cursor.piece;
  return state_in(profile, cursor.piece, t);
}

ProfileState evaluate(const SpeedProfile& profile, double t) {
  ProfileCursor cursor{profile.pieces.size()};  // forces the binary search
  return evaluate(profile, t, cursor);
}

SpeedProfile time_scaled(SpeedProfile profile, double c) {
  for (ProfilePiece& piece : profile.pieces) {
    piece.t0 *= c;
    piece.v0 /= c;
    piece.a0 /= c * c;
    piece.j /= c * c * c;
  }
  profile.duration *= c;
  return profile;
}

double peak_speed(const SpeedProfile& profile) {
  double peak = 0.0;
  const auto& pcs = profile.pieces;
  for (std::size_t i = 0; i < pcs.size(); ++i) {
    const double t1 = i + 1 < pcs.size() ? pcs[i + 1].t0 : profile.duration;
    const ProfilePiece& q = pcs[i];
    peak = std::max({peak, q.v0, state_in(profile, i, t1).v});
    // Interior extremum of v where a = a0 + j dt = 0.
    if (q.j != 0.0) {
      const double dt = -q.a0 / q.j;
      if (dt > 0.0 && q.t0 + dt < t1) peak = std::max(peak, state_in(profile, i, q.t0 + dt).v);
    }
  }
  return peak;
}

double peak_acceleration(const SpeedProfile& profile) {
  double peak = 0.0;
  const auto& pcs = profile.pieces;
  for (std::size_t i = 0; i < pcs.size(); ++i) {
    const double t1 = i + 1 < pcs.size() ? pcs[i + 1].t0 : profile.duration;
    peak = std::max({peak, std::abs(pcs[i].a0), std::abs(pcs[i].a0 + (t1 - pcs[i].t0) * pcs[i].j)});
  }
  return peak;
}

double peak_jerk(const SpeedProfile& profile) {
  double peak = 0.0;
  for (const auto& q : profile.pieces) peak = std::max(peak, std::abs(q.j));
  return peak;
}

Expected<SpeedProfile> trapezoid_profile(double length, double duration, double ramp_fraction) {
  if (auto v = check_timed(length, duration, ramp_fraction); !v.empty()) return tl::make_unexpected(v);
  const double T = duration;
  const double t_b = ramp_fraction * T;
  const double v_max = length / (T - t_b);  // (6.11)
  const double a_max = v_max / t_b;         // (6.12)
  Builder b;
  b.add_with_acceleration(t_b, a_max, 0.0);           // (6.13, erratum) v = a_max t
  b.add_with_acceleration(T - 2 * t_b, 0.0, 0.0);     // v = v_max
  b.add_with_acceleration(T - b.t, -a_max, 0.0);      // (6.13, erratum) v = a_max (T - t)
  return b.finish(length);
}

Expected<SpeedProfile> scurve_profile(double length, double duration, double ramp_fraction) {
  if (auto v = check_timed(length, duration, ramp_fraction); !v.empty()) return tl::make_unexpected(v);
  const double T = duration;
  const double t_b = ramp_fraction * T;
  const double v_max = length / (T - t_b);       // as (6.11)
  const double jerk = 4.0 * v_max / (t_b * t_b);  // a_peak = jerk t_b / 2 = 2 v_max / t_b
  const double h = t_b / 2;
  Builder b;
  b.add(h, jerk);
  b.add(t_b - b.t, -jerk);
  b.add_with_acceleration(T - 2 * t_b, 0.0, 0.0);  // cruise at v_max
  b.add_with_acceleration(h, 0.0, -jerk);
  b.add(T - b.t, jerk);
  return b.finish(length);
}

Expected<SpeedProfile> continuous_acceleration_profile(const std::vector<double>& dt, const std::vector<double>& u,
                                                       double length) {
  const std::size_t N = dt.size();
  const bool finite = std::all_of(dt.begin(), dt.end(), [](double x) { return std::isfinite(x) && x > 0.0; }) &&
                      std::all_of(u.begin(), u.end(), [](double x) { return std::isfinite(x); });
  if (N < 2 || u.size() != N || !finite || !std::isfinite(length) || !(length > 0.0))
    return tl::make_unexpected(Violations{{"motion", "a smoothed grid profile needs at least 2 intervals of positive "
                                                     "duration, finite accelerations and a positive length"}});
  // Grid point i at the grid's time T_i (i = 0 .. N) steps u_{i-1} -> u_i (u_{-1} = u_N = 0:
  // the rests) over its window; every time is shifted by h_0, so the motion starts with
  // point 0's window at t = 0.
  auto half_width = [&](std::size_t i) {
    return i == 0 ? dt[0] / 4 : i == N ? dt[N - 1] / 4 : std::min(dt[i - 1], dt[i]) / 2;
  };
  Builder b;
  double T_i = 0.0, v_min = 0.0, v_max = 0.0;
  const double shift = half_width(0);
  for (std::size_t i = 0; i <= N; ++i) {
    const double h = half_width(i), before = i == 0 ? 0.0 : u[i - 1], after = i == N ? 0.0 : u[i];
    b.add(T_i + shift - h - b.t, 0.0);  // at u_{i-1} up to the window (nothing before point 0's)
    const double v0 = b.v, a0 = b.a, j = (after - before) / (2 * h);
    b.add(2 * h, j);
    v_min = std::min(v_min, b.v), v_max = std::max(v_max, b.v);
    if (j != 0.0) {  // the speed's extremum inside the window, where a = a0 + j t = 0
      const double at = -a0 / j;
      if (at > 0.0 && at < 2 * h) v_min = std::min(v_min, v0 + at * (a0 + at * j / 2));
    }
    if (i < N) T_i += dt[i];
  }
  if (v_min < -1e-9 * v_max || !(b.s > 0.0))
    return tl::make_unexpected(Violations{core::unattainable(
        "motion", "smoothing the grid profile's acceleration steps turns the speed negative (" + number(v_min, 6) +
                      " m/s): use a finer grid")});
  // Each window moves the position by (u_i - u_{i-1}) h_i^2 / 6 (the speed is exact at both of
  // its ends): the whole motion is scaled to end after exactly `length` (s, v, a, j alike).
  const double scale = length / b.s;
  for (ProfilePiece& q : b.profile.pieces) q.s0 *= scale, q.v0 *= scale, q.a0 *= scale, q.j *= scale;
  return b.finish(length);
}

namespace {

// The phases of min_time_trapezoid: each ramp t_a [s], the cruise t_v [s].
struct TrapezoidTimes {
  double t_a = 0.0, t_v = 0.0;
};

TrapezoidTimes trapezoid_times(double length, double v_max, double a_max) {
  double v_peak = v_max, t_v = 0.0;
  if (length >= v_max * v_max / a_max) {
    t_v = (length - v_max * v_max / a_max) / v_max;
  } else {
    v_peak = std::sqrt(length * a_max);  // triangle: L = v_peak^2 / a_max
  }
  return {v_peak / a_max, t_v};
}

// The phases of min_time_double_s: each jerk phase t_j, each ramp t_a (acceleration and
// deceleration alike), the cruise t_v [s].
struct DoubleSTimes {
  double t_j = 0.0, t_a = 0.0, t_v = 0.0;
};

DoubleSTimes double_s_times(double length, double v_max, double a_max, double j_max) {
  // Biagiotti & Melchiorri (3.4), rest to rest (v0 = v1 = 0), symmetric: T_d = T_a.
  double t_j, t_a, t_v;
  if (v_max * j_max >= a_max * a_max) {
    t_j = a_max / j_max;
    t_a = t_j + v_max / a_max;
  } else {
    t_j = std::sqrt(v_max / j_max);  // a_max not reached on the way to v_max
    t_a = 2 * t_j;
  }
  t_v = length / v_max - t_a;  // L = v_max (T_a + T_v) rest to rest
  if (t_v < 0.0) {
    // v_max not reached: no cruise; first try with a_max reached.
    t_v = 0.0;
    t_j = a_max / j_max;
    const double delta = a_max * a_max * a_max * a_max / (j_max * j_max) + 4.0 * a_max * length;
    t_a = (a_max * a_max / j_max + std::sqrt(delta)) / (2.0 * a_max);
    if (t_a < 2 * t_j) {
      // a_max not reached either: two jerk phases per ramp, L = 2 j_max T_j^3.
      t_j = std::cbrt(length / (2.0 * j_max));
      t_a = 2 * t_j;
    }
  }
  return {t_j, t_a, t_v};
}

}  // namespace

Expected<SpeedProfile> min_time_trapezoid(double length, double v_max, double a_max) {
  Violations v;
  check_length(length, v);
  check_positive("maxSpeed", v_max, "m/s", v);
  check_positive("maxAcceleration", a_max, "m/s^2", v);
  if (!v.empty()) return tl::make_unexpected(v);
  Builder b;
  if (length == 0.0) return b.finish(0.0);
  const TrapezoidTimes t = trapezoid_times(length, v_max, a_max);
  b.add_with_acceleration(t.t_a, a_max, 0.0);
  b.add_with_acceleration(t.t_v, 0.0, 0.0);
  b.add_with_acceleration(t.t_a, -a_max, 0.0);
  return b.finish(length);
}

double min_time_trapezoid_duration(double length, double v_max, double a_max) {
  const TrapezoidTimes t = trapezoid_times(length, v_max, a_max);
  return 2.0 * t.t_a + t.t_v;
}

Expected<SpeedProfile> min_time_scurve(double length, double ramp_fraction, double v_max, double a_max) {
  Violations v;
  check_length(length, v);
  if (!std::isfinite(ramp_fraction) || !(ramp_fraction > 0.0) || ramp_fraction > 0.5)
    v.push_back({"rampFraction", "must be in (0, 0.5] (ramp time over move time), got " + number(ramp_fraction)});
  check_positive("maxSpeed", v_max, "m/s", v);
  check_positive("maxAcceleration", a_max, "m/s^2", v);
  if (!v.empty()) return tl::make_unexpected(v);
  if (length == 0.0) return Builder{}.finish(0.0);
  const double f = ramp_fraction;
  const double t_speed = length / ((1.0 - f) * v_max);                     // v_max = L / (T - t_b)  (6.11)
  const double t_accel = std::sqrt(2.0 * length / (f * (1.0 - f) * a_max));  // a_peak = 2 v_max / t_b
  return scurve_profile(length, std::max(t_speed, t_accel), f);
}

Expected<SpeedProfile> min_time_double_s(double length, double v_max, double a_max, double j_max) {
  Violations v;
  check_length(length, v);
  check_positive("maxSpeed", v_max, "m/s", v);
  check_positive("maxAcceleration", a_max, "m/s^2", v);
  check_positive("maxJerk", j_max, "m/s^3", v);
  if (!v.empty()) return tl::make_unexpected(v);
  Builder b;
  if (length == 0.0) return b.finish(0.0);
  const DoubleSTimes t = double_s_times(length, v_max, a_max, j_max);
  b.add(t.t_j, j_max);
  b.add(t.t_a - 2 * t.t_j, 0.0);
  b.add(t.t_j, -j_max);
  b.add_with_acceleration(t.t_v, 0.0, 0.0);
  b.add_with_acceleration(t.t_j, 0.0, -j_max);
  b.add(t.t_a - 2 * t.t_j, 0.0);
  b.add(t.t_j, j_max);
  return b.finish(length);
}

double min_time_double_s_duration(double length, double v_max, double a_max, double j_max) {
  const DoubleSTimes t = double_s_times(length, v_max, a_max, j_max);
  return 2.0 * t.t_a + t.t_v;
}

}  // namespace geotraj::core
