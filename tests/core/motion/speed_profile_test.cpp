// Speed profiles: the closed forms of thesis Eqs. 6.11-6.13 (with the erratum) and of the
// S-curve, and the minimum-time trapezoid and double S (short, medium and long portions):
// rest to rest, s(T) = L, continuity, limits respected and tight.
#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "core/motion/speed_profile.hpp"

namespace geotraj::test {
namespace {

using core::ProfileState;
using core::SpeedProfile;

// Walks the profile on a fine grid and checks continuity of s and v (and of a when
// `continuous_a`), monotone s, v >= 0, and returns the observed maxima.
struct Walk {
  double v_max = 0, a_max = 0, j_max = 0;
};
Walk walk(const SpeedProfile& p, bool continuous_a) {
  Walk w;
  const int n = 20000;
  ProfileState prev = core::evaluate(p, 0.0);
  core::ProfileCursor cursor;
  const double scale_s = std::max(p.length, 1e-300);
  for (int i = 1; i <= n; ++i) {
    const double t = p.duration * i / n;
    const ProfileState st = core::evaluate(p, t, cursor);
    const ProfileState ref = core::evaluate(p, t);
    EXPECT_EQ(st.s, ref.s) << "cursor and search disagree at t = " << t;
    const double dt = p.duration / n;
    EXPECT_GE(st.s, prev.s - 1e-15 * scale_s) << "s not monotone at t = " << t;
    EXPECT_GE(st.v, 0.0);
    // Continuity: the step over dt is bounded by the next derivative's bound.
    EXPECT_LE(std::abs(st.s - prev.s), dt * (std::max(st.v, prev.v) + 1e-12) + 1e-12 * scale_s);
    w.v_max = std::max(w.v_max, st.v);
    w.a_max = std::max(w.a_max, std::abs(st.a));
    w.j_max = std::max(w.j_max, std::abs(st.j));
    prev = st;
  }
  // v continuous: |dv| <= a_max dt; a continuous (S-curve): |da| <= j_max dt.
  prev = core::evaluate(p, 0.0);
  for (int i = 1; i <= n; ++i) {
    const double t = p.duration * i / n, dt = p.duration / n;
    const ProfileState st = core::evaluate(p, t);
    EXPECT_LE(std::abs(st.v - prev.v), w.a_max * dt * (1 + 1e-9) + 1e-12) << "v jumps at t = " << t;
    if (continuous_a) { EXPECT_LE(std::abs(st.a - prev.a), w.j_max * dt * (1 + 1e-9) + 1e-9) << "a jumps at t = " << t; }
    prev = st;
  }
  return w;
}

void expect_rest_to_rest(const SpeedProfile& p) {
  const auto s0 = core::evaluate(p, 0.0), s1 = core::evaluate(p, p.duration);
  EXPECT_EQ(s0.s, 0.0);
  EXPECT_EQ(s0.v, 0.0);
  EXPECT_EQ(s1.s, p.length);
  EXPECT_EQ(s1.v, 0.0);
  // The last piece integrates to L by itself too (no snapping hides a wrong profile).
  const auto& q = p.pieces.back();
  const double dt = p.duration - q.t0;
  EXPECT_NEAR(q.s0 + q.v0 * dt + q.a0 * dt * dt / 2 + q.j * dt * dt * dt / 6, p.length, 1e-12 * p.length);
  EXPECT_NEAR(q.v0 + q.a0 * dt + q.j * dt * dt / 2, 0.0, 1e-12 * std::max(1.0, core::peak_speed(p)));
  // Outside [0, T]: at rest.
  const auto before = core::evaluate(p, -1.0), after = core::evaluate(p, p.duration + 1.0);
  EXPECT_EQ(before.s, 0.0);
  EXPECT_EQ(before.v, 0.0);
  EXPECT_EQ(after.s, p.length);
  EXPECT_EQ(after.v, 0.0);
  EXPECT_EQ(after.a, 0.0);
}

TEST(SpeedProfile, TrapezoidClosedFormEq6_11To6_13) {
  for (double f : {0.05, 0.15, 0.3, 0.5}) {
    const double L = 1.234, T = 10.0, t_b = f * T;
    const auto p = core::trapezoid_profile(L, T, f);
    ASSERT_TRUE(p.has_value());
    EXPECT_DOUBLE_EQ(p->duration, T);
    expect_rest_to_rest(*p);
    const double v_max = L / (T - t_b), a_max = v_max / t_b;  // (6.11), (6.12)
    EXPECT_NEAR(core::peak_speed(*p), v_max, 1e-14);
    EXPECT_NEAR(core::peak_acceleration(*p), a_max, 1e-14);
    // (6.13) with the erratum.
    for (double t : {0.3 * t_b, 0.9 * t_b}) EXPECT_NEAR(core::evaluate(*p, t).v, a_max * t, 1e-14);
    for (double t : {T - 0.3 * t_b, T - 0.9 * t_b}) EXPECT_NEAR(core::evaluate(*p, t).v, a_max * (T - t), 1e-14);
    if (f < 0.5) { EXPECT_NEAR(core::evaluate(*p, T / 2).v, v_max, 1e-14); }
    const Walk w = walk(*p, false);
    EXPECT_LE(w.v_max, v_max * (1 + 1e-12));
    EXPECT_EQ(w.j_max, 0.0);
  }
}

TEST(SpeedProfile, SCurveClosedForm) {
  for (double f : {0.1, 0.15, 0.25, 0.5}) {
    const double L = 0.8, T = 5.0, t_b = f * T;
    const auto p = core::scurve_profile(L, T, f);
    ASSERT_TRUE(p.has_value());
    expect_rest_to_rest(*p);
    const double v_max = L / (T - t_b);
    EXPECT_NEAR(core::peak_speed(*p), v_max, 1e-14);
    EXPECT_NEAR(core::peak_acceleration(*p), 2 * v_max / t_b, 1e-13);
    EXPECT_NEAR(core::peak_jerk(*p), 4 * v_max / (t_b * t_b), 1e-12);
    EXPECT_NEAR(core::evaluate(*p, t_b).v, v_max, 1e-14);
    EXPECT_NEAR(core::evaluate(*p, t_b / 2).a, 2 * v_max / t_b, 1e-13);
    EXPECT_NEAR(core::evaluate(*p, 0.0).a, 0.0, 1e-15);
    const Walk w = walk(*p, true);
    EXPECT_LE(w.j_max, 4 * v_max / (t_b * t_b) * (1 + 1e-12));
  }
}

TEST(SpeedProfile, BadArgumentsNameTheField) {
  const auto a = core::trapezoid_profile(-1.0, 0.0, 0.7);
  ASSERT_FALSE(a.has_value());
  ASSERT_EQ(a.error().size(), 3u);
  EXPECT_EQ(a.error()[0].field, "length");
  EXPECT_EQ(a.error()[1].field, "durationS");
  EXPECT_EQ(a.error()[2].field, "rampFraction");
  const auto b = core::min_time_double_s(1.0, NAN, 1.0, 0.0);
  ASSERT_FALSE(b.has_value());
  ASSERT_EQ(b.error().size(), 2u);
  EXPECT_EQ(b.error()[0].field, "maxSpeed");
  EXPECT_EQ(b.error()[1].field, "maxJerk");
  EXPECT_FALSE(core::scurve_profile(1.0, 1.0, 0.0).has_value());
}

TEST(SpeedProfile, ZeroLengthIsAnEmptyRest) {
  const auto p = core::min_time_trapezoid(0.0, 1.0, 1.0);
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->duration, 0.0);
  EXPECT_EQ(core::evaluate(*p, 0.0).s, 0.0);
  EXPECT_EQ(core::evaluate(*p, 1.0).v, 0.0);
}

// s_c(t) = s(t / c): the same arc length at c times the time, speed 1 / c, acceleration
// 1 / c^2, jerk 1 / c^3, at every instant (a double S: every piece has a jerk).
TEST(SpeedProfile, TimeScaledIsTheSameMotionSlower) {
  const auto p = core::min_time_double_s(0.7, 0.5, 2.0, 20.0);
  ASSERT_TRUE(p.has_value());
  const double c = 1.7;
  const core::SpeedProfile slow = core::time_scaled(*p, c);
  EXPECT_DOUBLE_EQ(slow.duration, c * p->duration);
  EXPECT_EQ(slow.length, p->length);
  for (int k = 0; k <= 200; ++k) {
    const double t = p->duration * k / 200.0;
    const core::ProfileState a = core::evaluate(*p, t), b = core::evaluate(slow, c * t);
    EXPECT_NEAR(b.s, a.s, 1e-12) << t;
    EXPECT_NEAR(b.v, a.v / c, 1e-12) << t;
    EXPECT_NEAR(b.a, a.a / (c * c), 1e-10) << t;
    EXPECT_NEAR(b.j, a.j / (c * c * c), 1e-9) << t;
  }
  EXPECT_NEAR(core::peak_jerk(slow), core::peak_jerk(*p) / (c * c * c), 1e-9);
}

// Short (triangle), medium and long (cruise) portions.
TEST(SpeedProfile, MinTimeTrapezoidRespectsAndReachesLimits) {
  const double v = 0.5, a = 2.0;  // v^2 / a = 0.125 m
  for (double L : {0.01, 0.125, 0.3, 5.0}) {
    SCOPED_TRACE(L);
    const auto p = core::min_time_trapezoid(L, v, a);
    ASSERT_TRUE(p.has_value());
    expect_rest_to_rest(*p);
    const Walk w = walk(*p, false);
    EXPECT_LE(core::peak_speed(*p), v * (1 + 1e-12));
    EXPECT_NEAR(core::peak_acceleration(*p), a, 1e-12);  // tight: a_max always reached
    if (L >= v * v / a) {
      EXPECT_NEAR(core::peak_speed(*p), v, 1e-12);
      EXPECT_NEAR(p->duration, L / v + v / a, 1e-12);
    } else {
      EXPECT_NEAR(core::peak_speed(*p), std::sqrt(L * a), 1e-12);
      EXPECT_NEAR(p->duration, 2 * std::sqrt(L / a), 1e-12);
    }
    EXPECT_LE(w.a_max, a * (1 + 1e-12));
  }
}

// The four cases of the double S: v_max and a_max each reached or not.
TEST(SpeedProfile, MinTimeDoubleSRespectsAndReachesLimits) {
  struct Case {
    double L, v, a, j;
    bool v_reached, a_reached;
  };
  const Case cases[] = {
      {10.0, 1.0, 2.0, 10.0, true, true},     // long: cruise, a_max reached (v j >= a^2)
      {10.0, 1.0, 5.0, 10.0, true, false},    // long, v j < a^2: a_max not reached
      {0.5, 1.0, 2.0, 10.0, false, true},     // medium: no cruise, a_max reached
      {0.01, 1.0, 2.0, 10.0, false, false},   // short: jerk only
      {0.4, 1.0, 2.0, 10.0, false, true},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(::testing::Message() << "L=" << c.L << " v=" << c.v << " a=" << c.a << " j=" << c.j);
    const auto p = core::min_time_double_s(c.L, c.v, c.a, c.j);
    ASSERT_TRUE(p.has_value());
    expect_rest_to_rest(*p);
    const Walk w = walk(*p, true);
    EXPECT_LE(core::peak_speed(*p), c.v * (1 + 1e-12));
    EXPECT_LE(core::peak_acceleration(*p), c.a * (1 + 1e-12));
    EXPECT_NEAR(core::peak_jerk(*p), c.j, 1e-12);  // tight: j_max always used
    if (c.v_reached) { EXPECT_NEAR(core::peak_speed(*p), c.v, 1e-12); } else { EXPECT_LT(core::peak_speed(*p), c.v * (1 - 1e-6)); }
    if (c.a_reached) { EXPECT_NEAR(core::peak_acceleration(*p), c.a, 1e-12); } else { EXPECT_LT(core::peak_acceleration(*p), c.a * (1 - 1e-6)); }
    EXPECT_LE(w.j_max, c.j * (1 + 1e-12));
  }
}

// Minimum time: a little more speed or acceleration budget can only shorten it, a little
// less lengthens it (a tightness check that does not rely on the case formulas).
TEST(SpeedProfile, MinTimeIsMonotoneInTheLimits) {
  for (double L : {0.01, 0.3, 3.0}) {
    const double base = core::min_time_double_s(L, 1.0, 2.0, 10.0)->duration;
    EXPECT_LE(core::min_time_double_s(L, 1.1, 2.2, 11.0)->duration, base);
    EXPECT_GT(core::min_time_double_s(L, 0.9, 1.8, 9.0)->duration, base);
    // The double S is never faster than the trapezoid under the same v and a.
    EXPECT_GE(base, core::min_time_trapezoid(L, 1.0, 2.0)->duration - 1e-12);
  }
}

}  // namespace
}  // namespace geotraj::test

namespace geotraj::test {
namespace {

// A grid profile as a timing optimiser makes it: b = s_dot^2 linear on each of N intervals
// uniform in s, here a trapezoid of 1 m/s and 2 m/s^2 over 1 m.
struct GridProfile {
  std::vector<double> dt, u;
  double length = 1.0;
};
GridProfile trapezoid_grid(std::size_t N) {
  GridProfile g;
  const double L = g.length, v = 1.0, a = 2.0, ds = L / static_cast<double>(N);
  auto b = [&](double s) { return std::min({2 * a * s, v * v, 2 * a * (L - s)}); };
  for (std::size_t i = 0; i < N; ++i) {
    const double s0 = ds * static_cast<double>(i), b0 = b(s0), b1 = b(s0 + ds);
    g.u.push_back((b1 - b0) / (2 * ds));
    g.dt.push_back(2 * ds / (std::sqrt(b0) + std::sqrt(b1)));
  }
  return g;
}

TEST(ContinuousAccelerationProfile, StartsAndEndsAtRestWithZeroAccelerationAfterTheLength) {
  for (const std::size_t N : {2u, 7u, 100u, 1000u}) {
    const GridProfile g = trapezoid_grid(N);
    auto p = core::continuous_acceleration_profile(g.dt, g.u, g.length);
    ASSERT_TRUE(p) << p.error().front().description;
    double T = 0.0;
    for (double d : g.dt) T += d;
    EXPECT_NEAR(p->duration, T + g.dt.front() / 4 + g.dt.back() / 4, 1e-12) << "the rests' ramps add their time";
    EXPECT_EQ(p->pieces.front().a0, 0.0);
    // The end of the last piece, integrated (not evaluate's exact end): at rest, no
    // acceleration, at L.
    const core::ProfilePiece& last = p->pieces.back();
    const double h = p->duration - last.t0;
    EXPECT_NEAR(last.a0 + last.j * h, 0.0, 1e-9);
    EXPECT_NEAR(last.v0 + h * (last.a0 + h * last.j / 2), 0.0, 1e-9);
    EXPECT_NEAR(last.s0 + h * (last.v0 + h * (last.a0 / 2 + h * last.j / 6)), g.length, 1e-9);
    const Walk w = walk(*p, /*continuous_a=*/true);
    // The ramps keep the speed at every grid point; between them and in the scaling the
    // speed and acceleration move by a small amount only.
    EXPECT_LE(w.v_max, 1.0 + 1.0 / static_cast<double>(N * N)) << N;
    EXPECT_LE(w.a_max, 2.0 * (1.0 + 1.0 / static_cast<double>(N * N))) << N;
    EXPECT_GT(w.j_max, 0.0);
    EXPECT_TRUE(std::isfinite(w.j_max));
  }
}

TEST(ContinuousAccelerationProfile, TheJerkIsTheStepOverItsWindow) {
  // Inside, the jerk is (u_i - u_{i-1}) / min(dt_{i-1}, dt_i) at a step and 0 elsewhere; at the
  // start u_0 / (dt_0 / 2).
  const GridProfile g = trapezoid_grid(400);
  auto p = core::continuous_acceleration_profile(g.dt, g.u, g.length);
  ASSERT_TRUE(p);
  double model_peak = std::abs(g.u[0]) / (g.dt[0] / 2);
  for (std::size_t i = 1; i < g.dt.size(); ++i)
    model_peak = std::max(model_peak, std::abs(g.u[i] - g.u[i - 1]) / std::min(g.dt[i - 1], g.dt[i]));
  EXPECT_NEAR(core::peak_jerk(*p), model_peak, 1e-3 * model_peak);  // the final scaling
  EXPECT_NEAR(p->pieces.front().j, g.u[0] / (g.dt[0] / 2), 1e-3 * std::abs(p->pieces.front().j));
  EXPECT_EQ(core::evaluate(*p, 0.0).a, 0.0);
}

TEST(ContinuousAccelerationProfile, BadGridsAreRefused) {
  EXPECT_FALSE(core::continuous_acceleration_profile({1.0}, {0.0}, 1.0));
  EXPECT_FALSE(core::continuous_acceleration_profile({1.0, 0.0}, {1.0, -1.0}, 1.0));
  EXPECT_FALSE(core::continuous_acceleration_profile({1.0, 1.0}, {1.0}, 1.0));
  EXPECT_FALSE(core::continuous_acceleration_profile({1.0, 1.0}, {1.0, std::nan("")}, 1.0));
  EXPECT_FALSE(core::continuous_acceleration_profile({1.0, 1.0}, {1.0, -1.0}, 0.0));
  const auto e = core::continuous_acceleration_profile({1.0, 1.0}, {1.0, -1.0}, -1.0);
  ASSERT_FALSE(e);
  EXPECT_EQ(e.error().front().field, "motion");
}

}  // namespace
}  // namespace geotraj::test
