// Random basic moves (6.2.2), fixed seed, GEOTRAJ_PROPERTY_CASES cases each (default 300):
//  - joint moves on random arms (kinematics/random_robot.hpp) with random limits, shapes,
//    speed scales and durations: exact grid and ends, joints between the ends, minimum-time
//    moves within every joint limit with one joint at a limit, rates against central
//    differences at a random instant;
//  - straight-line moves between random poses: exact ends, positions on the segment, unit
//    and continuous orientation on the SLERP, speed and acceleration within the limits.
// A failing case prints its inputs in full (17 digits).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/planning/moves.hpp"
#include "random_robot.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::JointMovePlan;
using core::LinearMovePlan;
using core::MotionSpec;
using core::MoveSample;
using core::ProfileShape;
using Eigen::Quaterniond;
using Eigen::Vector3d;

std::string listed(const core::Violations& v) {
  std::string out;
  for (const auto& x : v) out += "  " + x.field + ": " + x.description + "\n";
  return out;
}

std::string describe_motion(const MotionSpec& m) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "motion: durationS %.17g profile %s rampFraction %.17g cycleRateHz %.17g speedScale %.17g maxSpeed "
                "%.17g maxAcceleration %.17g maxJerk %.17g\n",
                m.duration_s, m.profile == ProfileShape::kSCurve ? "S_CURVE" : "TRAPEZOIDAL", m.ramp_fraction,
                m.cycle_rate_hz, m.speed_scale, m.max_speed.value_or(0.0), m.max_acceleration.value_or(0.0),
                m.max_jerk.value_or(0.0));
  return buf;
}

// About 200 samples whatever the duration (the sampling is what is tested, not its cost).
// A plan refused fails the test (the exception of value()).
template <class Plan, class PlanFn>
Plan replan_for_samples(PlanFn plan_fn, MotionSpec& m) {
  m.cycle_rate_hz = 1.0;
  auto first = plan_fn(m);
  EXPECT_TRUE(first.has_value()) << (first ? "" : listed(first.error()));
  if (first.value().duration_s > 0.0) m.cycle_rate_hz = std::min(1e5, 200.0 / first->duration_s);
  auto plan = plan_fn(m);
  EXPECT_TRUE(plan.has_value()) << (plan ? "" : listed(plan.error()));
  return std::move(plan).value();
}

TEST(MovesProperty, RandomJointMoves) {
  std::mt19937_64 rng(kPropertySeed + 10);
  std::uniform_real_distribution<double> coin(0.0, 1.0);
  const int cases = property_case_count(300);
  for (int c = 0; c < cases; ++c) {
    core::RobotModel model = random_robot(rng);
    for (auto& l : model.limits) {
      l.max_velocity = 0.2 + 4.8 * coin(rng);
      l.max_acceleration = 0.5 + 19.5 * coin(rng);
      if (coin(rng) < 0.5) l.max_jerk = 2.0 + 198.0 * coin(rng);
    }
    const core::ValidRobot robot = core::ValidRobot::check(model).value();
    const core::JointVector q0 = random_joints(model, rng), q1 = random_joints(model, rng);
    core::JointMoveSpec spec;
    for (Eigen::Index i = 0; i < q0.size(); ++i) {
      spec.start.push_back(q0(i));
      spec.goal.push_back(q1(i));
    }
    MotionSpec m;
    m.profile = coin(rng) < 0.5 ? ProfileShape::kTrapezoidal : ProfileShape::kSCurve;
    m.ramp_fraction = 0.05 + 0.45 * coin(rng);
    m.speed_scale = 0.2 + 0.8 * coin(rng);
    const bool min_time = coin(rng) < 0.7;
    m.duration_s = min_time ? 0.0 : 0.5 + 5.0 * coin(rng);
    const auto plan = replan_for_samples<JointMovePlan>(
        [&](const MotionSpec& x) { return core::plan_joint_move(robot, spec, x); }, m);
    SCOPED_TRACE(describe_robot(model, q0, q1) + "(q: start, q_dot: goal)\n" + describe_motion(m));
    if (HasFailure()) break;

    std::vector<MoveSample> samples;
    core::JointMoveSampler sampler(plan);
    MoveSample s;
    while (sampler.next(s)) samples.push_back(s);
    ASSERT_EQ(samples.size(), plan.sample_count);
    EXPECT_EQ(samples.back().t, plan.duration_s);
    EXPECT_EQ(samples.front().q, q0);
    EXPECT_EQ(samples.back().q, q1);
    const double sc = m.speed_scale;
    double v_use = 0.0, a_use = 0.0;
    for (const MoveSample& x : samples) {
      for (std::size_t i = 0; i < model.dof(); ++i) {
        const auto j = static_cast<Eigen::Index>(i);
        EXPECT_GE(x.q(j), std::min(q0(j), q1(j)));
        EXPECT_LE(x.q(j), std::max(q0(j), q1(j)));
        v_use = std::max(v_use, std::abs(x.q_dot(j)) / model.limits[i].max_velocity);
        a_use = std::max(a_use, std::abs(x.q_ddot(j)) / model.limits[i].max_acceleration);
      }
    }
    EXPECT_LE(v_use, plan.velocity_usage * (1 + 1e-12) + 1e-300);
    EXPECT_LE(a_use, plan.acceleration_usage * (1 + 1e-12) + 1e-300);
    if (min_time) {
      // Within every limit (scaled), and one of them reached: the move is synchronised on
      // the tightest joint.
      EXPECT_LE(plan.velocity_usage, sc * (1 + 1e-12));
      EXPECT_LE(plan.acceleration_usage, sc * sc * (1 + 1e-12));
      double j_use = 0.0;
      bool any_jerk = false;
      for (std::size_t i = 0; i < model.dof(); ++i) {
        if (!model.limits[i].max_jerk) continue;
        any_jerk = true;
        const auto j = static_cast<Eigen::Index>(i);
        j_use = std::max(j_use, core::peak_jerk(plan.profile) * std::abs(q1(j) - q0(j)) / *model.limits[i].max_jerk);
      }
      const bool jerk_bound = m.profile == ProfileShape::kSCurve && any_jerk;
      if (jerk_bound) {
        EXPECT_LE(j_use, sc * sc * sc * (1 + 1e-12));
      }
      const double reached = std::max({plan.velocity_usage / sc, plan.acceleration_usage / (sc * sc),
                                       jerk_bound ? j_use / (sc * sc * sc) : 0.0});
      EXPECT_NEAR(reached, 1.0, 1e-9);
    } else {
      EXPECT_NEAR(plan.duration_s, m.duration_s / sc, 1e-15 * plan.duration_s);
    }
    // Rates against central differences at one instant inside a piece.
    const double h = 1e-6 * plan.duration_s;
    const auto& pcs = plan.profile.pieces;
    ASSERT_FALSE(pcs.empty());
    const std::size_t piece = static_cast<std::size_t>(coin(rng) * static_cast<double>(pcs.size())) % pcs.size();
    const double t0 = pcs[piece].t0, t1 = piece + 1 < pcs.size() ? pcs[piece + 1].t0 : plan.duration_s;
    if (t1 - t0 > 10 * h) {
      const double t = t0 + 5 * h + (t1 - t0 - 10 * h) * coin(rng);
      MoveSample lo, mid, hi;
      core::joint_move_at(plan, t - h, lo);
      core::joint_move_at(plan, t, mid);
      core::joint_move_at(plan, t + h, hi);
      const auto close = [](const auto& a, const auto& b) {
        return (a - b).cwiseAbs().maxCoeff() <= 1e-6 * std::max(1.0, b.cwiseAbs().maxCoeff());
      };
      EXPECT_TRUE(close(mid.q_dot, (hi.q - lo.q) / (2 * h))) << "q_dot at t = " << t;
      EXPECT_TRUE(close(mid.v_W, (hi.p_W - lo.p_W) / (2 * h))) << "v_W at t = " << t;
      EXPECT_TRUE(close(mid.a_W, (hi.v_W - lo.v_W) / (2 * h))) << "a_W at t = " << t;
      EXPECT_TRUE(close(mid.alpha_W, (hi.omega_W - lo.omega_W) / (2 * h))) << "alpha_W at t = " << t;
    }
    if (HasFailure()) break;  // one replayable case is enough
  }
}

Quaterniond random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  return Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
}

TEST(MovesProperty, RandomLinearMoves) {
  std::mt19937_64 rng(kPropertySeed + 11);
  std::uniform_real_distribution<double> coin(0.0, 1.0), unit(-1.0, 1.0);
  const int cases = property_case_count(300);
  for (int c = 0; c < cases; ++c) {
    core::LinearMoveSpec spec;
    spec.start.p_WT = Vector3d(unit(rng), unit(rng), unit(rng));
    spec.goal.p_WT = coin(rng) < 0.1 ? spec.start.p_WT : Vector3d(unit(rng), unit(rng), unit(rng));
    spec.start.q_WT = random_rotation(rng);
    spec.goal.q_WT = random_rotation(rng);
    const bool pure_rotation = spec.goal.p_WT == spec.start.p_WT;
    MotionSpec m;
    m.profile = coin(rng) < 0.5 ? ProfileShape::kTrapezoidal : ProfileShape::kSCurve;
    m.ramp_fraction = 0.05 + 0.45 * coin(rng);
    m.speed_scale = 0.2 + 0.8 * coin(rng);
    m.max_speed = 0.05 + 2.0 * coin(rng);
    m.max_acceleration = 0.1 + 10.0 * coin(rng);
    m.max_jerk = 1.0 + 100.0 * coin(rng);
    const bool min_time = !pure_rotation && coin(rng) < 0.7;
    m.duration_s = min_time ? 0.0 : 0.2 + 5.0 * coin(rng);
    const auto plan =
        replan_for_samples<LinearMovePlan>([&](const MotionSpec& x) { return core::plan_linear_move(spec, x); }, m);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "start p (%.17g, %.17g, %.17g) q_wxyz (%.17g, %.17g, %.17g, %.17g)\n"
                  "goal  p (%.17g, %.17g, %.17g) q_wxyz (%.17g, %.17g, %.17g, %.17g)\n",
                  spec.start.p_WT.x(), spec.start.p_WT.y(), spec.start.p_WT.z(), spec.start.q_WT.w(),
                  spec.start.q_WT.x(), spec.start.q_WT.y(), spec.start.q_WT.z(), spec.goal.p_WT.x(), spec.goal.p_WT.y(),
                  spec.goal.p_WT.z(), spec.goal.q_WT.w(), spec.goal.q_WT.x(), spec.goal.q_WT.y(), spec.goal.q_WT.z());
    SCOPED_TRACE(std::string(buf) + describe_motion(m));
    if (HasFailure()) break;

    const Vector3d d = spec.goal.p_WT - spec.start.p_WT;
    const double L = d.norm();
    const Quaterniond q0 = spec.start.q_WT.normalized(), q1 = spec.goal.q_WT.normalized();
    core::LinearMoveSampler sampler(plan);
    MoveSample s, prev;
    std::size_t n = 0;
    const double sc = m.speed_scale;
    while (sampler.next(s)) {
      EXPECT_NEAR(s.q_WT.norm(), 1.0, 1e-15);
      EXPECT_LE(s.q_WT.angularDistance(q0.slerp(s.u, q1)), 1e-12) << "t = " << s.t;
      if (L > 0.0) {
        // On the segment to rounding: a few ulps of the coordinates (up to ~2 m here); the
        // last bits differ between compilers (clang's contractions measured 1.09e-15).
        const double rounding = 16.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, L);
        const Vector3d r = s.p_W - spec.start.p_WT;
        EXPECT_LE((r - r.dot(d) / (L * L) * d).norm(), rounding) << "t = " << s.t;
        EXPECT_NEAR(r.norm(), s.s, rounding);
      } else {
        EXPECT_EQ(s.p_W, spec.start.p_WT);
      }
      if (min_time) {
        EXPECT_LE(s.speed, *m.max_speed * sc * (1 + 1e-12));
        EXPECT_LE(s.a_W.norm(), *m.max_acceleration * sc * sc * (1 + 1e-12));
      }
      if (n > 0) {
        EXPECT_GE(s.u, prev.u);
        EXPECT_GT(s.q_WT.coeffs().dot(prev.q_WT.coeffs()), 0.0);
      }
      prev = s;
      ++n;
    }
    EXPECT_EQ(n, plan.sample_count);
    EXPECT_EQ(prev.t, plan.duration_s);
    EXPECT_EQ(prev.p_W, spec.goal.p_WT);
    EXPECT_LE(prev.q_WT.angularDistance(q1), 1e-14);
    if (HasFailure()) break;
  }
}

}  // namespace
}  // namespace geotraj::test
