// Joint paths through waypoints (joint_path.hpp): the blended polyline met where it must be
// (the ends exactly, every blended waypoint within the tolerance, at the distance the path
// reports), curvature-continuous (q_s and q_ss continuous at every junction, derivatives
// against differences), the rests (stops, reversals, tolerance 0), straight passes and
// merged duplicates; the time-optimal timing within the joint limits by differences of the
// samples at 1 and 4 kHz, no acceleration step where a blend meets a line, the two-waypoint
// case against the joint move's minimum-time trapezoid, a given duration, errors that name
// their fields, and no allocation per sample.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "test_support.hpp"
#include "core/planning/joint_path.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::test {
namespace {

using core::JointPath;
using core::JointPathPlan;
using core::JointPathPoint;
using core::JointPathSegment;
using core::JointPathSpec;
using core::JointVector;
using core::JointWaypointPass;
using core::MotionSpec;
using core::MoveSample;
using core::Violations;
using Kind = JointWaypointPass::Kind;

const core::ValidRobot& pa10() {
  static const core::ValidRobot robot = *core::ValidRobot::check(*core::find_builtin_robot("pa10"));
  return robot;
}

JointVector vec(const std::vector<double>& v) {
  JointVector q(static_cast<Eigen::Index>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) q(static_cast<Eigen::Index>(i)) = v[i];
  return q;
}

// `count` waypoints drawn within the middle 80 % of the PA-10's position limits.
JointPathSpec random_spec(std::mt19937& rng, std::size_t count, double tolerance) {
  const core::RobotModel& m = pa10();
  JointPathSpec spec;
  spec.blend_tolerance = tolerance;
  for (std::size_t i = 0; i < count; ++i) {
    core::JointWaypoint w;
    for (const auto& lim : m.limits) {
      const double mid = 0.5 * (lim.min_position + lim.max_position), half = 0.4 * (lim.max_position - lim.min_position);
      w.positions.push_back(std::uniform_real_distribution<double>(mid - half, mid + half)(rng));
    }
    spec.waypoints.push_back(std::move(w));
  }
  return spec;
}

JointPath build(const JointPathSpec& spec) {
  auto path = core::build_joint_path(pa10(), spec);
  EXPECT_TRUE(path.has_value()) << (path ? "" : listed(path.error()));
  return path ? *path : JointPath{};
}

JointPathPoint at(const JointPath& path, double sigma) {
  JointPathPoint p;
  std::size_t hint = 0;
  core::evaluate(path, sigma, p, hint);
  return p;
}

// The smallest distance from w to the path: a dense scan, then golden sections.
double distance_to(const JointPath& path, const JointVector& w) {
  constexpr int kScan = 20000;
  double best = std::numeric_limits<double>::infinity(), best_s = 0.0;
  for (int i = 0; i <= kScan; ++i) {
    const double s = path.length * i / kScan;
    if (const double d = (at(path, s).q - w).norm(); d < best) best = d, best_s = s;
  }
  double lo = std::max(0.0, best_s - path.length / kScan), hi = std::min(path.length, best_s + path.length / kScan);
  for (int i = 0; i < 100; ++i) {
    const double a = lo + (hi - lo) / 3.0, b = hi - (hi - lo) / 3.0;
    if ((at(path, a).q - w).norm() < (at(path, b).q - w).norm()) {
      hi = b;
    } else {
      lo = a;
    }
  }
  return std::min(best, (at(path, 0.5 * (lo + hi)).q - w).norm());
}

MotionSpec fastest(double rate = 1000.0) {
  MotionSpec m;
  m.duration_s = 0.0;
  m.cycle_rate_hz = rate;
  return m;
}

JointPathPlan plan(const JointPathSpec& spec, const MotionSpec& motion = fastest()) {
  auto timed = core::plan_joint_path(pa10(), build(spec), motion);
  EXPECT_TRUE(timed.has_value()) << (timed ? "" : listed(timed.error()));
  if (!timed) throw std::runtime_error("plan_joint_path failed");  // the test fails here
  return *timed;
}

std::vector<MoveSample> samples_of(const JointPathPlan& p) {
  std::vector<MoveSample> out;
  if (p.sample_count == 0) return out;
  core::JointPathSampler sampler(p);
  MoveSample s;
  while (sampler.next(s)) out.push_back(s);
  return out;
}

// ---------------------------------------------------------------------------------------
// Geometry

TEST(JointPath, MeetsTheEndsExactlyAndPassesEveryWaypointWithinTheTolerance) {
  std::mt19937 rng(7);
  for (const double tolerance : {0.01, 0.1, 0.5}) {
    const JointPathSpec spec = random_spec(rng, 9, tolerance);
    const JointPath path = build(spec);
    EXPECT_EQ(at(path, 0.0).q, vec(spec.waypoints.front().positions));
    EXPECT_EQ(path.last, vec(spec.waypoints.back().positions));
    EXPECT_LT((at(path, path.length).q - path.last).norm(), 1e-12);
    for (std::size_t i = 1; i + 1 < spec.waypoints.size(); ++i) {
      const JointWaypointPass& pass = path.waypoints[i];
      ASSERT_EQ(pass.kind, Kind::kBlend) << "waypoint " << i;
      const JointVector w = vec(spec.waypoints[i].positions);
      const double measured = distance_to(path, w);
      EXPECT_LE(measured, tolerance * (1.0 + 1e-12)) << "waypoint " << i;
      // The reported deviation is the distance, at the reported sigma.
      EXPECT_NEAR(pass.deviation, measured, 1e-9 * std::max(1.0, measured)) << "waypoint " << i;
      EXPECT_NEAR((at(path, pass.sigma).q - w).norm(), pass.deviation, 1e-12) << "waypoint " << i;
    }
    EXPECT_EQ(path.rests, (std::vector<double>{0.0, path.length}));
  }
}

TEST(JointPath, TheToleranceIsUsedWhereTheLinesAreLongEnough) {
  // A right angle of long lines: the waypoint is passed at exactly the tolerance.
  JointPathSpec spec;
  spec.blend_tolerance = 0.05;
  spec.waypoints = {{{0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}}, {{1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}},
                    {{1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0}}};
  const JointPath path = build(spec);
  ASSERT_EQ(path.waypoints[1].kind, Kind::kBlend);
  EXPECT_NEAR(path.waypoints[1].deviation, 0.05, 1e-15);
  EXPECT_NEAR(distance_to(path, vec(spec.waypoints[1].positions)), 0.05, 1e-9);
}

TEST(JointPath, IsCurvatureContinuousWhereBlendsMeetLines) {
  std::mt19937 rng(11);
  const JointPath path = build(random_spec(rng, 12, 0.2));
  std::size_t blends = 0;
  for (std::size_t k = 0; k + 1 < path.segments.size(); ++k) {
    const JointPathSegment& a = path.segments[k];
    const JointPathSegment& b = path.segments[k + 1];
    EXPECT_EQ(a.sigma1, b.sigma0);
    blends += b.kind == JointPathSegment::Kind::kBlend;
    // Both sides of the junction, each evaluated in its own segment.
    JointPathPoint left, right;
    std::size_t hl = k, hr = k + 1;
    core::evaluate(path, a.sigma1, left, hl);
    ASSERT_EQ(hl, k);
    core::evaluate(path, b.sigma0, right, hr);
    ASSERT_EQ(hr, k + 1);
    EXPECT_LT((left.q - right.q).norm(), 1e-9) << "junction " << k;
    EXPECT_LT((left.q_s - right.q_s).norm(), 1e-9) << "junction " << k;
    EXPECT_NEAR(left.q_s.norm(), 1.0, 1e-12) << "junction " << k;  // sigma is arc length on the lines
    EXPECT_LT(left.q_ss.norm(), 1e-9) << "junction " << k;            // zero curvature where they meet
    EXPECT_LT(right.q_ss.norm(), 1e-9) << "junction " << k;
  }
  EXPECT_GE(blends, 10u);
}

TEST(JointPath, DerivativesMatchDifferences) {
  std::mt19937 rng(3);
  const JointPath path = build(random_spec(rng, 6, 0.3));
  const double h = 1e-5;
  for (const auto& seg : path.segments) {
    if (seg.kind != JointPathSegment::Kind::kBlend) continue;
    for (const double f : {0.1, 0.37, 0.5, 0.81}) {
      const double s = seg.sigma0 + f * (seg.sigma1 - seg.sigma0);
      const JointPathPoint p = at(path, s), lo = at(path, s - h), hi = at(path, s + h);
      EXPECT_LT(((hi.q - lo.q) / (2 * h) - p.q_s).norm(), 1e-8 * (1.0 + p.q_s.norm()));
      EXPECT_LT(((hi.q_s - lo.q_s) / (2 * h) - p.q_ss).norm(), 1e-6 * (1.0 + p.q_ss.norm()));
      EXPECT_LT(((hi.q_ss - lo.q_ss) / (2 * h) - p.q_sss).norm(), 1e-5 * (1.0 + p.q_sss.norm()));
    }
  }
}

TEST(JointPath, StaysWithinThePositionLimits) {
  // Waypoints at the limits' corners: the blends lie in the convex hull of their lines.
  const core::RobotModel& m = pa10();
  JointPathSpec spec;
  spec.blend_tolerance = 1.0;
  for (int i = 0; i < 6; ++i) {
    core::JointWaypoint w;
    for (std::size_t j = 0; j < m.dof(); ++j)
      w.positions.push_back((i + static_cast<int>(j)) % 2 == 0 ? m.limits[j].min_position : m.limits[j].max_position);
    spec.waypoints.push_back(std::move(w));
  }
  const JointPath path = build(spec);
  for (int i = 0; i <= 5000; ++i) {
    const JointVector q = at(path, path.length * i / 5000).q;
    for (std::size_t j = 0; j < m.dof(); ++j) {
      EXPECT_GE(q(static_cast<Eigen::Index>(j)), m.limits[j].min_position - 1e-12);
      EXPECT_LE(q(static_cast<Eigen::Index>(j)), m.limits[j].max_position + 1e-12);
    }
  }
}

TEST(JointPath, RestsAtStopsReversalsAndEveryWaypointWithoutATolerance) {
  const std::vector<double> a{0, 0, 0, 0, 0, 0, 0}, b{0.5, 0, 0, 0, 0, 0, 0}, c{0.5, 0.5, 0, 0, 0, 0, 0},
      d{0, 0.5, 0, 0, 0, 0, 0};
  JointPathSpec spec;
  spec.blend_tolerance = 0.1;
  spec.waypoints = {{a}, {b}, {c, true}, {d}, {c}, {b}};  // a stop at c, a reversal at d
  const JointPath path = build(spec);
  EXPECT_EQ(path.waypoints[1].kind, Kind::kBlend);
  EXPECT_EQ(path.waypoints[2].kind, Kind::kRest);
  EXPECT_EQ(path.waypoints[3].kind, Kind::kRest);
  EXPECT_EQ(path.waypoints[4].kind, Kind::kBlend);
  ASSERT_EQ(path.rests.size(), 4u);
  EXPECT_EQ(at(path, path.rests[1]).q, vec(c));
  EXPECT_LT((at(path, path.rests[2]).q - vec(d)).norm(), 1e-15);

  spec.blend_tolerance = 0.0;
  const JointPath sharp = build(spec);
  EXPECT_EQ(sharp.rests.size(), spec.waypoints.size());
  for (const auto& seg : sharp.segments) EXPECT_EQ(seg.kind, JointPathSegment::Kind::kLine);
}

TEST(JointPath, PassesCollinearWaypointsOnTheLineAndMergesDuplicates) {
  JointPathSpec spec;
  spec.blend_tolerance = 0.1;
  spec.waypoints = {{{0, 0, 0, 0, 0, 0, 0}},
                    {{0.2, 0.1, 0, 0, 0, 0, 0}},
                    {{0.2, 0.1, 0, 0, 0, 0, 5e-10}},  // a duplicate
                    {{0.4, 0.2, 0, 0, 0, 0, 0}},      // collinear
                    {{0.4, 0.6, 0, 0, 0, 0, 0}}};
  const JointPath path = build(spec);
  EXPECT_EQ(path.waypoints[1].kind, Kind::kThrough);
  EXPECT_EQ(path.waypoints[2].kind, Kind::kMerged);
  EXPECT_EQ(path.waypoints[3].kind, Kind::kBlend);
  EXPECT_EQ(path.rests.size(), 2u);
  // The only blend may take the whole line before it (it ends at a straight pass)...
  EXPECT_LE(path.waypoints[3].blend_length, std::hypot(0.2, 0.1) + 1e-12);
  // ...and never more than the line after it (it ends at the path's end).
  EXPECT_LE(path.waypoints[3].blend_length, 0.4 + 1e-12);
  // Two waypoints at one place: a path of no length.
  JointPathSpec still;
  still.waypoints = {{{0.1, 0, 0, 0, 0, 0, 0}}, {{0.1, 0, 0, 0, 0, 0, 0}}};
  const JointPath point = build(still);
  EXPECT_EQ(point.length, 0.0);
  EXPECT_EQ(at(point, 0.0).q, vec(still.waypoints[0].positions));
}

TEST(JointPath, ShortStepsShareTheirLinesBetweenBlendsWithoutOverlap) {
  // Dozens of small steps on a circle in two joints: each blend takes at most half a step.
  JointPathSpec spec;
  spec.blend_tolerance = 0.05;
  for (int i = 0; i <= 40; ++i) {
    const double a = 2.0 * std::numbers::pi * i / 40.0;
    spec.waypoints.push_back({{0.3 * std::cos(a), 0.3 * std::sin(a), 0, 0, 0, 0, 0}});
  }
  const JointPath path = build(spec);
  const double step = 2.0 * 0.3 * std::sin(std::numbers::pi / 40.0);
  for (std::size_t i = 1; i + 1 < spec.waypoints.size(); ++i) {
    ASSERT_EQ(path.waypoints[i].kind, Kind::kBlend);
    EXPECT_LE(path.waypoints[i].blend_length, step / 2.0 + 1e-15);
    EXPECT_LE(path.waypoints[i].deviation, 0.05);
  }
  for (std::size_t k = 0; k < path.segments.size(); ++k) EXPECT_LT(path.segments[k].sigma0, path.segments[k].sigma1);
}

TEST(JointPath, TheBlendsShapeIsNearTheCircularArcsCurvature) {
  // At one deviation, a circular arc has the smallest largest curvature (1 / r with
  // deviation r (1 / cos(theta / 2) - 1)); the G2 quintic stays within 12 % of it.
  for (const double degrees : {10.0, 45.0, 90.0, 135.0, 170.0}) {
    const double theta = degrees * std::numbers::pi / 180.0;
    JointPathSpec spec;
    spec.blend_tolerance = 0.01;
    spec.waypoints = {{{0, 0, 0, 0, 0, 0, 0}},
                      {{1.0, 0, 0, 0, 0, 0, 0}},
                      {{1.0 + std::cos(theta), std::sin(theta), 0, 0, 0, 0, 0}}};
    const JointPath path = build(spec);
    const auto& pass = path.waypoints[1];
    ASSERT_EQ(pass.kind, Kind::kBlend);
    const double kappa = core::blend_peak_curvature(pass.blend_shape, theta) / pass.blend_length;
    const double circle = (1.0 / std::cos(theta / 2.0) - 1.0) / pass.deviation;
    EXPECT_GE(kappa, circle * 0.999) << degrees << " degrees";
    EXPECT_LE(kappa, circle * 1.12) << degrees << " degrees";
  }
}

TEST(JointPath, RefusesBadInputNamingTheField) {
  JointPathSpec spec;
  spec.blend_tolerance = -1.0;
  spec.waypoints = {{{0, 0, 0, 0, 0, 0}}};
  auto path = core::build_joint_path(pa10(), spec);
  ASSERT_FALSE(path);
  EXPECT_TRUE(names(path.error(), "waypoints")) << listed(path.error());
  EXPECT_TRUE(names(path.error(), "blendTolerance")) << listed(path.error());
  EXPECT_TRUE(names(path.error(), "waypoints[0].positions")) << listed(path.error());

  spec.blend_tolerance = std::numeric_limits<double>::quiet_NaN();
  spec.waypoints = {{{0, 0, 0, 0, 0, 0, 0}}, {{0, 0, std::numeric_limits<double>::infinity(), 0, 0, 0, 100.0}}};
  path = core::build_joint_path(pa10(), spec);
  ASSERT_FALSE(path);
  EXPECT_TRUE(names(path.error(), "blendTolerance")) << listed(path.error());
  EXPECT_TRUE(names(path.error(), "waypoints[1].positions[2]")) << listed(path.error());
  EXPECT_TRUE(names(path.error(), "waypoints[1].positions[6]")) << listed(path.error());
}

// ---------------------------------------------------------------------------------------
// Timing

// Every sample's velocity and acceleration by differences of the streamed positions within
// the limits (the one-step difference of a velocity is within a_max h of the mean), and the
// last sample exactly at the last waypoint, at rest.
void expect_within_limits(const JointPathPlan& p, double slack) {
  const auto s = samples_of(p);
  ASSERT_GE(s.size(), 3u);
  const core::RobotModel& m = pa10();
  for (std::size_t k = 1; k + 1 < s.size(); ++k) {
    const double h0 = s[k].t - s[k - 1].t, h1 = s[k + 1].t - s[k].t;
    for (std::size_t j = 0; j < m.dof(); ++j) {
      const auto J = static_cast<Eigen::Index>(j);
      const double v = (s[k + 1].q(J) - s[k].q(J)) / h1;
      EXPECT_LE(std::abs(v), m.limits[j].max_velocity * (1.0 + slack)) << "joint " << j << " t " << s[k].t;
      const double a = 2.0 * ((s[k + 1].q(J) - s[k].q(J)) / h1 - (s[k].q(J) - s[k - 1].q(J)) / h0) / (h0 + h1);
      EXPECT_LE(std::abs(a), m.limits[j].max_acceleration * (1.0 + slack)) << "joint " << j << " t " << s[k].t;
      EXPECT_LE(std::abs(s[k].q_dot(J)), m.limits[j].max_velocity * (1.0 + 1e-9));
      EXPECT_LE(std::abs(s[k].q_ddot(J)), m.limits[j].max_acceleration * (1.0 + 1e-9));
    }
  }
  EXPECT_EQ(s.back().q, p.path.last);
  EXPECT_EQ(s.back().q_dot.norm(), 0.0);
  EXPECT_EQ(s.front().q, p.path.first);
}

TEST(JointPathTiming, TimeOptimalSamplesStayWithinTheLimitsAtOneAndFourKilohertz) {
  std::mt19937 rng(5);
  const JointPathSpec spec = random_spec(rng, 9, 0.1);
  for (const double rate : {1000.0, 4000.0}) {
    const JointPathPlan p = plan(spec, fastest(rate));
    EXPECT_GT(p.duration_s, 0.0);
    EXPECT_LE(p.velocity_usage, 1.0 + 1e-9);
    EXPECT_LE(p.acceleration_usage, 1.0 + 1e-9);
    EXPECT_GT(std::max(p.velocity_usage, p.acceleration_usage), 0.999);  // some limit binds
    EXPECT_FALSE(p.binding.empty());
    expect_within_limits(p, 1e-3);
  }
}

TEST(JointPathTiming, NoAccelerationStepWhereABlendMeetsALine) {
  // At each junction the joint accelerations on both sides agree to within what the sweep's
  // piecewise-constant path acceleration changes from one grid interval to the next (a
  // circular arc's corner would jump by up to twice the limit).
  std::mt19937 rng(19);
  const JointPathPlan p = plan(random_spec(rng, 9, 0.2));
  const core::RobotModel& m = pa10();
  double worst = 0.0;
  for (std::size_t k = 0; k + 1 < p.path.segments.size(); ++k) {
    const double sigma = p.path.segments[k].sigma1;
    // The time of the junction: sigma(t) increases (the path rests only at its ends).
    double lo = 0.0, hi = p.duration_s;
    for (int i = 0; i < 200; ++i) ((core::evaluate(p.profile, 0.5 * (lo + hi)).s < sigma) ? lo : hi) = 0.5 * (lo + hi);
    const double t = 0.5 * (lo + hi), dt = 1e-9;
    MoveSample before, after;
    core::ProfileCursor c1, c2;
    std::size_t h1 = 0, h2 = 0;
    core::joint_path_at(p, t - dt, c1, h1, before);
    core::joint_path_at(p, t + dt, c2, h2, after);
    for (std::size_t j = 0; j < m.dof(); ++j) {
      const auto J = static_cast<Eigen::Index>(j);
      worst = std::max(worst, std::abs(after.q_ddot(J) - before.q_ddot(J)) / m.limits[j].max_acceleration);
    }
  }
  EXPECT_LT(worst, 0.02) << "largest step of a joint acceleration at a junction, of its limit";
  std::printf("[ figure   ] largest acceleration step at a blend's end: %.4f of the limit\n", worst);
}

TEST(JointPathTiming, TwoWaypointsTakeTheJointMovesMinimumTime) {
  JointPathSpec spec;
  spec.waypoints = {{{0.1, -0.4, 0.2, 0.9, -0.3, 0.5, 0.0}}, {{1.2, 0.3, -0.6, 1.5, 0.4, -0.2, 1.0}}};
  const JointPathPlan p = plan(spec, fastest(1000.0));
  core::JointMoveSpec move{spec.waypoints[0].positions, spec.waypoints[1].positions};
  const auto reference = core::plan_joint_move(pa10(), move, fastest(1000.0));
  ASSERT_TRUE(reference) << listed(reference.error());
  // The synchronised trapezoid is the time-optimal motion on the line when one joint binds
  // both limits; otherwise it is slower and the sweep faster.
  EXPECT_LE(p.duration_s, reference->duration_s * (1.0 + 2e-3));
  EXPECT_GE(p.duration_s, reference->duration_s * 0.9);
  EXPECT_LT(p.duration_grid_error, 0.01 * p.duration_s);
}

TEST(JointPathTiming, BlendsAreFasterThanRestingAndShorterWithALargerTolerance) {
  std::mt19937 rng(23);
  JointPathSpec spec = random_spec(rng, 8, 0.0);
  const double rest = plan(spec).duration_s;
  spec.blend_tolerance = 0.05;
  const double small = plan(spec).duration_s;
  spec.blend_tolerance = 0.2;
  const double large = plan(spec).duration_s;
  EXPECT_LT(small, rest);
  EXPECT_LT(large, small);
}

TEST(JointPathTiming, AGivenDurationIsHonouredAndRestsAtTheStops) {
  std::mt19937 rng(29);
  JointPathSpec spec = random_spec(rng, 5, 0.1);
  spec.waypoints[2].stop = true;
  MotionSpec motion = fastest(250.0);
  const double fastest_s = plan(spec, motion).duration_s;
  motion.duration_s = 2.0 * fastest_s;
  const JointPathPlan p = plan(spec, motion);
  EXPECT_DOUBLE_EQ(p.duration_s, 2.0 * fastest_s);
  EXPECT_LE(p.velocity_usage, 0.5 + 1e-6);
  EXPECT_LE(p.acceleration_usage, 0.25 + 1e-6);
  // The stop: some sample within a period of it is at the waypoint, at rest.
  const auto s = samples_of(p);
  const JointVector stop = vec(spec.waypoints[2].positions);
  double nearest = std::numeric_limits<double>::infinity();
  for (const auto& x : s) nearest = std::min(nearest, (x.q - stop).norm());
  EXPECT_LT(nearest, 1e-3);
  EXPECT_EQ(s.size(), core::grid_sample_count(p.duration_s, 250.0));
}

TEST(JointPathTiming, SamplingAllocatesNothing) {
  std::mt19937 rng(31);
  const JointPathPlan p = plan(random_spec(rng, 6, 0.1));
  core::JointPathSampler sampler(p);
  MoveSample s;
  sampler.next(s);  // sizes the sample's vectors
  const long before = testing::allocation_count();
  while (sampler.next(s)) {
  }
  EXPECT_EQ(testing::allocation_count(), before);
}

}  // namespace
}  // namespace geotraj::test
