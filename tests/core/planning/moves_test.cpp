// The thesis's basic moves (6.2.2): the joint-interpolated move (6.2.2.1) and the Cartesian
// straight-line move (6.2.2.2, Eqs. 6.1, 6.2). Sample grid and exact ends, rests, analytic
// velocities and accelerations against central differences, joint limits of minimum-time
// moves (synchronised: one joint at its limit), the straight line and the SLERP, pure
// rotations, errors that name their fields, and no allocation per sample.
#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "random_robot.hpp"
#include "test_support.hpp"
#include "core/planning/moves.hpp"
#include "core/robot/dynamics.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::test {
namespace {

using core::JointMovePlan;
using core::JointMoveSpec;
using core::JointVector;
using core::LinearMovePlan;
using core::LinearMoveSpec;
using core::MotionSpec;
using core::MoveSample;
using core::ProfileShape;
using core::RobotModel;
using core::Violations;
using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const RobotModel& pa10() { return *core::find_builtin_robot("pa10"); }
const RobotModel& ur5() { return *core::find_builtin_robot("ur5"); }

MotionSpec timed(double duration, ProfileShape shape = ProfileShape::kTrapezoidal, double rate = 100.0) {
  MotionSpec m;
  m.duration_s = duration;
  m.profile = shape;
  m.cycle_rate_hz = rate;
  return m;
}

MotionSpec fastest(ProfileShape shape = ProfileShape::kTrapezoidal, double rate = 100.0) {
  MotionSpec m = timed(0.0, shape, rate);
  return m;
}

JointMoveSpec joint_move(const std::vector<double>& start, const std::vector<double>& goal) { return {start, goal}; }

// A pa10 start (elbow and wrist bent, away from singularities) and a move from it that
// turns every joint.
const std::vector<double> kPa10Start = {0.0, 0.5, 0.0, 1.2, 0.0, 0.9, 0.0};
JointMoveSpec pa10_move() { return joint_move(kPa10Start, {0.8, -0.3, 0.6, 1.9, -1.0, 0.2, 2.5}); }
const std::vector<double> kUr5Start = {0.0, -std::numbers::pi / 2, std::numbers::pi / 2, -std::numbers::pi / 2,
                                       -std::numbers::pi / 2, 0.0};

// The model checked, as where a model enters the service.
core::ValidRobot valid(const RobotModel& model) { return core::ValidRobot::check(model).value(); }

// The plan (a failed one fails the test through the exception of value()).
JointMovePlan plan_or_fail(const RobotModel& model, const JointMoveSpec& spec, const MotionSpec& motion) {
  auto plan = core::plan_joint_move(valid(model), spec, motion);
  EXPECT_TRUE(plan.has_value()) << (plan ? "" : listed(plan.error()));
  return std::move(plan).value();
}

LinearMovePlan plan_or_fail(const LinearMoveSpec& spec, const MotionSpec& motion) {
  auto plan = core::plan_linear_move(spec, motion);
  EXPECT_TRUE(plan.has_value()) << (plan ? "" : listed(plan.error()));
  if (!plan) return {};
  return *plan;
}

template <class Sampler, class Plan>
std::vector<MoveSample> run(const Plan& plan) {
  std::vector<MoveSample> out;
  if (plan.sample_count == 0) return out;  // a plan that failed (already reported)
  out.reserve(plan.sample_count);
  Sampler sampler(plan);
  MoveSample s;
  while (sampler.next(s)) out.push_back(s);
  return out;
}

std::vector<MoveSample> run(const JointMovePlan& plan) { return run<core::JointMoveSampler>(plan); }
std::vector<MoveSample> run(const LinearMovePlan& plan) { return run<core::LinearMoveSampler>(plan); }

Quaterniond quat(double w, double x, double y, double z) { return Quaterniond(w, x, y, z).normalized(); }

LinearMoveSpec line_move() {
  LinearMoveSpec spec;
  spec.start.p_WT = Vector3d(0.4, -0.2, 0.5);
  spec.start.q_WT = quat(0.2, 0.9, -0.1, 0.3);
  spec.goal.p_WT = Vector3d(0.1, 0.35, 0.8);
  spec.goal.q_WT = quat(-0.5, 0.1, 0.7, 0.2);
  return spec;
}

MotionSpec cartesian_fastest(ProfileShape shape = ProfileShape::kTrapezoidal) {
  MotionSpec m = fastest(shape);
  m.max_speed = 0.5;
  m.max_acceleration = 2.0;
  m.max_jerk = 20.0;
  return m;
}

// The axial vector of the skew part of W ([omega]x = R_dot R^T).
Vector3d axial(const Eigen::Matrix3d& W) {
  return Vector3d(W(2, 1) - W(1, 2), W(0, 2) - W(2, 0), W(1, 0) - W(0, 1)) / 2;
}

// |a - b| <= tol max(1, |b|)
::testing::AssertionResult Near(const Eigen::VectorXd& a, const Eigen::VectorXd& b, double tol, const char* what) {
  const double err = (a - b).cwiseAbs().maxCoeff(), bound = tol * std::max(1.0, b.cwiseAbs().maxCoeff());
  if (err <= bound) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << what << ": error " << err << " > " << bound << "\n  analytic " << a.transpose()
                                       << "\n  differences " << b.transpose();
}

// Central differences at t with step h of every rate a MoveSample carries, against the
// analytic ones. The caller keeps t +- h inside one piece of the profile.
template <class At>
void check_rates(At at, double t, double h, double tol, bool joints) {
  MoveSample m, p, s;
  at(t - h, m);
  at(t, s);
  at(t + h, p);
  SCOPED_TRACE(::testing::Message() << "t = " << t);
  EXPECT_TRUE(Near(s.v_W, (p.p_W - m.p_W) / (2 * h), tol, "v_W"));
  EXPECT_TRUE(Near(s.a_W, (p.v_W - m.v_W) / (2 * h), tol, "a_W"));
  const Eigen::Matrix3d R = s.q_WT.toRotationMatrix();
  const Eigen::Matrix3d R_dot = (p.q_WT.toRotationMatrix() - m.q_WT.toRotationMatrix()) / (2 * h);
  EXPECT_TRUE(Near(s.omega_W, axial(R_dot * R.transpose()), tol, "omega_W (from dR/dt R^T)"));
  EXPECT_TRUE(Near(s.alpha_W, (p.omega_W - m.omega_W) / (2 * h), tol, "alpha_W"));
  EXPECT_NEAR(s.speed, s.v_W.norm(), 1e-15);
  if (joints) {
    EXPECT_TRUE(Near(s.q_dot, (p.q - m.q) / (2 * h), tol, "q_dot"));
    EXPECT_TRUE(Near(s.q_ddot, (p.q_dot - m.q_dot) / (2 * h), tol, "q_ddot"));
  }
}

// Times strictly inside the pieces of `profile` (at least `margin` from every boundary).
std::vector<double> interior_times(const core::SpeedProfile& profile, double margin, int per_piece) {
  std::vector<double> out;
  for (std::size_t i = 0; i < profile.pieces.size(); ++i) {
    const double t0 = profile.pieces[i].t0;
    const double t1 = i + 1 < profile.pieces.size() ? profile.pieces[i + 1].t0 : profile.duration;
    if (t1 - t0 <= 2 * margin) continue;
    for (int k = 1; k <= per_piece; ++k) out.push_back(t0 + margin + (t1 - t0 - 2 * margin) * k / (per_piece + 1));
  }
  return out;
}

// =======================================================================================
// Joint-interpolated move (6.2.2.1)

TEST(JointMove, SampleGridHasTheExactCountAndEndsAtTheDuration) {
  struct Case {
    double duration, rate, scale;
    std::size_t count;
    double end;
  };
  for (const Case c : {Case{2.0, 100.0, 1.0, 201, 2.0}, Case{1.234, 100.0, 1.0, 125, 1.234},
                       Case{1.0, 250.0, 0.5, 501, 2.0}, Case{0.3, 1000.0, 1.0, 301, 0.3}}) {
    MotionSpec m = timed(c.duration, ProfileShape::kTrapezoidal, c.rate);
    m.speed_scale = c.scale;
    const JointMovePlan plan = plan_or_fail(pa10(), pa10_move(), m);
    EXPECT_EQ(plan.sample_count, c.count);
    EXPECT_EQ(plan.duration_s, c.end);
    const auto samples = run(plan);
    ASSERT_EQ(samples.size(), c.count);
    for (std::size_t k = 0; k + 1 < samples.size(); ++k) EXPECT_EQ(samples[k].t, static_cast<double>(k) / c.rate);
    EXPECT_EQ(samples.back().t, c.end);
  }
}

TEST(JointMove, StartsAndEndsAtRestExactlyAtTheGivenJoints) {
  for (const ProfileShape shape : {ProfileShape::kTrapezoidal, ProfileShape::kSCurve}) {
    for (const MotionSpec& m : {timed(1.7, shape), fastest(shape)}) {
      const JointMoveSpec spec = pa10_move();
      const auto samples = run(plan_or_fail(pa10(), spec, m));
      ASSERT_GE(samples.size(), 2u);
      const MoveSample& first = samples.front();
      const MoveSample& last = samples.back();
      ASSERT_TRUE(first.has_joints && last.has_joints);
      for (std::size_t i = 0; i < 7; ++i) {
        const auto j = static_cast<Eigen::Index>(i);
        EXPECT_EQ(first.q(j), spec.start[i]);
        EXPECT_EQ(last.q(j), spec.goal[i]);
        EXPECT_EQ(first.q_dot(j), 0.0);
        EXPECT_EQ(last.q_dot(j), 0.0);
        EXPECT_EQ(last.q_ddot(j), 0.0);
      }
      EXPECT_EQ(first.u, 0.0);
      EXPECT_EQ(last.u, 1.0);
      EXPECT_EQ(first.speed, 0.0);
      EXPECT_EQ(last.speed, 0.0);
      EXPECT_EQ(last.omega_W.norm(), 0.0);
      EXPECT_EQ(last.a_W.norm(), 0.0);
      // The tool pose is the forward kinematics of the ends.
      JointVector q1(7);
      for (std::size_t i = 0; i < 7; ++i) q1(static_cast<Eigen::Index>(i)) = spec.goal[i];
      const Eigen::Isometry3d X1 = core::forward_kinematics(pa10(), q1);
      EXPECT_EQ(last.p_W, X1.translation());
      EXPECT_LE(last.q_WT.angularDistance(Quaterniond(X1.linear())), 1e-15);
      EXPECT_GT(last.manipulability, 0.0);
    }
  }
}

TEST(JointMove, JointsFollowTheStraightLineOfJointSpace) {
  const JointMoveSpec spec = pa10_move();
  const auto samples = run(plan_or_fail(pa10(), spec, timed(1.5, ProfileShape::kSCurve)));
  double u_prev = -1.0;
  for (const MoveSample& s : samples) {
    EXPECT_GE(s.u, u_prev);  // x(t) monotone
    u_prev = s.u;
    EXPECT_EQ(s.s, 0.0);
    for (std::size_t i = 0; i < 7; ++i) {
      const auto j = static_cast<Eigen::Index>(i);
      EXPECT_NEAR(s.q(j), spec.start[i] + s.u * (spec.goal[i] - spec.start[i]), 1e-15);
    }
  }
}

TEST(JointMove, RatesMatchCentralDifferences) {
  // h = 1e-5 s: truncation h^2 |d3/dt3| / 6 below 1e-9 on these moves, rounding 1e-16 / h.
  constexpr double h = 1e-5, tol = 1e-7;
  for (const RobotModel* model : {&pa10(), &ur5()}) {
    const JointMoveSpec spec = model == &pa10() ? pa10_move()
                                                : joint_move(kUr5Start, {1.0, -0.6, 2.0, -2.5, 0.7, 3.0});
    for (const ProfileShape shape : {ProfileShape::kTrapezoidal, ProfileShape::kSCurve}) {
      for (const MotionSpec& m : {timed(1.3, shape), fastest(shape)}) {
        const JointMovePlan plan = plan_or_fail(*model, spec, m);
        SCOPED_TRACE(model->name);
        const auto at = [&](double t, MoveSample& out) { core::joint_move_at(plan, t, out); };
        for (const double t : interior_times(plan.profile, 4 * h, 5)) check_rates(at, t, h, tol, true);
      }
    }
  }
}

// |q_dot_i| / vmax_i, |q_ddot_i| / amax_i (and jerk) over the samples, and the largest.
struct Usage {
  double velocity = 0.0, acceleration = 0.0;
};

Usage measured_usage(const RobotModel& model, const std::vector<MoveSample>& samples) {
  Usage u;
  for (const MoveSample& s : samples) {
    for (std::size_t i = 0; i < model.dof(); ++i) {
      const auto j = static_cast<Eigen::Index>(i);
      EXPECT_GE(s.q(j), model.limits[i].min_position);
      EXPECT_LE(s.q(j), model.limits[i].max_position);
      u.velocity = std::max(u.velocity, std::abs(s.q_dot(j)) / model.limits[i].max_velocity);
      u.acceleration = std::max(u.acceleration, std::abs(s.q_ddot(j)) / model.limits[i].max_acceleration);
    }
  }
  return u;
}

TEST(JointMove, MinimumTimeKeepsEveryJointWithinItsLimitsWithOneAtALimit) {
  for (const ProfileShape shape : {ProfileShape::kTrapezoidal, ProfileShape::kSCurve}) {
    for (const double scale : {1.0, 0.4}) {
      MotionSpec m = fastest(shape, 1000.0);
      m.speed_scale = scale;
      const JointMovePlan plan = plan_or_fail(pa10(), pa10_move(), m);
      SCOPED_TRACE(::testing::Message() << "shape " << static_cast<int>(shape) << ", scale " << scale);
      // The plan's usage is exact (peaks of the profile); the samples confirm it.
      EXPECT_LE(plan.velocity_usage, scale + 1e-12);
      EXPECT_LE(plan.acceleration_usage, scale * scale + 1e-12);
      EXPECT_NEAR(std::max(plan.velocity_usage / scale, plan.acceleration_usage / (scale * scale)), 1.0, 1e-12);
      const Usage u = measured_usage(pa10(), run(plan));
      EXPECT_LE(u.velocity, scale * (1 + 1e-12));
      EXPECT_LE(u.acceleration, scale * scale * (1 + 1e-12));
    }
  }
}

// Within torques (moves.hpp, torque_stretch): the PA-10 given random mass properties and a
// 2 kg payload, each joint's torque limit halfway between its largest gravity load along the
// move and its largest torque on the fastest move within the joint limits (at least 5 % above
// that load); stretched by the
// factor torque_stretch gives, the move's torques, sampled at 10 kHz, stay within every limit
// and one reaches it. Random seeds, both profiles.
TEST(JointMove, StretchedByTorqueStretchTheTorquesHoldWithOneAtItsLimit) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    std::mt19937_64 rng(seed);
    RobotModel model = with_random_inertials(pa10(), rng);
    model.payload.mass = 2.0;
    model.payload.center_of_mass = Vector3d(0.0, 0.0, 0.1);
    for (const ProfileShape shape : {ProfileShape::kTrapezoidal, ProfileShape::kSCurve}) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << ", shape " << static_cast<int>(shape));
      const MotionSpec m = fastest(shape, 10'000.0);
      const JointMovePlan free = plan_or_fail(model, pa10_move(), m);
      const auto dof = static_cast<Eigen::Index>(model.dof());
      const JointVector zero = JointVector::Zero(dof);
      // The torques of a plan's samples, and the gravity loads along the move.
      const auto torques = [&](const core::RobotModel& r, const JointMovePlan& plan, JointVector& peak, JointVector& load) {
        peak = load = JointVector::Zero(dof);
        JointVector tau, g;
        for (const MoveSample& s : run(plan)) {
          core::inverse_dynamics(r, s.q, s.q_dot, s.q_ddot, core::dynamics_options(r), tau);
          core::inverse_dynamics(r, s.q, zero, zero, core::dynamics_options(r), g);
          peak = peak.cwiseMax(tau.cwiseAbs());
          load = load.cwiseMax(g.cwiseAbs());
        }
      };
      JointVector peak, load;
      torques(model, free, peak, load);
      RobotModel limited = model;
      for (std::size_t j = 0; j < model.dof(); ++j)
        limited.limits[j].max_torque = std::max(1.05 * load(static_cast<Eigen::Index>(j)),
                                                0.5 * (peak(static_cast<Eigen::Index>(j)) + load(static_cast<Eigen::Index>(j))));
      const JointMovePlan fast = plan_or_fail(limited, pa10_move(), m);
      const double f = core::torque_stretch(fast, 2'000.0);
      EXPECT_GT(f, 1.0);
      MotionSpec slower = m;
      slower.speed_scale /= f * (1.0 + 1e-6);
      const JointMovePlan stretched = plan_or_fail(limited, pa10_move(), slower);
      EXPECT_NEAR(stretched.duration_s, fast.duration_s * f, 1e-5 * fast.duration_s * f);
      JointVector stretched_peak, unused;
      torques(limited, stretched, stretched_peak, unused);
      double top = 0.0;
      for (std::size_t j = 0; j < model.dof(); ++j) {
        const double usage = stretched_peak(static_cast<Eigen::Index>(j)) / *limited.limits[j].max_torque;
        EXPECT_LE(usage, 1.0 + 1e-6) << "joint " << j;
        top = std::max(top, usage);
      }
      EXPECT_GT(top, 0.999);
      EXPECT_NEAR(core::torque_stretch(stretched, 2'000.0), 1.0, 1e-5);
    }
  }
}

TEST(JointMove, MinimumTimeIsTheSlowestJointsOwnTimeAndTheOthersFinishWithIt) {
  // Joint 0 moves furthest and has the lowest limits: it is the slowest in every respect,
  // so the move takes exactly its own minimum time; the others are scaled to finish with it.
  const JointMoveSpec spec = joint_move(kPa10Start, {2.0, 0.9, 0.3, 1.0, 0.5, 1.1, -0.4});
  const JointMovePlan plan = plan_or_fail(pa10(), spec, fastest());
  EXPECT_EQ(plan.limiting_joint, 0u);
  const auto& lim = pa10().limits[0];
  const auto own = core::min_time_trapezoid(2.0 - kPa10Start[0], lim.max_velocity, lim.max_acceleration);
  ASSERT_TRUE(own.has_value());
  EXPECT_NEAR(plan.duration_s, own->duration, 1e-12 * own->duration);
  // Joint 0 reaches its speed limit (a cruise) and its acceleration limit.
  EXPECT_NEAR(plan.velocity_usage, 1.0, 1e-12);
  EXPECT_NEAR(plan.acceleration_usage, 1.0, 1e-12);
  // Every joint arrives at the same time: the last sample, not before.
  const auto samples = run(plan);
  const MoveSample& before = samples[samples.size() - 2];
  for (std::size_t i = 0; i < 7; ++i) {
    const auto j = static_cast<Eigen::Index>(i);
    EXPECT_NE(before.q(j), spec.goal[i]) << "joint " << i << " arrived early";
  }
}

TEST(JointMove, MinimumTimeSCurveHonoursJointJerkLimits) {
  RobotModel model = pa10();
  for (auto& l : model.limits) l.max_jerk = 6.0 * l.max_acceleration;
  const JointMovePlan plan = plan_or_fail(model, pa10_move(), fastest(ProfileShape::kSCurve, 2000.0));
  const double x_jerk = core::peak_jerk(plan.profile);
  double jerk_usage = 0.0;
  for (std::size_t i = 0; i < 7; ++i) {
    const double d = std::abs(pa10_move().goal[i] - pa10_move().start[i]);
    jerk_usage = std::max(jerk_usage, x_jerk * d / *model.limits[i].max_jerk);
  }
  EXPECT_LE(jerk_usage, 1 + 1e-12);
  EXPECT_NEAR(std::max({plan.velocity_usage, plan.acceleration_usage, jerk_usage}), 1.0, 1e-12);
  const Usage u = measured_usage(model, run(plan));
  EXPECT_LE(u.velocity, 1 + 1e-12);
  EXPECT_LE(u.acceleration, 1 + 1e-12);
}

TEST(JointMove, SCurveWithoutJerkLimitsIsTheFastestRampFractionSCurve) {
  // The built-in arms publish no jerk limits: the S-curve of rampFraction, as fast as the
  // speed and acceleration limits allow (continuous acceleration, a limit reached).
  MotionSpec m = fastest(ProfileShape::kSCurve);
  m.ramp_fraction = 0.3;
  const JointMovePlan plan = plan_or_fail(pa10(), pa10_move(), m);
  EXPECT_NEAR(std::max(plan.velocity_usage, plan.acceleration_usage), 1.0, 1e-12);
  EXPECT_LE(plan.velocity_usage, 1 + 1e-12);
  EXPECT_LE(plan.acceleration_usage, 1 + 1e-12);
  // The acceleration is continuous: starts and ends at zero.
  EXPECT_EQ(plan.profile.pieces.front().a0, 0.0);
  EXPECT_NEAR(core::evaluate(plan.profile, plan.duration_s * (1 - 1e-12)).a, 0.0, 1e-6);
}

TEST(JointMove, WithADurationTheTimeIsHonouredAndTheUsageReported) {
  const JointMovePlan slow = plan_or_fail(pa10(), pa10_move(), timed(30.0));
  EXPECT_EQ(slow.duration_s, 30.0);
  EXPECT_LT(slow.velocity_usage, 1.0);
  const JointMovePlan fast = plan_or_fail(pa10(), pa10_move(), timed(0.2));
  EXPECT_EQ(fast.duration_s, 0.2);
  EXPECT_GT(fast.velocity_usage, 1.0);  // beyond the limits, as asked; the plan says so
}

TEST(JointMove, NothingToMove) {
  const JointMoveSpec still = joint_move(kPa10Start, kPa10Start);
  const JointMovePlan fast = plan_or_fail(pa10(), still, fastest());
  EXPECT_EQ(fast.duration_s, 0.0);
  EXPECT_EQ(fast.sample_count, 1u);
  const auto one = run(fast);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].t, 0.0);
  EXPECT_EQ(one[0].u, 1.0);
  EXPECT_EQ(one[0].q_dot.norm(), 0.0);
  const auto rest = run(plan_or_fail(pa10(), still, timed(0.5)));
  ASSERT_EQ(rest.size(), 51u);
  for (const MoveSample& s : rest) EXPECT_EQ(s.speed, 0.0);
}

TEST(JointMove, QuaternionsStayInOneHemisphere) {
  // The UR5's last joint turns by 6 rad: the tool turns through +-pi, where a quaternion
  // from a rotation matrix would flip sign.
  const JointMoveSpec spec = joint_move(kUr5Start, {0.0, -1.2, 1.5, -1.9, -1.57, 6.0});
  const auto samples = run(plan_or_fail(ur5(), spec, timed(3.0)));
  for (std::size_t k = 1; k < samples.size(); ++k) {
    EXPECT_GT(samples[k].q_WT.coeffs().dot(samples[k - 1].q_WT.coeffs()), 0.9) << "sample " << k;
    EXPECT_NEAR(samples[k].q_WT.norm(), 1.0, 1e-15);
  }
}

TEST(JointMove, NoHeapAllocationPerSample) {
  const JointMovePlan plan = plan_or_fail(pa10(), pa10_move(), timed(2.0, ProfileShape::kSCurve, 1000.0));
  ASSERT_GT(plan.sample_count, 0u);
  core::JointMoveSampler sampler(plan);
  MoveSample s;
  sampler.next(s);  // sizes the sample's vectors
  const long before = geotraj::testing::allocation_count();
  std::size_t n = 1;
  while (sampler.next(s)) ++n;
  EXPECT_EQ(geotraj::testing::allocation_count(), before);
  EXPECT_EQ(n, plan.sample_count);
  sampler.reset();
  EXPECT_EQ(sampler.index(), 0u);
  ASSERT_TRUE(sampler.next(s));
  EXPECT_EQ(s.t, 0.0);
}

TEST(JointMove, BadInputNamesEveryField) {
  RobotModel model = pa10();
  JointMoveSpec spec = pa10_move();
  spec.start[1] = model.limits[1].max_position + 0.01;  // outside the limits
  spec.goal[2] = kNaN;
  spec.goal[6] = -100.0;
  MotionSpec m = timed(-1.0);
  m.cycle_rate_hz = 0.0;
  auto plan = core::plan_joint_move(valid(model), spec, m);
  ASSERT_FALSE(plan.has_value());
  const Violations& v = plan.error();
  for (const char* field :
       {"jointMove.start[1]", "jointMove.goal[2]", "jointMove.goal[6]", "motion.durationS", "motion.cycleRateHz"})
    EXPECT_TRUE(names(v, field)) << field << "\n" << listed(v);
  EXPECT_EQ(v.size(), 5u) << listed(v);
}

TEST(JointMove, WrongSizes) {
  JointMoveSpec spec = pa10_move();
  spec.start.pop_back();
  spec.goal.push_back(0.0);
  auto plan = core::plan_joint_move(valid(pa10()), spec, timed(1.0));
  ASSERT_FALSE(plan.has_value());
  EXPECT_TRUE(names(plan.error(), "jointMove.start")) << listed(plan.error());
  EXPECT_TRUE(names(plan.error(), "jointMove.goal")) << listed(plan.error());
}

TEST(JointMove, MinimumTimeNeedsNoCartesianLimits) {
  // validate_motion asks a minimum-time PATH motion for maxSpeed and maxAcceleration (and
  // maxJerk for an S-curve); a joint move uses the joints' limits instead.
  EXPECT_TRUE(core::plan_joint_move(valid(pa10()), pa10_move(), fastest(ProfileShape::kSCurve)).has_value());
}

TEST(JointMove, TinyDisplacementsArePlannedWithFiniteNumbersOrRefused) {
  // Normalised limits vmax / |dq| are huge for |dq| = 1e-300 rad. The trapezoid is still
  // representable; the S-curve's jerk 4 v / t_b^2 overflows, and the move is refused by name.
  for (const ProfileShape shape : {ProfileShape::kTrapezoidal, ProfileShape::kSCurve}) {
    JointMoveSpec spec = joint_move(kPa10Start, kPa10Start);
    spec.goal[0] = 1e-300;  // from 0
    ASSERT_NE(spec.goal[0], spec.start[0]);
    const auto plan = core::plan_joint_move(valid(pa10()), spec, fastest(shape));
    if (!plan) {
      EXPECT_EQ(shape, ProfileShape::kSCurve);
      EXPECT_TRUE(names(plan.error(), "motion.durationS")) << listed(plan.error());
      continue;
    }
    EXPECT_TRUE(std::isfinite(plan->duration_s));
    for (const MoveSample& s : run(*plan)) {
      EXPECT_TRUE(s.q.allFinite() && s.q_dot.allFinite() && s.q_ddot.allFinite()) << "t = " << s.t;
      EXPECT_TRUE(s.v_W.allFinite() && s.a_W.allFinite() && s.alpha_W.allFinite()) << "t = " << s.t;
    }
    EXPECT_LE(plan->velocity_usage, 1.0);
    EXPECT_LE(plan->acceleration_usage, 1.0 + 1e-12);
  }
}

TEST(JointMove, TooManySamplesIsRefused) {
  MotionSpec m = timed(1e5, ProfileShape::kTrapezoidal, 1e5);
  auto plan = core::plan_joint_move(valid(pa10()), pa10_move(), m);
  ASSERT_FALSE(plan.has_value());
  EXPECT_TRUE(names(plan.error(), "motion.durationS")) << listed(plan.error());
}

// =======================================================================================
// Cartesian straight-line move (6.2.2.2)

TEST(LinearMove, SampleGridHasTheExactCountAndEndsAtTheDuration) {
  struct Case {
    double duration, rate;
    std::size_t count;
  };
  for (const auto& [duration, rate, count] : {Case{2.0, 100.0, 201}, Case{1.234, 100.0, 125}, Case{0.01, 1000.0, 11}}) {
    const LinearMovePlan plan = plan_or_fail(line_move(), timed(duration, ProfileShape::kTrapezoidal, rate));
    EXPECT_EQ(plan.sample_count, count);
    const auto samples = run(plan);
    ASSERT_EQ(samples.size(), count);
    for (std::size_t k = 0; k + 1 < samples.size(); ++k) EXPECT_EQ(samples[k].t, static_cast<double>(k) / rate);
    EXPECT_EQ(samples.back().t, duration);
  }
}

TEST(LinearMove, StartsAndEndsAtRestExactlyAtTheGivenPoses) {
  const LinearMoveSpec spec = line_move();
  for (const ProfileShape shape : {ProfileShape::kTrapezoidal, ProfileShape::kSCurve}) {
    for (const MotionSpec& m : {timed(1.1, shape), cartesian_fastest(shape)}) {
      const auto samples = run(plan_or_fail(spec, m));
      ASSERT_GE(samples.size(), 2u);
      const MoveSample& first = samples.front();
      const MoveSample& last = samples.back();
      EXPECT_FALSE(first.has_joints);
      EXPECT_EQ(first.q.size(), 0);
      EXPECT_EQ(first.p_W, spec.start.p_WT);
      EXPECT_EQ(last.p_W, spec.goal.p_WT);
      EXPECT_EQ(first.q_WT.coeffs(), spec.start.q_WT.normalized().coeffs());
      // The goal's rotation exactly, as q1 or -q1 (the hemisphere of the start).
      const Eigen::Vector4d g = spec.goal.q_WT.normalized().coeffs();
      EXPECT_TRUE(last.q_WT.coeffs() == g || last.q_WT.coeffs() == -g) << last.q_WT.coeffs().transpose();
      EXPECT_EQ(first.v_W.norm(), 0.0);
      EXPECT_EQ(first.omega_W.norm(), 0.0);
      EXPECT_EQ(last.v_W.norm(), 0.0);
      EXPECT_EQ(last.a_W.norm(), 0.0);
      EXPECT_EQ(last.omega_W.norm(), 0.0);
      EXPECT_EQ(last.alpha_W.norm(), 0.0);
      EXPECT_EQ(first.u, 0.0);
      EXPECT_EQ(last.u, 1.0);
      EXPECT_EQ(first.s, 0.0);
      EXPECT_EQ(last.s, (spec.goal.p_WT - spec.start.p_WT).stableNorm());
    }
  }
}

TEST(LinearMove, EveryPositionIsOnTheSegment) {
  const LinearMoveSpec spec = line_move();
  const Vector3d p0 = spec.start.p_WT, d = spec.goal.p_WT - p0;
  const double L = d.norm();
  const LinearMovePlan plan = plan_or_fail(spec, timed(1.0, ProfileShape::kSCurve, 1000.0));
  EXPECT_EQ(plan.length, d.stableNorm());
  double s_prev = -1.0;
  for (const MoveSample& s : run(plan)) {
    const Vector3d r = s.p_W - p0;
    const double along = r.dot(d) / L;
    EXPECT_LE((r - along * d / L).norm(), 1e-15) << "off the line at t = " << s.t;  // (6.1)
    EXPECT_GE(along, -1e-15);
    EXPECT_LE(along, L + 1e-15);
    EXPECT_NEAR(along, s.s, 1e-15);
    EXPECT_NEAR(s.u, s.s / L, 1e-15);
    EXPECT_GE(s.s, s_prev);
    s_prev = s.s;
    // The velocity is along the line, in the direction of motion.
    EXPECT_LE((s.v_W - s.speed * d / L).norm(), 1e-15);
  }
}

TEST(LinearMove, OrientationIsUnitContinuousAndTheSlerpOfTheEnds) {
  const LinearMoveSpec spec = line_move();
  const LinearMovePlan plan = plan_or_fail(spec, timed(1.0, ProfileShape::kTrapezoidal, 500.0));
  const Quaterniond q0 = spec.start.q_WT.normalized(), q1 = spec.goal.q_WT.normalized();
  EXPECT_NEAR(plan.theta, q0.angularDistance(q1), 1e-14);
  const auto samples = run(plan);
  const double dt = 1.0 / 500.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const MoveSample& s = samples[k];
    EXPECT_NEAR(s.q_WT.norm(), 1.0, 1e-15);
    // (6.2): the SLERP of q0 and q1 at the progress u (Eigen's slerp takes the shorter way).
    EXPECT_LE(s.q_WT.angularDistance(q0.slerp(s.u, q1)), 1e-14) << "t = " << s.t;
    if (k > 0) {
      EXPECT_GT(s.q_WT.coeffs().dot(samples[k - 1].q_WT.coeffs()), 0.0);
      EXPECT_LE(s.q_WT.angularDistance(samples[k - 1].q_WT), plan.peak_angular_speed * dt * (1 + 1e-9));
    }
  }
}

TEST(LinearMove, RatesMatchCentralDifferences) {
  constexpr double h = 1e-5, tol = 1e-7;
  for (const ProfileShape shape : {ProfileShape::kTrapezoidal, ProfileShape::kSCurve}) {
    for (const MotionSpec& m : {timed(0.9, shape), cartesian_fastest(shape)}) {
      const LinearMovePlan plan = plan_or_fail(line_move(), m);
      const auto at = [&](double t, MoveSample& out) { core::linear_move_at(plan, t, out); };
      for (const double t : interior_times(plan.profile, 4 * h, 5)) check_rates(at, t, h, tol, false);
    }
  }
}

TEST(LinearMove, MinimumTimeReachesTheLimits) {
  LinearMoveSpec spec = line_move();
  spec.goal.p_WT = spec.start.p_WT + Vector3d(1.0, 1.0, 0.5);  // 1.5 m: long enough to cruise
  MotionSpec m = cartesian_fastest();
  const LinearMovePlan plan = plan_or_fail(spec, m);
  EXPECT_NEAR(plan.peak_speed, 0.5, 1e-15);
  EXPECT_NEAR(plan.peak_acceleration, 2.0, 1e-15);
  EXPECT_NEAR(plan.duration_s, 1.5 / 0.5 + 0.5 / 2.0, 1e-12);  // L / v + v / a
  double v = 0.0, a = 0.0;
  for (const MoveSample& s : run(plan)) {
    v = std::max(v, s.speed);
    a = std::max(a, s.a_W.norm());
  }
  EXPECT_LE(v, 0.5 * (1 + 1e-15));
  EXPECT_LE(a, 2.0 * (1 + 1e-15));
  // speedScale: the same motion, slower.
  m.speed_scale = 0.5;
  EXPECT_NEAR(plan_or_fail(spec, m).duration_s, 2 * plan.duration_s, 1e-12);
  // Double S: the jerk too.
  const LinearMovePlan s_plan = plan_or_fail(spec, cartesian_fastest(ProfileShape::kSCurve));
  EXPECT_LE(core::peak_jerk(s_plan.profile), 20.0 * (1 + 1e-15));
  EXPECT_LE(s_plan.peak_speed, 0.5 * (1 + 1e-15));
}

TEST(LinearMove, PureRotationProgressesOverTheAngle) {
  LinearMoveSpec spec = line_move();
  spec.goal.p_WT = spec.start.p_WT;
  const Quaterniond q0 = spec.start.q_WT.normalized();
  spec.goal.q_WT = Quaterniond(Eigen::AngleAxisd(2.5, Vector3d(1, -2, 0.5).normalized())) * q0;
  const LinearMovePlan plan = plan_or_fail(spec, timed(2.0, ProfileShape::kSCurve, 200.0));
  EXPECT_EQ(plan.length, 0.0);
  EXPECT_NEAR(plan.theta, 2.5, 1e-14);
  EXPECT_NEAR(plan.profile.length, 2.5, 1e-14);  // over the angle [rad]
  // v_max = theta / (T (1 - f)) is the peak angular speed.
  EXPECT_NEAR(plan.peak_angular_speed, 2.5 / (2.0 * 0.85), 1e-12);
  const auto samples = run(plan);
  for (const MoveSample& s : samples) {
    EXPECT_EQ(s.p_W, spec.start.p_WT);
    EXPECT_EQ(s.v_W.norm(), 0.0);
    EXPECT_EQ(s.s, 0.0);
    // The angle turned is u theta about the fixed axis.
    EXPECT_NEAR(s.q_WT.angularDistance(q0), s.u * 2.5, 1e-13);
    EXPECT_LE(s.omega_W.cross(plan.axis_W).norm(), 1e-15);
  }
  EXPECT_LE(samples.back().q_WT.angularDistance(spec.goal.q_WT), 1e-15);
  const auto at = [&](double t, MoveSample& out) { core::linear_move_at(plan, t, out); };
  for (const double t : interior_times(plan.profile, 4e-5, 4)) check_rates(at, t, 1e-5, 1e-7, false);
}

TEST(LinearMove, PureRotationNeedsADuration) {
  LinearMoveSpec spec = line_move();
  spec.goal.p_WT = spec.start.p_WT;
  auto plan = core::plan_linear_move(spec, cartesian_fastest());
  ASSERT_FALSE(plan.has_value());
  EXPECT_TRUE(names(plan.error(), "motion.durationS")) << listed(plan.error());
  // Neither translating nor turning: the same, and with a duration a rest.
  spec.goal.q_WT = spec.start.q_WT;
  EXPECT_FALSE(core::plan_linear_move(spec, cartesian_fastest()).has_value());
  const auto samples = run(plan_or_fail(spec, timed(0.5)));
  ASSERT_EQ(samples.size(), 51u);
  for (const MoveSample& s : samples) {
    EXPECT_EQ(s.p_W, spec.start.p_WT);
    EXPECT_EQ(s.omega_W.norm(), 0.0);
  }
}

TEST(LinearMove, TakesTheShorterWayRound) {
  LinearMoveSpec spec = line_move();
  const LinearMovePlan a = plan_or_fail(spec, timed(1.0));
  spec.goal.q_WT.coeffs() = -spec.goal.q_WT.coeffs();  // the same rotation
  const LinearMovePlan b = plan_or_fail(spec, timed(1.0));
  EXPECT_NEAR(a.theta, b.theta, 1e-15);
  EXPECT_LE(a.theta, std::numbers::pi);
  EXPECT_LE((a.axis_W - b.axis_W).norm(), 1e-15);
}

TEST(LinearMove, NearlyUnitQuaternionsAreNormalised) {
  LinearMoveSpec spec = line_move();
  spec.start.q_WT.coeffs() *= 1.0005;
  const auto samples = run(plan_or_fail(spec, timed(1.0)));
  EXPECT_NEAR(samples.front().q_WT.norm(), 1.0, 1e-15);
}

TEST(LinearMove, BadInputNamesEveryField) {
  LinearMoveSpec spec = line_move();
  spec.start.p_WT.y() = kNaN;
  spec.start.q_WT.coeffs() *= 2.0;
  spec.goal.p_WT.x() = 2e6;
  spec.goal.q_WT.coeffs()(0) = std::numeric_limits<double>::infinity();
  MotionSpec m = timed(1.0);
  m.ramp_fraction = 0.7;
  auto plan = core::plan_linear_move(spec, m);
  ASSERT_FALSE(plan.has_value());
  const Violations& v = plan.error();
  for (const char* field : {"linearMove.start.position", "linearMove.start.orientation", "linearMove.goal.position",
                            "linearMove.goal.orientation", "motion.rampFraction"})
    EXPECT_TRUE(names(v, field)) << field << "\n" << listed(v);
  EXPECT_EQ(v.size(), 5u) << listed(v);
}

TEST(LinearMove, MinimumTimeNeedsTheCartesianLimits) {
  auto plan = core::plan_linear_move(line_move(), fastest());
  ASSERT_FALSE(plan.has_value());
  EXPECT_TRUE(names(plan.error(), "motion.durationS")) << listed(plan.error());
  plan = core::plan_linear_move(line_move(), [] {
    MotionSpec m = cartesian_fastest(ProfileShape::kSCurve);
    m.max_jerk.reset();
    return m;
  }());
  ASSERT_FALSE(plan.has_value());
  EXPECT_TRUE(names(plan.error(), "motion.maxJerk")) << listed(plan.error());
}

TEST(LinearMove, AMoveTooShortToRepresentIsRefused) {
  auto plan = core::plan_linear_move(line_move(), timed(1e-300));
  ASSERT_FALSE(plan.has_value());
  EXPECT_TRUE(names(plan.error(), "motion.durationS")) << listed(plan.error());
}

TEST(LinearMove, NoHeapAllocationPerSample) {
  const LinearMovePlan plan = plan_or_fail(line_move(), timed(2.0, ProfileShape::kSCurve, 1000.0));
  ASSERT_GT(plan.sample_count, 0u);
  core::LinearMoveSampler sampler(plan);
  MoveSample s;
  sampler.next(s);
  const long before = geotraj::testing::allocation_count();
  std::size_t n = 1;
  while (sampler.next(s)) ++n;
  EXPECT_EQ(geotraj::testing::allocation_count(), before);
  EXPECT_EQ(n, plan.sample_count);
}

}  // namespace
}  // namespace geotraj::test
