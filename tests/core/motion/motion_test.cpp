// Motion along a path (thesis 6.3.2, 7.2.9): MotionSpec validation, portions between rests,
// the sample grid, samples on the path, exact arc length (kArcLength), the thesis's
// velocity-error measure (Tables 7.21 and 7.22), Cartesian limits of minimum-time plans,
// velocity and acceleration against central differences, no allocation per sample, and
// regression shapes (collinear frames, closed path, U-turn cusp, mid-path stop).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "core/geometry/arc_length.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "test_support.hpp"
#include "thesis_paths.hpp"

namespace geotraj::test {
namespace {

using core::MotionSample;
using core::MotionSpec;
using core::TimeParameterization;

core::Path demo(char which, core::BlendMethod blend = core::BlendMethod::kPolynomial) {
  auto path = core::build_path(geotraj::testing::thesis_demo_path(which, blend));
  EXPECT_TRUE(path.has_value());
  return *path;
}

std::vector<MotionSample> run(const core::Path& path, const core::MotionPlan& plan) {
  std::vector<MotionSample> out;
  out.reserve(plan.sample_count);
  core::MotionSampler sampler(path, plan);
  MotionSample s;
  while (sampler.next(s)) out.push_back(s);
  return out;
}

core::MotionPlan plan_or_die(const core::Path& path, const MotionSpec& spec) {
  auto plan = core::plan_motion(path, spec);
  if (!plan) {
    for (const auto& v : plan.error()) ADD_FAILURE() << v.field << ": " << v.description;
    std::abort();
  }
  return *plan;
}

MotionSpec timed(double duration, TimeParameterization tp = TimeParameterization::kArcLength) {
  MotionSpec spec;
  spec.duration_s = duration;
  spec.time_parameterization = tp;
  return spec;
}

// ---------------------------------------------------------------------------------------
// Validation

TEST(MotionSpec, DefaultsWithADurationAreValid) { EXPECT_TRUE(core::validate_motion(timed(10)).empty()); }

TEST(MotionSpec, BadValuesNameTheField) {
  struct Case {
    const char* field;
    void (*bad)(MotionSpec&);
  };
  const Case cases[] = {
      {"motion.durationS", [](MotionSpec& s) { s.duration_s = -1; }},
      {"motion.durationS", [](MotionSpec& s) { s.duration_s = NAN; }},
      {"motion.rampFraction", [](MotionSpec& s) { s.ramp_fraction = 0; }},
      {"motion.rampFraction", [](MotionSpec& s) { s.ramp_fraction = 0.7; }},
      {"motion.rampFraction", [](MotionSpec& s) { s.ramp_fraction = NAN; }},
      {"motion.cycleRateHz", [](MotionSpec& s) { s.cycle_rate_hz = 0; }},
      {"motion.cycleRateHz", [](MotionSpec& s) { s.cycle_rate_hz = NAN; }},
      {"motion.cycleRateHz", [](MotionSpec& s) { s.cycle_rate_hz = INFINITY; }},
      {"motion.speedScale", [](MotionSpec& s) { s.speed_scale = 0; }},
      {"motion.speedScale", [](MotionSpec& s) { s.speed_scale = 1.5; }},
      {"motion.accelerationScale", [](MotionSpec& s) { s.acceleration_scale = 0; }},
      {"motion.accelerationScale", [](MotionSpec& s) { s.acceleration_scale = NAN; }},
      {"motion.accelerationScale", [](MotionSpec& s) { s.acceleration_scale = 1.5; }},
      {"motion.maxSpeed", [](MotionSpec& s) { s.max_speed = -1; }},
      {"motion.maxAcceleration", [](MotionSpec& s) { s.max_acceleration = NAN; }},
      {"motion.maxJerk", [](MotionSpec& s) { s.max_jerk = 0; }},
  };
  const auto path = demo('A');
  for (const auto& c : cases) {
    MotionSpec spec = timed(10);
    c.bad(spec);
    const auto v = core::validate_motion(spec);
    EXPECT_TRUE(names(v, c.field)) << c.field;
    const auto plan = core::plan_motion(path, spec);
    ASSERT_FALSE(plan.has_value()) << c.field;
    EXPECT_TRUE(names(plan.error(), c.field)) << c.field;
  }
}

TEST(MotionSpec, DurationZeroNeedsLimits) {
  MotionSpec spec;  // duration 0, no limits
  EXPECT_TRUE(names(core::validate_motion(spec), "motion.durationS"));
  spec.max_speed = 1;
  EXPECT_TRUE(names(core::validate_motion(spec), "motion.durationS"));
  spec.max_acceleration = 1;
  EXPECT_TRUE(core::validate_motion(spec).empty());
  spec.profile = core::ProfileShape::kSCurve;
  EXPECT_TRUE(names(core::validate_motion(spec), "motion.maxJerk"));
  spec.max_jerk = 10;
  EXPECT_TRUE(core::validate_motion(spec).empty());
}

// ---------------------------------------------------------------------------------------
// Portions and the sample grid

// Regression (hostile input): a move time of 1e-300 s made the peak speed inf, which the
// service would have streamed. It is refused, naming the field.
TEST(MotionPlan, MoveTimeTooShortToRepresentIsRefused) {
  const auto path = demo('A');
  const auto plan = core::plan_motion(path, timed(1e-300));
  ASSERT_FALSE(plan);
  ASSERT_EQ(plan.error().size(), 1u);
  EXPECT_EQ(plan.error()[0].field, "motion.durationS");
  EXPECT_NE(plan.error()[0].description.find("too short"), std::string::npos) << plan.error()[0].description;
}

TEST(MotionPlan, ThesisDemoRestsAtTheCusp) {
  const auto path = demo('A');
  const auto plan = plan_or_die(path, timed(10));
  ASSERT_EQ(plan.portions.size(), 2u);  // frame 3 (index 2) is a cusp
  EXPECT_EQ(plan.portions[0].u_start, 0.0);
  EXPECT_EQ(plan.portions[0].u_end, 2.0);
  EXPECT_EQ(plan.portions[1].u_start, 2.0);
  EXPECT_EQ(plan.portions[1].u_end, 3.0);
  EXPECT_DOUBLE_EQ(plan.portions[0].length, path.cumulative_lengths[2]);
  EXPECT_DOUBLE_EQ(plan.duration_s, 10.0);
  EXPECT_NEAR(plan.portions[1].t_end(), 10.0, 1e-12);
  // Equal peak speed: T_i proportional to L_i.
  const double v = path.length() / (10.0 * (1 - 0.15));
  EXPECT_NEAR(core::peak_speed(plan.portions[0].profile), v, 1e-12);
  EXPECT_NEAR(core::peak_speed(plan.portions[1].profile), v, 1e-12);
  EXPECT_NEAR(plan.peak_speed, v, 1e-12);
  EXPECT_EQ(plan.sample_count, 1001u);
}

TEST(MotionPlan, SampleCountAndEndTimeExact) {
  const auto path = demo('B');
  struct Case {
    double duration, rate, scale;
    std::size_t count;
  };
  const Case cases[] = {{10, 100, 1, 1001}, {10.005, 100, 1, 1002}, {0.3, 10, 1, 4}, {1.0 / 3, 3, 1, 2},
                        {7, 1000, 0.5, 14001}, {10, 30, 1, 301}};
  for (const auto& c : cases) {
    SCOPED_TRACE(::testing::Message() << c.duration << " s at " << c.rate << " Hz, scale " << c.scale);
    MotionSpec spec = timed(c.duration);
    spec.cycle_rate_hz = c.rate;
    spec.speed_scale = c.scale;
    const auto plan = plan_or_die(path, spec);
    EXPECT_EQ(plan.duration_s, c.duration / c.scale);
    EXPECT_EQ(plan.sample_count, c.count);
    const auto samples = run(path, plan);
    ASSERT_EQ(samples.size(), c.count);
    EXPECT_EQ(samples.front().t, 0.0);
    EXPECT_EQ(samples.back().t, plan.duration_s);
    for (std::size_t k = 0; k + 1 < samples.size(); ++k) EXPECT_EQ(samples[k].t, k / c.rate);
    EXPECT_EQ(samples.back().u, path.u_max());
    EXPECT_EQ(samples.back().speed, 0.0);
  }
}

// ---------------------------------------------------------------------------------------
// Samples: on the path, at the profile's arc length, zero speed at rests

void expect_on_path_and_at_profile_s(const core::Path& path, const core::MotionPlan& plan, double tol_s) {
  const auto samples = run(path, plan);
  ASSERT_EQ(samples.size(), plan.sample_count);
  double worst = 0.0;
  for (const auto& smp : samples) {
    const auto jet = core::evaluate(path, smp.u, 0);
    EXPECT_LT((jet[0] - smp.p_W).norm(), 1e-12) << "t = " << smp.t;
    const auto& por = plan.portions[smp.portion];
    const double s_profile = por.s_start + core::evaluate(por.profile, smp.t - por.t_start).s;
    const double s_true = core::arc_length_at(path, smp.u);
    worst = std::max(worst, std::abs(s_true - s_profile));
    EXPECT_NEAR(smp.s, s_true, tol_s) << "t = " << smp.t;
  }
  EXPECT_LE(worst, tol_s);
  std::printf("  worst |s(u) - s_profile(t)| = %.3g m over %zu samples\n", worst, samples.size());
}

TEST(MotionSampler, ArcLengthSamplesLandOnTheProfileTo1e9m) {
  for (char which : {'A', 'B', 'C'})
    for (double duration : {5.0, 10.0, 15.0}) {
      SCOPED_TRACE(::testing::Message() << "path " << which << ", " << duration << " s");
      const auto path = demo(which);
      expect_on_path_and_at_profile_s(path, plan_or_die(path, timed(duration)), 1e-9);
    }
}

TEST(MotionSampler, ArcLengthOnTrapezoidBlendAndSCurveAt1kHz) {
  const auto path = demo('C', core::BlendMethod::kTrapezoidal);
  MotionSpec spec = timed(4);
  spec.profile = core::ProfileShape::kSCurve;
  spec.cycle_rate_hz = 1000;
  expect_on_path_and_at_profile_s(path, plan_or_die(path, spec), 1e-9);
}

TEST(MotionSampler, SpeedIsZeroAtRests) {
  const auto path = demo('C');
  for (auto tp : {TimeParameterization::kArcLength, TimeParameterization::kSmooth,
                  TimeParameterization::kTaylorFirstOrder, TimeParameterization::kTaylorSecondOrder}) {
    MotionSpec spec = timed(10, tp);
    spec.cycle_rate_hz = 50;  // the cusp portion starts on the grid? not necessarily: check both
    const auto plan = plan_or_die(path, spec);
    const auto samples = run(path, plan);
    EXPECT_EQ(samples.front().speed, 0.0);
    EXPECT_EQ(samples.back().speed, 0.0);
    EXPECT_EQ(samples.front().u, 0.0);
    EXPECT_EQ(samples.back().u, 3.0);
    // Around the cusp at u = 2: the speed falls to 0 (the profile's v at the sample's time).
    const double t_cusp = plan.portions[1].t_start;
    for (const auto& smp : samples) {
      if (std::abs(smp.t - t_cusp) < 1e-12) {
        EXPECT_EQ(smp.u, 2.0);
        EXPECT_EQ(smp.speed, 0.0);
      }
      // Continuity: |v| <= a_peak |t - t_cusp| on either side.
      EXPECT_LE(smp.speed, plan.peak_acceleration * std::abs(smp.t - t_cusp) * (1 + 1e-9) + 1e-12) << "t = " << smp.t;
    }
  }
}

// ---------------------------------------------------------------------------------------
// The thesis's measure: speed = distance between consecutive samples / period (7.2.9),
// against the profile's mean speed over the period.

struct SpeedError {
  double peak = 0.0;        // largest measured speed [m/s]
  double max_error = 0.0;   // largest |measured - profile mean| [m/s]
  double arc_error = 0.0;   // the same with the true arc length between the samples [m/s]
  double unexplained = 0.0; // chord error beyond the chord's deficit on the arc [m/s]
  double percent() const { return 100.0 * max_error / peak; }
};

double curvature(const core::Path& path, double u) {
  return core::local_geometry(core::evaluate(path, u), 0.0).kappa;
}

SpeedError measure(const core::Path& path, const core::MotionPlan& plan) {
  const auto samples = run(path, plan);
  SpeedError e;
  const auto s_at = [&](double t) {
    std::size_t i = 0;  // the portion containing t (the later one at a boundary)
    while (i + 1 < plan.portions.size() && t >= plan.portions[i + 1].t_start) ++i;
    const auto& por = plan.portions[i];
    return por.s_start + core::evaluate(por.profile, t - por.t_start).s;
  };
  for (std::size_t k = 0; k + 1 < samples.size(); ++k) {
    const auto &a = samples[k], &b = samples[k + 1];
    // Across the cusp the distance is not the arc length travelled; skip that period.
    if (b.portion != a.portion) continue;
    const double dt = b.t - a.t;
    const double measured = (b.p_W - a.p_W).norm() / dt;
    const double ds = s_at(b.t) - s_at(a.t);
    const double desired = ds / dt;
    e.peak = std::max(e.peak, measured);
    e.max_error = std::max(e.max_error, std::abs(measured - desired));
    const double arc = (core::arc_length_at(path, b.u) - core::arc_length_at(path, a.u)) / dt;
    e.arc_error = std::max(e.arc_error, std::abs(arc - desired));
    // A chord spanning an arc ds with curvature <= kappa is at least 2/kappa sin(kappa ds/2).
    const double kappa =
        1.05 * std::max({curvature(path, a.u), curvature(path, b.u), curvature(path, 0.5 * (a.u + b.u))});
    const double deficit = kappa > 0 ? (ds - 2 / kappa * std::sin(kappa * ds / 2)) / dt : 0.0;
    e.unexplained = std::max(e.unexplained, std::abs(measured - desired) - deficit);
  }
  return e;
}

// The thesis measures the speed as chord / period (7.2.9). A chord is shorter than its arc
// by about ds^3 kappa^2 / 24: at 100 Hz on these paths (kappa up to ~70 1/m where the
// speed is high) that alone is several 0.01 % of the peak speed, so the assertions are on
// (1) the speed measured along the arc, within 0.01 % of the peak, and (2) the chord
// measure beyond the chord's geometric deficit, within 0.01 % of the peak. The thesis's
// figures are printed beside ours, not asserted (its blends differ: see the peak speeds).
TEST(MotionSampler, ThesisTables7_21And7_22VelocityError) {
  struct Row {
    char path;
    double duration;
    double thesis_peak, thesis_error, thesis_percent;
  };
  const Row rows[] = {{'A', 10, 0.1855, 0.0007, 0.3929}, {'B', 10, 0.1899, 0.0015, 0.8135},
                      {'C', 10, 0.1918, 0.0026, 1.3387}, {'C', 5, 0.4658, 0.0197, 4.2384},
                      {'C', 15, 0.1208, 0.0008, 0.6355}};
  std::printf("\n  Velocity tracking at 100 Hz, trapezoid rampFraction 0.15 (thesis Tables 7.21, 7.22)\n"
              "  speed = chord / period as the thesis measures it, against the profile's mean speed\n");
  std::printf("  %-4s %5s | %-23s | %-23s | %-23s | %s\n", "path", "T [s]", "thesis: peak  err  %",
              "TAYLOR_2ND: peak err %", "ARC_LENGTH: peak err %", "ARC_LENGTH along the arc: err %");
  for (const auto& r : rows) {
    const auto path = demo(r.path);
    const auto taylor = measure(path, plan_or_die(path, timed(r.duration, TimeParameterization::kTaylorSecondOrder)));
    const auto exact = measure(path, plan_or_die(path, timed(r.duration, TimeParameterization::kArcLength)));
    std::printf("  %-4c %5.0f | %.4f %.4f %7.4f | %.4f %.4f %7.4f | %.4f %.5f %7.4f | %.1e %.1e\n", r.path,
                r.duration, r.thesis_peak, r.thesis_error, r.thesis_percent, taylor.peak, taylor.max_error,
                taylor.percent(), exact.peak, exact.max_error, exact.percent(), exact.arc_error,
                100 * exact.arc_error / exact.peak);
    EXPECT_LT(exact.arc_error, 1e-4 * exact.peak) << r.path << " " << r.duration;
    EXPECT_LT(exact.unexplained, 1e-4 * exact.peak) << r.path << " " << r.duration;
    EXPECT_LT(exact.max_error, taylor.max_error);
  }
}

// ---------------------------------------------------------------------------------------
// Minimum time under Cartesian limits (duration 0): speed, tangential and centripetal
// acceleration, checked on the sampled values.

TEST(MotionSampler, MinimumTimeRespectsCartesianLimits) {
  for (auto shape : {core::ProfileShape::kTrapezoidal, core::ProfileShape::kSCurve})
    for (char which : {'A', 'C'})
      for (double a_max : {0.5, 5.0}) {
        SCOPED_TRACE(::testing::Message() << "path " << which << " a_max " << a_max << " shape "
                                          << static_cast<int>(shape));
        const auto path = demo(which);
        MotionSpec spec;
        spec.profile = shape;
        spec.max_speed = 0.5;
        spec.max_acceleration = a_max;
        spec.max_jerk = 20;
        spec.cycle_rate_hz = 500;
        const auto plan = plan_or_die(path, spec);
        EXPECT_GT(plan.duration_s, 0.0);
        const auto samples = run(path, plan);
        double worst_v = 0, worst_at = 0, worst_an = 0;
        for (const auto& smp : samples) {
          worst_v = std::max(worst_v, smp.speed);
          const auto g = core::local_geometry(core::evaluate(path, smp.u), 0.0);
          if (smp.speed > 0) {
            worst_at = std::max(worst_at, std::abs(smp.a_W.dot(smp.v_W) / smp.speed));
            worst_an = std::max(worst_an, g.kappa * smp.speed * smp.speed);
            // The normal part of the acceleration is kappa v^2 (2.31).
            const Eigen::Vector3d a_n = smp.a_W - smp.a_W.dot(g.T) * g.T;
            EXPECT_NEAR(a_n.norm(), g.kappa * smp.speed * smp.speed, 1e-6 * (1 + a_max));
          }
        }
        EXPECT_LE(worst_v, 0.5 * (1 + 1e-9));
        EXPECT_LE(worst_at, a_max * (1 + 1e-9));
        EXPECT_LE(worst_an, a_max * (1 + 1e-6));
        // Tight: the trapezoid reaches a_max, the double S j_max; a portion that cruises
        // does so at v_lim = min(maxSpeed, sqrt(a_max / kappa_max)).
        for (const auto& por : plan.portions) {
          const double v_lim = std::min(0.5, std::sqrt(a_max / por.kappa_max));
          const double vp = core::peak_speed(por.profile);
          EXPECT_LE(vp, v_lim * (1 + 1e-12));
          if (shape == core::ProfileShape::kTrapezoidal) {
            EXPECT_NEAR(core::peak_acceleration(por.profile), a_max, 1e-9 * a_max);
          } else {
            EXPECT_NEAR(core::peak_jerk(por.profile), 20.0, 1e-9);
          }
          const bool cruises = std::any_of(por.profile.pieces.begin(), por.profile.pieces.end(),
                                           [](const auto& q) { return q.a0 == 0.0 && q.j == 0.0; });
          if (cruises) { EXPECT_NEAR(vp, v_lim, 1e-12); }
          std::printf("  path %c a_max %.1f shape %d: kappa_max %.2f 1/m, v_lim %.4f, peak v %.4f m/s%s\n", which,
                      a_max, static_cast<int>(shape), por.kappa_max, v_lim, vp, cruises ? " (cruise)" : "");
        }
        EXPECT_GT(worst_v, 0.0);
      }
}

TEST(MotionSampler, SpeedScaleSlowsTheSameMotion) {
  const auto path = demo('B');
  MotionSpec spec;
  spec.max_speed = 0.4;
  spec.max_acceleration = 2;
  const auto fast = plan_or_die(path, spec);
  spec.speed_scale = 0.5;
  const auto slow = plan_or_die(path, spec);
  EXPECT_NEAR(slow.duration_s, 2 * fast.duration_s, 1e-12 * fast.duration_s);
  EXPECT_NEAR(slow.peak_speed, 0.5 * fast.peak_speed, 1e-12);
  EXPECT_NEAR(slow.peak_acceleration, 0.25 * fast.peak_acceleration, 1e-12);
}

// ---------------------------------------------------------------------------------------
// Velocity and acceleration against central differences of the positions.
// S-curve at 1 kHz (continuous acceleration): step h = 1 ms. The central difference errs by
// h^2/6 |d3p/dt3| for the velocity, and |d3p/dt3| ~ v^3 kappa^2 reaches 0.2^3 230^2 ~ 420
// m/s^3 on path C (kappa up to 230 1/m): 7e-5 m/s. Tolerances: 1e-4 m/s (5e-4 of the peak
// speed) and 5e-3 m/s^2 (h^2/12 |d4p/dt4| plus h |jerk jump| at the S-curve's phase changes).
TEST(MotionSampler, VelocityAndAccelerationMatchCentralDifferences) {
  for (auto tp : {TimeParameterization::kArcLength, TimeParameterization::kSmooth}) {
    const auto path = demo('C');
    MotionSpec spec = timed(10, tp);
    spec.profile = core::ProfileShape::kSCurve;
    spec.cycle_rate_hz = 1000;
    const auto plan = plan_or_die(path, spec);
    const auto smp = run(path, plan);
    const double h = 1e-3;
    double worst_v = 0, worst_a = 0;
    for (std::size_t k = 1; k + 2 < smp.size(); ++k) {
      if (smp[k - 1].portion != smp[k + 1].portion) continue;  // a rest between: one-sided
      const Eigen::Vector3d v_fd = (smp[k + 1].p_W - smp[k - 1].p_W) / (2 * h);
      const Eigen::Vector3d a_fd = (smp[k + 1].p_W - 2 * smp[k].p_W + smp[k - 1].p_W) / (h * h);
      worst_v = std::max(worst_v, (v_fd - smp[k].v_W).norm());
      worst_a = std::max(worst_a, (a_fd - smp[k].a_W).norm());
    }
    std::printf("  time parameterization %d: worst |v - FD| = %.3g m/s, |a - FD| = %.3g m/s^2\n",
                static_cast<int>(tp), worst_v, worst_a);
    EXPECT_LT(worst_v, 1e-4);
    EXPECT_LT(worst_a, 5e-3);
  }
}

TEST(MotionSampler, NoHeapAllocationPerSample) {
  const auto path = demo('C');
  for (auto tp : {TimeParameterization::kArcLength, TimeParameterization::kTaylorSecondOrder}) {
    const auto plan = plan_or_die(path, timed(10, tp));
    core::MotionSampler sampler(path, plan);
    MotionSample s;
    const long before = geotraj::testing::allocation_count();
    std::size_t n = 0;
    while (sampler.next(s)) ++n;
    EXPECT_EQ(geotraj::testing::allocation_count() - before, 0);
    EXPECT_EQ(n, plan.sample_count);
  }
}

TEST(MotionSampler, ResetReplaysTheSameSamples) {
  const auto path = demo('A');
  const auto plan = plan_or_die(path, timed(3));
  core::MotionSampler sampler(path, plan);
  MotionSample a, b;
  std::vector<MotionSample> first;
  while (sampler.next(a)) first.push_back(a);
  sampler.reset();
  for (const auto& f : first) {
    ASSERT_TRUE(sampler.next(b));
    EXPECT_EQ(b.u, f.u);
  }
  EXPECT_FALSE(sampler.next(b));
}

// ---------------------------------------------------------------------------------------
// Regressions: shapes that stress the portion logic.

TEST(MotionRegression, ThreeCollinearKeyFrames) {
  core::PathSpec spec;
  spec.frames = {Frame({0, 0, 0}, {1, 0, 0}), Frame({0.5, 0, 0}, {1, 0, 0}),
                 Frame({1, 0, 0}, {1, 0, 0})};
  const auto path = *core::build_path(spec);
  EXPECT_NEAR(path.length(), 1.0, 1e-12);
  MotionSpec m;
  m.max_speed = 0.25;
  m.max_acceleration = 1;
  const auto plan = plan_or_die(path, m);
  ASSERT_EQ(plan.portions.size(), 1u);
  EXPECT_EQ(plan.portions[0].kappa_max, 0.0);  // straight: no centripetal cap
  EXPECT_NEAR(plan.duration_s, 1.0 / 0.25 + 0.25 / 1.0, 1e-12);
  expect_on_path_and_at_profile_s(path, plan, 1e-9);
  for (const auto& s : run(path, plan)) {
    EXPECT_NEAR(s.p_W.y(), 0.0, 1e-15);
    EXPECT_NEAR(s.p_W.x(), s.s, 1e-9);
  }
}

TEST(MotionRegression, ClosedPathReturnsToItsStart) {
  core::PathSpec spec;
  spec.closed = true;
  spec.frames = {Frame({0, 0, 0}, {1, 0, 0}).scale(0.3), Frame({0.3, 0.3, 0}, {0, 1, 0}).scale(0.3),
                 Frame({0, 0.6, 0}, {-1, 0, 0}).scale(0.3)};
  const auto path = *core::build_path(spec);
  const auto plan = plan_or_die(path, timed(6));
  ASSERT_EQ(plan.portions.size(), 1u);
  EXPECT_EQ(plan.portions[0].u_end, 3.0);
  EXPECT_DOUBLE_EQ(plan.portions[0].length, path.length());
  const auto samples = run(path, plan);
  EXPECT_LT((samples.back().p_W - samples.front().p_W).norm(), 1e-12);
  EXPECT_EQ(samples.back().s, path.length());
  expect_on_path_and_at_profile_s(path, plan, 1e-9);
}

TEST(MotionRegression, UTurnThroughACusp) {
  core::PathSpec spec;
  spec.frames = {Frame({0, 0, 0}, {1, 0, 0}).scale(0.2),
                 Frame({0.4, 0.1, 0}, {1, 0, 0}).scale(0.2).cusp(),
                 Frame({0, 0.2, 0}, {-1, 0, 0}).scale(0.2)};
  const auto path = *core::build_path(spec);
  for (auto tp : {TimeParameterization::kArcLength, TimeParameterization::kTaylorSecondOrder}) {
    const auto plan = plan_or_die(path, timed(4, tp));
    ASSERT_EQ(plan.portions.size(), 2u);
    const auto samples = run(path, plan);
    // The motion reverses at the cusp: before it, v along +x; after it, along -x.
    const double t_cusp = plan.portions[1].t_start;
    for (const auto& s : samples) {
      if (s.t > t_cusp - 0.2 && s.t < t_cusp - 1e-9) { EXPECT_GE(s.v_W.x(), -1e-12); }
      if (s.t > t_cusp + 1e-9 && s.t < t_cusp + 0.2) { EXPECT_LE(s.v_W.x(), 1e-12); }
      EXPECT_LT((core::evaluate(path, s.u, 0)[0] - s.p_W).norm(), 1e-12);
    }
  }
  expect_on_path_and_at_profile_s(path, plan_or_die(path, timed(4)), 1e-9);
}

TEST(MotionRegression, StopInMidPath) {
  core::PathSpec spec;
  core::KeyFrame mid = Frame({0.5, 0.2, 0.1}, {1, 0, 0}).scale(0.5);
  mid.stop = true;
  spec.frames = {Frame({0, 0, 0}, {1, 0, 0}).scale(0.5), mid,
                 Frame({1, 0, 0.2}, {1, 0, 0}).scale(0.5), Frame({1.5, 0.3, 0.2}, {0, 1, 0}).scale(0.5)};
  const auto path = *core::build_path(spec);
  MotionSpec m;
  m.max_speed = 0.3;
  m.max_acceleration = 1.5;
  m.max_jerk = 10;
  m.profile = core::ProfileShape::kSCurve;
  const auto plan = plan_or_die(path, m);
  ASSERT_EQ(plan.portions.size(), 2u);
  EXPECT_EQ(plan.portions[0].u_end, 1.0);
  EXPECT_EQ(plan.portions[1].u_end, 3.0);
  const auto samples = run(path, plan);
  const double t_stop = plan.portions[1].t_start;
  for (const auto& s : samples) {
    // Speed continuous down to zero at the stop: within |t - t_stop| the speed is below
    // the jerk-limited bound j t^2 / 2.
    const double dt = std::abs(s.t - t_stop);
    if (dt < 0.05) { EXPECT_LE(s.speed, 10 * dt * dt / 2 + 1e-12) << "t = " << s.t; }
  }
  expect_on_path_and_at_profile_s(path, plan, 1e-9);
}

}  // namespace
}  // namespace geotraj::test

namespace geotraj {
namespace {

// Tables 7.21 and 7.22 reproduced: the thesis's reading (orders 1-4 at every frame, zeros
// where nothing is given, 7.2.8's kappa' = tau' = 0 at frames 2 and 3) and its ramps as a
// time (Table 6.2's RampTime: 0.75 s per ramp in each of the two portions around the cusp)
// give the printed peak speeds within 1 % at 5, 10 and 15 s.
TEST(MotionPlan, ThesisTables721And722PeakSpeeds) {
  struct Row {
    char path;
    double duration_s, thesis_peak;
  };
  const Row rows[] = {{'A', 10, 0.1855}, {'B', 10, 0.1899}, {'C', 10, 0.1918}, {'C', 5, 0.4658}, {'C', 15, 0.1208}};
  for (const Row& row : rows) {
    SCOPED_TRACE(std::string("path ") + row.path + " at " + std::to_string(row.duration_s) + " s");
    const auto path = test::build_or_fail(
        testing::thesis_demo_path(row.path, core::BlendMethod::kPolynomial, core::UnspecifiedConstraints::kThesisZeros));
    core::MotionSpec spec;
    spec.duration_s = row.duration_s;
    spec.ramp_time_s = 0.75;
    const auto plan = core::plan_motion(path, spec);
    ASSERT_TRUE(plan) << plan.error()[0].field << ": " << plan.error()[0].description;
    EXPECT_NEAR(plan->peak_speed, row.thesis_peak, 0.01 * row.thesis_peak);
    // Two portions (the cusp rests), each with two 0.75 s ramps: v (T - 1.5 s) = L.
    EXPECT_NEAR(plan->peak_speed * (row.duration_s - 1.5), path.length(), 1e-9 * path.length());
  }
}

TEST(MotionSpec, RampTimeIsCheckedAndNamed) {
  core::MotionSpec spec;
  spec.duration_s = 10;
  spec.ramp_time_s = -1;
  auto v = core::validate_motion(spec);
  ASSERT_FALSE(v.empty());
  EXPECT_EQ(v[0].field, "motion.rampTimeS");
  spec.ramp_time_s = 0.5;
  spec.ramp_fraction_given = true;
  v = core::validate_motion(spec);
  ASSERT_FALSE(v.empty());
  EXPECT_EQ(v[0].field, "motion.rampTimeS");
  // Ramps longer than the move.
  spec.ramp_fraction_given = false;
  spec.ramp_time_s = 6.0;
  const auto path = test::build_or_fail(testing::thesis_demo_path('C'));
  const auto plan = core::plan_motion(path, spec);
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error()[0].field, "motion.rampTimeS");
}

}  // namespace
}  // namespace geotraj
