// Jogging (core/live/jog.hpp) on the built-in arms (PA-10, 7 joints; UR5, 6 joints):
//  - every streamed set point within the joints' velocity, acceleration and jerk limits, by
//    finite differences of q at the cycle rate (1 kHz and 100 Hz), for joint and Cartesian
//    jogs and for random command sequences from random starts (a failing case prints its
//    seed and commands);
//  - position limits: a jog into a limit comes to rest on it (to 1e-9) and never passes it,
//    and can move away again; continuous joints have none;
//  - stop() reaches rest within the time the jerk-limited braking profile predicts;
//  - the ramps scale the whole command: a joint jog keeps its command's ratios while it speeds
//    up, slows down and brakes for a position limit; a Cartesian jog's tool steps stay on the
//    commanded line (within 1 degree) at its start, release and approach to a limit;
//  - Cartesian jogs in W and in the tool frame follow the commanded twist; near a stretched
//    elbow the damping is reported and the joint velocities stay bounded;
//  - no heap allocation per cycle; validation names the field, the value and the rule.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "core/live/jog.hpp"
#include "core/live/rate_profile.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::JogCommand;
using core::JogFrame;
using core::JogOptions;
using core::Jogger;
using core::JogSample;
using core::JointVector;
using core::RobotModel;
using core::Vector6d;

const RobotModel& pa10() { return *core::find_builtin_robot("pa10"); }
const RobotModel& ur5() { return *core::find_builtin_robot("ur5"); }

JogOptions options_at(double rate_hz) {
  JogOptions o;
  o.cycle_rate_hz = rate_hz;
  return o;
}

JogCommand joint_command(const JointVector& c) {
  JogCommand cmd;
  cmd.joints = c;
  return cmd;
}

JogCommand twist_command(const Vector6d& c, JogFrame frame) {
  JogCommand cmd;
  cmd.twist = c;
  cmd.frame = frame;
  return cmd;
}

Vector6d twist(double vx, double vy, double vz, double wx, double wy, double wz) {
  Vector6d v;
  v << vx, vy, vz, wx, wy, wz;
  return v;
}

/// One joint of n set to `value`, the others 0.
JointVector one_joint(Eigen::Index n, Eigen::Index joint, double value) {
  JointVector c = JointVector::Zero(n);
  c(joint) = value;
  return c;
}

/// Runs `cycles` cycles, appending the samples to `out` (when given).
void run(Jogger& jog, int cycles, std::vector<JogSample>* out = nullptr) {
  JogSample s;
  for (int k = 0; k < cycles; ++k) {
    jog.next(s);
    if (out) out->push_back(s);
  }
}

int cycles_for(double seconds, const Jogger& jog) { return static_cast<int>(std::lround(seconds / jog.period())); }

/// Every set point of a stream that started at rest at q0 within the limits: the finite
/// differences of q at the cycle rate (velocity, acceleration, jerk: each a weighted mean of
/// the true derivative over the cycles it spans, so bounded by the same limits), the sample's
/// own q_dot and q_ddot, and the position limits. The tolerance is rounding: 2^m 4 eps (|q| + 1)
/// / h^m for the m-th difference (the positions are sums of per-cycle increments).
::testing::AssertionResult WithinLimits(const RobotModel& model, const Jogger& jog, const JointVector& q0,
                                        const std::vector<JogSample>& samples) {
  const double h = jog.period();
  const double eps = std::numeric_limits<double>::epsilon();
  const Eigen::Index n = q0.size();
  // The jog was at rest before its start: q(-2) = q(-1) = q(0) = q0.
  std::vector<JointVector> q = {q0, q0, q0};
  for (const auto& s : samples) q.push_back(s.q);
  for (Eigen::Index j = 0; j < n; ++j) {
    const auto& l = model.limits[static_cast<std::size_t>(j)];
    const double v_max = jog.velocity_bound(static_cast<std::size_t>(j));
    const double a_max = l.max_acceleration, j_max = jog.jerk_bound(static_cast<std::size_t>(j));
    const bool bounded = model.joints[static_cast<std::size_t>(j)].type != core::JointType::kContinuous;
    for (std::size_t k = 3; k < q.size(); ++k) {
      const double scale = 4.0 * eps * (std::abs(q[k](j)) + 1.0);
      const double d1 = (q[k](j) - q[k - 1](j)) / h;
      const double d2 = (q[k](j) - 2.0 * q[k - 1](j) + q[k - 2](j)) / (h * h);
      const double d3 = (q[k](j) - 3.0 * q[k - 1](j) + 3.0 * q[k - 2](j) - q[k - 3](j)) / (h * h * h);
      const auto where = [&] {
        std::ostringstream os;
        os << model.name << " joint " << j << " at t = " << samples[k - 3].t << " s (sample " << k - 3 << ", "
           << 1.0 / h << " Hz)";
        return os.str();
      };
      if (std::abs(d1) > v_max * (1.0 + 1e-12) + 2.0 * scale / h) {
        return ::testing::AssertionFailure() << where() << ": finite-difference velocity " << d1 << " beyond " << v_max;
      }
      if (std::abs(d2) > a_max * (1.0 + 1e-12) + 4.0 * scale / (h * h)) {
        return ::testing::AssertionFailure() << where() << ": finite-difference acceleration " << d2 << " beyond "
                                             << a_max;
      }
      if (std::abs(d3) > j_max * (1.0 + 1e-12) + 8.0 * scale / (h * h * h)) {
        return ::testing::AssertionFailure() << where() << ": finite-difference jerk " << d3 << " beyond " << j_max;
      }
      const JogSample& s = samples[k - 3];
      if (!(std::abs(s.q_dot(j)) <= v_max * (1.0 + 1e-12)) || !(std::abs(s.q_ddot(j)) <= a_max * (1.0 + 1e-12))) {
        return ::testing::AssertionFailure() << where() << ": set point q_dot " << s.q_dot(j) << ", q_ddot "
                                             << s.q_ddot(j) << " beyond " << v_max << ", " << a_max;
      }
      if (bounded && !(q[k](j) >= l.min_position && q[k](j) <= l.max_position)) {
        return ::testing::AssertionFailure() << where() << ": q " << q[k](j) << " outside [" << l.min_position << ", "
                                             << l.max_position << "]";
      }
    }
  }
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------
// Finite-difference limits

class JogLimits : public ::testing::TestWithParam<std::tuple<const char*, double>> {
 protected:
  const RobotModel& model() const { return *core::find_builtin_robot(std::get<0>(GetParam())); }
  double rate() const { return std::get<1>(GetParam()); }
};

TEST_P(JogLimits, JointJogWithinVelocityAccelerationJerk) {
  const RobotModel& m = model();
  const JointVector q0 = core::home_configuration(m);
  const auto n = static_cast<Eigen::Index>(m.dof());
  Jogger jog(m, q0, options_at(rate()));
  std::vector<JogSample> samples;
  JointVector c(n);
  for (Eigen::Index j = 0; j < n; ++j) c(j) = (j % 2 == 0 ? 1.0 : -1.0) * (1.0 - 0.1 * static_cast<double>(j));
  jog.command(joint_command(c));
  run(jog, cycles_for(0.6, jog), &samples);  // up to full speed
  jog.command(joint_command(-c));           // full reversal
  run(jog, cycles_for(0.05, jog), &samples);
  jog.command(joint_command(0.3 * c));      // changed again mid-ramp
  run(jog, cycles_for(0.4, jog), &samples);
  jog.stop();
  run(jog, cycles_for(1.0, jog), &samples);
  EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
  EXPECT_TRUE(samples.back().at_rest);
  for (const auto& s : samples) EXPECT_EQ(s.damping, 0.0);
}

TEST_P(JogLimits, CartesianJogWithinVelocityAccelerationJerk) {
  const RobotModel& m = model();
  const JointVector q0 = core::home_configuration(m);
  Jogger jog(m, q0, options_at(rate()));
  std::vector<JogSample> samples;
  jog.command(twist_command(twist(0.5, -0.3, 0.2, 0.0, 0.0, 0.0), JogFrame::kWorld));
  run(jog, cycles_for(0.5, jog), &samples);
  jog.command(twist_command(twist(0.0, 0.0, 0.0, 0.4, -0.5, 0.8), JogFrame::kTool));
  run(jog, cycles_for(0.5, jog), &samples);
  jog.command(twist_command(twist(-1.0, 0.0, -1.0, 0.0, 0.0, 0.0), JogFrame::kTool));
  run(jog, cycles_for(0.3, jog), &samples);
  jog.stop();
  run(jog, cycles_for(1.0, jog), &samples);
  EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
  EXPECT_TRUE(samples.back().at_rest);
}

// Random starts within the limits and random sequences of joint, world, tool and stop
// commands of random lengths (1 cycle to 0.5 s): the limits hold throughout, position
// limits included. Cases: GEOTRAJ_PROPERTY_CASES (default 20 per model and rate).
TEST_P(JogLimits, RandomCommandSequences) {
  const RobotModel& m = model();
  const auto n = static_cast<Eigen::Index>(m.dof());
  const int cases = property_case_count(20);
  for (int c = 0; c < cases; ++c) {
    const auto seed = static_cast<std::uint32_t>(kPropertySeed + static_cast<std::uint64_t>(c));
    std::mt19937 random(seed);
    std::uniform_real_distribution<double> unit(-1.0, 1.0), fraction(0.0, 1.0);
    JointVector q0(n);
    for (Eigen::Index j = 0; j < n; ++j) {
      const auto& l = m.limits[static_cast<std::size_t>(j)];
      // Half the starts near a limit (within 0.1 rad of it), to drive joints into it.
      const double u = fraction(random);
      q0(j) = c % 2 == 0 ? l.min_position + u * (l.max_position - l.min_position)
                         : (u < 0.5 ? l.min_position + 0.2 * u : l.max_position - 0.2 * (1.0 - u));
    }
    Jogger jog(m, q0, options_at(rate()));
    std::vector<JogSample> samples;
    std::ostringstream log;
    log << "seed " << seed << " (case " << c << "), " << m.name << " at " << rate() << " Hz, q0 = ["
        << q0.transpose() << "]\n";
    for (int segment = 0; segment < 25; ++segment) {
      const int kind = static_cast<int>(fraction(random) * 4.0);
      const int cycles = 1 + static_cast<int>(fraction(random) * (0.5 * rate()));
      log << "  " << cycles << " cycles: ";
      if (kind == 0) {
        JointVector cmd(n);
        for (Eigen::Index j = 0; j < n; ++j) cmd(j) = unit(random);
        jog.command(joint_command(cmd));
        log << "joints [" << cmd.transpose() << "]\n";
      } else if (kind == 1 || kind == 2) {
        Vector6d t;
        for (int i = 0; i < 6; ++i) t(i) = unit(random);
        jog.command(twist_command(t, kind == 1 ? JogFrame::kWorld : JogFrame::kTool));
        log << (kind == 1 ? "world" : "tool") << " twist [" << t.transpose() << "]\n";
      } else {
        jog.stop();
        log << "stop\n";
      }
      run(jog, cycles, &samples);
    }
    ASSERT_TRUE(WithinLimits(m, jog, q0, samples)) << log.str();
    for (const auto& s : samples) {
      ASSERT_TRUE(s.q.allFinite() && s.q_dot.allFinite() && s.twist_W.allFinite()) << log.str();
    }
  }
}

INSTANTIATE_TEST_SUITE_P(BuiltinArms, JogLimits,
                         ::testing::Combine(::testing::Values("pa10", "ur5"), ::testing::Values(1000.0, 100.0)),
                         [](const auto& param_info) {
                           return std::string(std::get<0>(param_info.param)) + "_" +
                                  std::to_string(static_cast<int>(std::get<1>(param_info.param))) + "Hz";
                         });

// ---------------------------------------------------------------------------------------
// Joint jogging

// Regression: a velocityScale of 5e-324 made every joint's jog speed 0, and an
// acceleration of 1e308 an infinite jerk bound (over jerkRampS): the jogger's check aborted the
// server. validate_jog_limits names them first; at the ends of the limits' range it jogs.
TEST(Jog, DerivedBoundsAreValidatedAndTheRangesEndsJog) {
  const RobotModel& pa10 = *core::find_builtin_robot("pa10");
  JogOptions options;
  options.velocity_scale = 5e-324;
  ASSERT_TRUE(core::validate_jog_options(options, "start").empty());  // a fraction in (0, 1]
  auto v = core::validate_jog_limits(pa10, options, "start");
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0].field, "start.velocityScale");
  EXPECT_NE(v[0].description.find("joint 0 (S1)"), std::string::npos) << v[0].description;
  options = JogOptions{};
  options.jerk_ramp_s = 1e-300;
  v = core::validate_jog_limits(pa10, options, "");
  ASSERT_EQ(v.size(), 1u);
  EXPECT_EQ(v[0].field, "jerkRampS");
  // Every limit at an end of [kMinJointLimit, kMaxJointLimit]: a jog of every joint and its
  // stop run, every set point finite.
  for (const double end : {core::kMinJointLimit, core::kMaxJointLimit}) {
    RobotModel m = pa10;
    for (auto& l : m.limits) l.max_velocity = l.max_acceleration = end, l.max_jerk = end;
    ASSERT_TRUE(core::validate_robot(m).empty());
    JogOptions o;
    o.cycle_rate_hz = 1000.0;
    ASSERT_TRUE(core::validate_jog_limits(m, o, "").empty());
    Jogger jogger(m, core::home_configuration(m), o);
    JogCommand c;
    c.joints = JointVector::Ones(7);
    jogger.command(c);
    JogSample s;
    for (int k = 0; k < 200; ++k) {
      if (k == 100) jogger.stop();
      jogger.next(s);
      ASSERT_TRUE(s.q.allFinite() && s.q_dot.allFinite() && s.q_ddot.allFinite()) << end << " cycle " << k;
    }
  }
}

TEST(Jog, JointTargetIsCommandTimesScaledMaxVelocity) {
  const RobotModel& m = pa10();
  JogOptions o = options_at(100.0);
  o.velocity_scale = 0.5;
  Jogger jog(m, core::home_configuration(m), o);
  JointVector c = JointVector::Zero(7);
  c(1) = 0.8;
  c(5) = -0.25;
  jog.command(joint_command(c));
  std::vector<JogSample> samples;
  run(jog, 100, &samples);
  const JogSample& s = samples.back();
  for (Eigen::Index j = 0; j < 7; ++j) {
    EXPECT_EQ(s.q_dot(j), c(j) * m.limits[static_cast<std::size_t>(j)].max_velocity * 0.5) << "joint " << j;
    EXPECT_EQ(s.q_ddot(j), 0.0);
  }
  EXPECT_EQ(s.damping, 0.0);
  EXPECT_FALSE(s.at_rest);
  EXPECT_NEAR(s.t, 1.0, 1e-12);
}

TEST(Jog, StartsAtRestAndStaysThereWithoutCommand) {
  const RobotModel& m = pa10();
  const JointVector q0 = core::home_configuration(m);
  Jogger jog(m, q0, {});
  EXPECT_TRUE(jog.at_rest());
  JogSample s;
  jog.next(s);
  EXPECT_TRUE(s.at_rest);
  EXPECT_EQ(s.q, q0);
  EXPECT_TRUE(s.X_WT.isApprox(core::forward_kinematics(m, q0), 1e-14));
  EXPECT_TRUE(s.twist_W.isZero(0.0));
  EXPECT_GT(s.sigma_min, 0.0);
}

// A joint jogged into its upper limit comes to rest on it, never past it; it is reported as
// limited, stays there while the command pushes on, and moves away when told to.
class JogIntoLimit : public ::testing::TestWithParam<double> {};

TEST_P(JogIntoLimit, StopsExactlyAtTheLimitAndMovesAwayAfterwards) {
  const RobotModel& m = pa10();
  const Eigen::Index joint = 2;
  const auto& l = m.limits[joint];
  for (const double direction : {1.0, -1.0}) {
    SCOPED_TRACE(direction > 0 ? "toward max" : "toward min");
    const double limit = direction > 0 ? l.max_position : l.min_position;
    JointVector q0 = core::home_configuration(m);
    q0(joint) = limit - direction * 1.5;  // 1.5 rad from the limit: full speed is reached first
    Jogger jog(m, q0, options_at(GetParam()));
    jog.command(joint_command(one_joint(7, joint, direction)));
    std::vector<JogSample> samples;
    run(jog, cycles_for(3.0, jog), &samples);
    ASSERT_TRUE(WithinLimits(m, jog, q0, samples));
    const JogSample& rest = samples.back();
    EXPECT_TRUE(rest.at_rest);
    EXPECT_NEAR(rest.q(joint), limit, 1e-9);
    EXPECT_TRUE(rest.limited[joint]);
    for (Eigen::Index j = 0; j < 7; ++j) {
      if (j != joint) {
        EXPECT_FALSE(rest.limited[static_cast<std::size_t>(j)]);
      }
    }
    // It reached full speed before braking (so the braking was the limit's, not the ramp's).
    double peak = 0.0;
    for (const auto& s : samples) peak = std::max(peak, std::abs(s.q_dot(joint)));
    EXPECT_NEAR(peak, l.max_velocity, 1e-12);

    // Moving away: allowed, and the limited flag clears.
    jog.command(joint_command(one_joint(7, joint, -0.5 * direction)));
    std::vector<JogSample> away;
    run(jog, cycles_for(0.5, jog), &away);
    EXPECT_GT(direction * (limit - away.back().q(joint)), 0.01);
    EXPECT_FALSE(away.back().limited[joint]);
    samples.insert(samples.end(), away.begin(), away.end());
    EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
  }
}

INSTANTIATE_TEST_SUITE_P(Rates, JogIntoLimit, ::testing::Values(1000.0, 100.0, 250.0), [](const auto& param_info) {
  return std::to_string(static_cast<int>(param_info.param)) + "Hz";
});

// A joint with its own max_jerk uses it (not the ramp bound), and still stops on the limit.
TEST(Jog, OwnMaxJerkIsUsed) {
  RobotModel m = pa10();
  m.limits[0].max_jerk = 5.0;
  JointVector q0 = core::home_configuration(m);
  q0(0) = m.limits[0].max_position - 0.3;
  Jogger jog(m, q0, options_at(500.0));
  EXPECT_EQ(jog.jerk_bound(0), 5.0);
  EXPECT_EQ(jog.jerk_bound(1), m.limits[1].max_acceleration / JogOptions{}.jerk_ramp_s);
  jog.command(joint_command(one_joint(7, 0, 1.0)));
  std::vector<JogSample> samples;
  run(jog, cycles_for(4.0, jog), &samples);
  EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
  EXPECT_TRUE(samples.back().at_rest);
  EXPECT_NEAR(samples.back().q(0), m.limits[0].max_position, 1e-9);
}

// A joint that starts on its limit and is pushed into it does not move.
TEST(Jog, HeldOnALimitItStartsOn) {
  const RobotModel& m = ur5();
  JointVector q0 = core::home_configuration(m);
  q0(4) = m.limits[4].min_position;
  Jogger jog(m, q0, options_at(1000.0));
  jog.command(joint_command(one_joint(6, 4, -1.0)));
  std::vector<JogSample> samples;
  run(jog, 200, &samples);
  for (const auto& s : samples) {
    ASSERT_EQ(s.q(4), m.limits[4].min_position);
    ASSERT_TRUE(s.limited[4]);
    ASSERT_TRUE(s.at_rest);
  }
}

// A continuous joint has no position limits: it jogs past the (unread) limit values.
TEST(Jog, ContinuousJointHasNoLimit) {
  RobotModel m = ur5();
  m.joints[5].type = core::JointType::kContinuous;
  JointVector q0 = core::home_configuration(m);
  q0(5) = m.limits[5].max_position - 0.1;
  Jogger jog(m, q0, options_at(100.0));
  jog.command(joint_command(one_joint(6, 5, 1.0)));
  std::vector<JogSample> samples;
  run(jog, 100, &samples);
  EXPECT_GT(samples.back().q(5), m.limits[5].max_position + 1.0);
  EXPECT_FALSE(samples.back().limited[5]);
  EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
}

// ---------------------------------------------------------------------------------------
// Stopping

// From full speed (and from mid-ramp, where the acceleration is not zero), stop() reaches
// rest within the predicted time (the whole command's braking ramp), rounded up to the
// cycle grid (a Cartesian jog's to 2 %).
TEST(Jog, StopReachesRestWithinThePredictedTime) {
  for (const double rate : {1000.0, 100.0}) {
    for (const double run_s : {1.0, 0.07}) {
      for (const bool cartesian : {false, true}) {
        SCOPED_TRACE(std::to_string(rate) + " Hz, stop after " + std::to_string(run_s) + " s" +
                     (cartesian ? ", Cartesian" : ", joints"));
        const RobotModel& m = pa10();
        Jogger jog(m, core::home_configuration(m), options_at(rate));
        if (cartesian) {
          jog.command(twist_command(twist(0.0, 0.6, -0.4, 0.0, 0.3, 0.0), JogFrame::kWorld));
        } else {
          jog.command(joint_command((JointVector(7) << 1, -1, 1, -1, 0.5, -0.5, 1).finished()));
        }
        run(jog, cycles_for(run_s, jog));
        ASSERT_FALSE(jog.at_rest());
        const double predicted = jog.stopping_time();
        // Each joint's own braking profile, from the state at the stop: the whole command
        // slows together, so as slowly as its slowest joint or more slowly (the Cartesian
        // ramp uses 0.8 of the limits). In the joint jog one joint bounds both the ramp's
        // acceleration and its jerk (every jerk bound is a_max / jerkRampS): its own time.
        double longest = 0.0;
        for (Eigen::Index j = 0; j < 7; ++j) {
          longest = std::max(longest, core::RateProfile::plan(jog.q_dot()(j), jog.q_ddot()(j), 0.0,
                                                               m.limits[static_cast<std::size_t>(j)].max_acceleration,
                                                               jog.jerk_bound(static_cast<std::size_t>(j)))
                                          .duration());
        }
        if (cartesian) {
          EXPECT_GT(predicted, longest);
        } else {
          EXPECT_EQ(predicted, longest);
        }
        jog.stop();
        JogSample s;
        int cycles = 0;
        while (!jog.at_rest() && cycles < 100000) {
          jog.next(s);
          ++cycles;
        }
        EXPECT_TRUE(s.at_rest);
        if (cartesian) {
          // The ramp's limits follow D and its drift as the arm moves: an estimate (to 1 %).
          EXPECT_NEAR(cycles * jog.period(), predicted, 0.02 * predicted + jog.period());
        } else {
          EXPECT_LE(cycles * jog.period(), predicted + jog.period() * (1.0 + 1e-9));
          // And not much sooner: the ramp is time-optimal within its limits.
          EXPECT_GE(cycles * jog.period(), predicted - 1e-9);
        }
        // At rest it stays.
        jog.next(s);
        EXPECT_TRUE(s.at_rest);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------
// Cartesian jogging

// A pure +x twist in W at 0.5: after the ramp the tool moves at (0.125, 0, 0) m/s without
// turning, to 1e-3 of the commanded speed.
TEST(Jog, CartesianWorldTwistIsFollowed) {
  for (const char* name : {"pa10", "ur5"}) {
    for (const double rate : {1000.0, 100.0}) {
      SCOPED_TRACE(std::string(name) + " at " + std::to_string(rate) + " Hz");
      const RobotModel& m = *core::find_builtin_robot(name);
      Jogger jog(m, core::home_configuration(m), options_at(rate));
      jog.command(twist_command(twist(0.5, 0, 0, 0, 0, 0), JogFrame::kWorld));
      std::vector<JogSample> samples;
      run(jog, cycles_for(1.0, jog), &samples);
      const Vector6d expected = twist(0.125, 0, 0, 0, 0, 0);
      for (std::size_t k = samples.size() / 2; k < samples.size(); ++k) {
        const auto& s = samples[k];
        ASSERT_LE((s.twist_W - expected).norm(), 1e-3 * 0.125) << "t = " << s.t << " s: " << s.twist_W.transpose();
        ASSERT_EQ(s.damping, 0.0);
      }
      // After the ramp the tool moves along +x: 0.125 m/s for half the run.
      const std::size_t mid = samples.size() / 2;
      const Eigen::Vector3d d = samples.back().X_WT.translation() - samples[mid].X_WT.translation();
      // The samples' twists are exact to O(h^2) (jog.hpp); between them the joint velocities
      // are nearly constant while J changes, so the path between samples is off by O(h).
      EXPECT_NEAR(d.x(), 0.125 * (samples.back().t - samples[mid].t), 1e-3 * d.x());
      EXPECT_LT(d.tail<2>().norm(), 1e-3 * d.x());
      EXPECT_LT(Eigen::AngleAxisd(samples[mid].X_WT.linear().transpose() * samples.back().X_WT.linear()).angle(), 1e-4);
    }
  }
}

// A +x twist in the tool frame moves the tool along its own x axis (here not W's); a turn
// about the tool's z axis turns it about that axis with its origin in place.
TEST(Jog, CartesianToolFrameTwistIsFollowed) {
  const RobotModel& m = pa10();
  const JointVector q0 = core::home_configuration(m);
  const Eigen::Isometry3d X0 = core::forward_kinematics(m, q0);
  const Eigen::Vector3d x_T0 = X0.linear().col(0);
  ASSERT_LT(std::abs(x_T0.dot(Eigen::Vector3d::UnitX())), 0.9);  // a test that W's x would fail

  {
    Jogger jog(m, q0, options_at(1000.0));
    jog.command(twist_command(twist(0.5, 0, 0, 0, 0, 0), JogFrame::kTool));
    std::vector<JogSample> samples;
    run(jog, 1000, &samples);
    for (std::size_t k = 500; k < samples.size(); ++k) {
      const auto& s = samples[k];
      Vector6d expected = Vector6d::Zero();
      expected.head<3>() = s.X_WT.linear().col(0) * 0.125;
      ASSERT_LE((s.twist_W - expected).norm(), 1e-3 * 0.125) << "t = " << s.t << " s";
    }
    // After the ramp: along the tool's x axis, which stays where it started (no turning).
    const Eigen::Vector3d d = samples.back().X_WT.translation() - samples[500].X_WT.translation();
    EXPECT_GT(d.norm(), 0.05);
    EXPECT_GT(d.normalized().dot(samples[500].X_WT.linear().col(0)), 1.0 - 1e-8);
    EXPECT_GT(d.normalized().dot(x_T0), 1.0 - 1e-4);  // the ramp turned it a little
  }
  {
    Jogger jog(m, q0, options_at(1000.0));
    jog.command(twist_command(twist(0, 0, 0, 0, 0, 1.0), JogFrame::kTool));
    std::vector<JogSample> samples;
    run(jog, 1000, &samples);
    for (std::size_t k = 500; k < samples.size(); ++k) {
      const auto& s = samples[k];
      Vector6d expected = Vector6d::Zero();
      expected.tail<3>() = s.X_WT.linear().col(2) * 0.5;
      ASSERT_LE((s.twist_W - expected).norm(), 1e-3 * 0.5) << "t = " << s.t << " s";
    }
    // After the ramp: turning about z_T (which stays put) with the origin in place.
    const Eigen::Isometry3d& Xm = samples[500].X_WT;
    const Eigen::Isometry3d& X1 = samples.back().X_WT;
    EXPECT_LT((X1.translation() - Xm.translation()).norm(), 1e-6);
    EXPECT_GT(X1.linear().col(2).dot(Xm.linear().col(2)), 1.0 - 1e-8);
    EXPECT_NEAR(Eigen::AngleAxisd(Xm.linear().transpose() * X1.linear()).angle(), 0.5 * (samples.back().t - samples[500].t), 1e-5);
    EXPECT_LT((X1.translation() - X0.translation()).norm(), 1e-3);  // the ramp moved it a little
  }
}

// A twist beyond what the joints can do is slowed down as a whole: the direction is kept,
// the fastest joint at its bound.
TEST(Jog, CartesianTargetScaledDownUniformly) {
  const RobotModel& m = pa10();
  JogOptions o = options_at(1000.0);
  o.max_linear_speed = 5.0;
  Jogger jog(m, core::home_configuration(m), o);
  const Vector6d command = twist(0.0, 1.0, 0.0, 0.0, 0.0, 0.0);  // a direction with no joint limit in 1.5 s
  jog.command(twist_command(command, JogFrame::kWorld));
  std::vector<JogSample> samples;
  run(jog, 1500, &samples);
  const JogSample& s = samples.back();
  double worst = 0.0;
  for (Eigen::Index j = 0; j < 7; ++j) worst = std::max(worst, std::abs(s.q_dot(j)) / jog.velocity_bound(static_cast<std::size_t>(j)));
  EXPECT_NEAR(worst, 1.0, 1e-6);
  EXPECT_LT(s.twist_W.head<3>().norm(), 5.0 * 0.99);  // slower than asked
  EXPECT_GT(s.twist_W.head<3>().norm(), 0.1);
  EXPECT_GT(s.twist_W.head<3>().normalized().dot(command.head<3>().normalized()), 1.0 - 1e-3);
  // The scale changes as the arm moves, and a joint whose target keeps changing at a rate c
  // follows it with a lag of c^2 / (2 j_max) in velocity (c ~ 0.6 rad/s^2 here): about 1e-2.
  EXPECT_LT(s.twist_W.tail<3>().norm(), 2e-2 * s.twist_W.head<3>().norm());
  EXPECT_TRUE(WithinLimits(m, jog, core::home_configuration(m), samples));
  for (const auto& x : samples) ASSERT_TRUE(x.limited.none()) << "t = " << x.t << " s";  // no limit interfered
}

// A configuration of the PA-10 away from home: arm turned, elbow and wrist bent, nothing
// near a singularity or a limit within the jogs below.
JointVector pa10_away_from_home() { return (JointVector(7) << 0.5, -0.3, 0.6, 1.2, -0.5, 0.9, -2.4).finished(); }

/// The largest angle [deg] between a step of the tool's origin (from the previous set point;
/// the first from X0) and the commanded direction: `axis` in W, or for the tool frame the
/// previous pose's `axis` of the tool. Steps below 1e-9 m are too short to tell a direction.
double max_angle_off_line(const Eigen::Isometry3d& X0, const std::vector<JogSample>& samples,
                          const Eigen::Vector3d& axis, JogFrame frame) {
  double worst = 0.0;
  Eigen::Isometry3d previous = X0;
  for (const auto& s : samples) {
    const Eigen::Vector3d step = s.X_WT.translation() - previous.translation();
    const Eigen::Vector3d line = frame == JogFrame::kTool ? Eigen::Vector3d(previous.linear() * axis) : axis;
    if (step.norm() > 1e-9) {
      const double angle = std::atan2(step.cross(line).norm(), step.dot(line)) * 180.0 / std::numbers::pi;
      worst = std::max(worst, angle);
    }
    previous = s.X_WT;
  }
  return worst;
}

// Regression (a Cartesian jog left its line when it slowed: the joints decelerated each on
// its own, and the tool's steps turned up to 20 degrees off the commanded axis at the
// release): a linear jog along each axis of W and of the tool frame, from a configuration
// away from home, speeds up, cruises and is released (stop() or a zero twist); every step of
// the tool stays within 1 degree of the commanded direction (the ramps scale the whole
// twist), and every joint within its limits.
TEST(Jog, CartesianJogKeepsItsLineWhileRampingAndReleased) {
  const RobotModel& m = pa10();
  const JointVector q0 = pa10_away_from_home();
  const Eigen::Isometry3d X0 = core::forward_kinematics(m, q0);
  for (const double rate : {1000.0, 100.0}) {
    for (const JogFrame frame : {JogFrame::kTool, JogFrame::kWorld}) {
      for (int axis = 0; axis < 3; ++axis) {
        for (const bool zero_twist : {false, true}) {
          std::ostringstream where;
          where << rate << " Hz, " << (frame == JogFrame::kTool ? "tool" : "world") << " axis " << axis
                << (zero_twist ? ", released by a zero twist" : ", released by stop()");
          SCOPED_TRACE(where.str());
          Jogger jog(m, q0, options_at(rate));
          Vector6d c = Vector6d::Zero();
          c(axis) = 0.5;  // 0.125 m/s
          jog.command(twist_command(c, frame));
          std::vector<JogSample> samples;
          run(jog, cycles_for(0.4, jog), &samples);  // speed-up and cruise
          if (zero_twist) {
            jog.command(twist_command(Vector6d::Zero(), frame));
          } else {
            jog.stop();
          }
          run(jog, cycles_for(0.6, jog), &samples);  // slow-down
          ASSERT_TRUE(samples.back().at_rest);
          EXPECT_GT((samples.back().X_WT.translation() - X0.translation()).norm(), 0.03);  // it went somewhere
          EXPECT_LT(max_angle_off_line(X0, samples, Eigen::Vector3d::Unit(axis), frame), 1.0);
          EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
        }
      }
    }
  }
}

/// max_j f_j - min_j f_j of f_j = q_dot_j / (c_j v_max_j) over the commanded joints (the
/// fraction of its command each has reached), and the largest |q_dot_j| of the others.
std::pair<double, double> fraction_spread(const Jogger& jog, const JointVector& c, const JointVector& q_dot) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, others = 0.0;
  for (Eigen::Index j = 0; j < c.size(); ++j) {
    if (c(j) == 0.0) {
      others = std::max(others, std::abs(q_dot(j)));
      continue;
    }
    const double f = q_dot(j) / (c(j) * jog.velocity_bound(static_cast<std::size_t>(j)));
    lo = std::min(lo, f);
    hi = std::max(hi, f);
  }
  return {hi - lo, others};
}

// A joint jog of several joints speeds up, slows down to a smaller command and stops with
// every joint at the same fraction of its command (the ratios of the joints' velocities are
// the command's throughout): the ramps scale the whole joint command.
TEST(Jog, JointJogKeepsTheCommandsRatiosWhileRamping) {
  const RobotModel& m = pa10();
  const JointVector q0 = core::home_configuration(m);
  const JointVector c = (JointVector(7) << 0.8, -0.5, 0.3, 0.0, 0.6, -1.0, 0.2).finished();
  for (const double rate : {1000.0, 100.0}) {
    SCOPED_TRACE(std::to_string(rate) + " Hz");
    Jogger jog(m, q0, options_at(rate));
    jog.command(joint_command(c));
    std::vector<JogSample> samples;
    run(jog, cycles_for(0.5, jog), &samples);
    jog.command(joint_command(0.4 * c));  // the same direction, slower: along the same line
    run(jog, cycles_for(0.4, jog), &samples);
    jog.command(joint_command(JointVector::Zero(7)));  // released
    run(jog, cycles_for(0.1, jog), &samples);
    jog.command(joint_command(c));  // pressed again mid-stop
    run(jog, cycles_for(0.3, jog), &samples);
    jog.stop();
    run(jog, cycles_for(0.6, jog), &samples);
    ASSERT_TRUE(samples.back().at_rest);
    for (const auto& s : samples) {
      const auto [spread, others] = fraction_spread(jog, c, s.q_dot);
      ASSERT_LE(spread, 1e-9) << "t = " << s.t << " s: q_dot = " << s.q_dot.transpose();
      ASSERT_EQ(others, 0.0) << "t = " << s.t << " s";
    }
    EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
  }
}

// Approaching a position limit slows the whole joint command: a jog of three joints, one of
// them (joint 2) 0.6 rad from its upper limit, brakes all three together (the command's
// ratios kept) so that joint 2 comes to rest on its limit as the others come to rest; the
// command pushing on holds them there.
TEST(Jog, JointLimitSlowsTheWholeCommand) {
  const RobotModel& m = pa10();
  for (const double rate : {1000.0, 100.0}) {
    SCOPED_TRACE(std::to_string(rate) + " Hz");
    JointVector q0 = core::home_configuration(m);
    q0(2) = m.limits[2].max_position - 0.6;
    const JointVector c = (JointVector(7) << 0.5, 0.0, 1.0, 0.0, -0.4, 0.0, 0.0).finished();
    Jogger jog(m, q0, options_at(rate));
    jog.command(joint_command(c));
    std::vector<JogSample> samples;
    run(jog, cycles_for(2.0, jog), &samples);
    const JogSample& rest = samples.back();
    ASSERT_TRUE(rest.at_rest);
    EXPECT_NEAR(rest.q(2), m.limits[2].max_position, 1e-9);
    EXPECT_TRUE(rest.limited[2]);
    for (const auto& s : samples) {
      const auto [spread, others] = fraction_spread(jog, c, s.q_dot);
      ASSERT_LE(spread, 1e-9) << "t = " << s.t << " s: q_dot = " << s.q_dot.transpose();
      ASSERT_EQ(others, 0.0) << "t = " << s.t << " s";
    }
    // Every joint moved as far as the command's ratios say joint 2 did.
    for (const Eigen::Index j : {0, 4}) {
      EXPECT_NEAR((rest.q(j) - q0(j)) / (c(j) * jog.velocity_bound(static_cast<std::size_t>(j))),
                  0.6 / jog.velocity_bound(2), 1e-9);
    }
    EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
  }
}

// Approaching a position limit slows the whole twist: a jog down along W's z from the
// configuration away from home bends the elbow (joint 3) to its upper limit. The tool stays
// on its line while every joint slows together and comes to rest, joint 3 at the limit (short
// of it by the 2 % margin on its braking travel: 1.4e-4 rad here) and held there while the
// command pushes on.
TEST(Jog, CartesianJogKeepsItsLineIntoAJointLimit) {
  const RobotModel& m = pa10();
  const JointVector q0 = pa10_away_from_home();
  const Eigen::Isometry3d X0 = core::forward_kinematics(m, q0);
  for (const double rate : {1000.0, 100.0}) {
    SCOPED_TRACE(std::to_string(rate) + " Hz");
    Jogger jog(m, q0, options_at(rate));
    jog.command(twist_command(twist(0, 0, -0.5, 0, 0, 0), JogFrame::kWorld));
    std::vector<JogSample> samples;
    run(jog, cycles_for(5.0, jog), &samples);
    const JogSample& rest = samples.back();
    ASSERT_TRUE(rest.at_rest);
    EXPECT_TRUE(rest.limited[3]);
    EXPECT_EQ(rest.limited.count(), 1u);
    EXPECT_LT(m.limits[3].max_position - rest.q(3), 1e-3);
    EXPECT_GE(m.limits[3].max_position - rest.q(3), 0.0);
    EXPECT_LT(max_angle_off_line(X0, samples, -Eigen::Vector3d::UnitZ(), JogFrame::kWorld), 1.0);
    EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
    // Held: the command pushing on moves nothing.
    JogSample s;
    jog.next(s);
    EXPECT_TRUE(s.at_rest);
    EXPECT_EQ(s.q, rest.q);
  }
}

// Near a stretched elbow (PA-10 joint 3 at 0.01 rad; UR5 joint 2) the Jacobian is nearly
// singular: the damping is on and reported, the joint velocities bounded and finite, also
// for the twist that asks to stretch further.
TEST(Jog, SingularityIsDamped) {
  struct Case {
    const char* robot;
    Eigen::Index elbow;
  };
  for (const Case c : {Case{"pa10", 3}, Case{"ur5", 2}}) {
    SCOPED_TRACE(c.robot);
    const RobotModel& m = *core::find_builtin_robot(c.robot);
    JointVector q0 = core::home_configuration(m);
    q0(c.elbow) = 0.01;
    const JogOptions o = options_at(1000.0);
    Jogger jog(m, q0, o);
    JogSample s;
    jog.next(s);
    ASSERT_LT(s.sigma_min, o.singular_threshold);
    // Away from the shoulder, along the stretched arm: the singular direction.
    const Eigen::Vector3d outward = (s.X_WT.translation() - core::joint_axes(m, q0)[1].origin).normalized();
    jog.command(twist_command((Vector6d() << outward, 0, 0, 0).finished(), JogFrame::kWorld));
    std::vector<JogSample> samples;
    run(jog, 500, &samples);
    bool damped = false;
    for (const auto& x : samples) {
      ASSERT_TRUE(x.q_dot.allFinite() && std::isfinite(x.damping));
      EXPECT_GE(x.damping, 0.0);
      EXPECT_LE(x.damping, o.damping);
      if (x.sigma_min < o.singular_threshold) damped = damped || x.damping > 0.0;
    }
    EXPECT_TRUE(damped);
    EXPECT_GT(samples.front().damping, 0.0);
    // The damping follows Chiaverini's rule from the previous sample's sigma_min.
    for (std::size_t k = 1; k < samples.size(); ++k) {
      const double ratio = std::min(1.0, samples[k - 1].sigma_min / o.singular_threshold);
      EXPECT_NEAR(samples[k].damping, o.damping * std::sqrt(1.0 - ratio * ratio), 1e-12);
    }
    EXPECT_TRUE(WithinLimits(m, jog, q0, [&] {
      std::vector<JogSample> all = {s};
      all.insert(all.end(), samples.begin(), samples.end());
      return all;
    }()));
  }
}

// Exactly singular (PA-10 all zeros: straight up): full damping, finite velocities.
TEST(Jog, ExactSingularityGivesFullDamping) {
  const RobotModel& m = pa10();
  const JointVector q0 = JointVector::Zero(7);
  Jogger jog(m, q0, options_at(100.0));
  jog.command(twist_command(twist(0, 0, 1, 0, 0, 0), JogFrame::kWorld));
  JogSample s;
  jog.next(s);
  EXPECT_NEAR(s.damping, JogOptions{}.damping, 1e-9);
  std::vector<JogSample> samples;
  run(jog, 200, &samples);
  for (const auto& x : samples) ASSERT_TRUE(x.q.allFinite() && x.q_dot.allFinite());
  samples.insert(samples.begin(), s);
  EXPECT_TRUE(WithinLimits(m, jog, q0, samples));
}

// ---------------------------------------------------------------------------------------
// No heap allocation per cycle

TEST(Jog, NoAllocationPerCycle) {
  const RobotModel& m = pa10();
  Jogger jog(m, core::home_configuration(m), options_at(1000.0));
  JogSample s;
  jog.next(s);  // the sample's vectors are fixed-capacity: nothing to grow
  JogCommand joints = joint_command((JointVector(7) << 1, -1, 0.5, 0, 0, 0.2, -0.3).finished());
  JogCommand tool = twist_command(twist(0.1, 0.2, 0.3, 0.1, 0.2, 0.3), JogFrame::kTool);
  const long before = testing::allocation_count();
  jog.command(joints);
  for (int k = 0; k < 500; ++k) jog.next(s);
  jog.command(tool);
  for (int k = 0; k < 500; ++k) jog.next(s);
  jog.stop();
  for (int k = 0; k < 500; ++k) jog.next(s);
  EXPECT_EQ(testing::allocation_count() - before, 0);
}

// ---------------------------------------------------------------------------------------
// Validation

bool names(const core::Violations& v, const std::string& field, const std::string& part = "") {
  return std::any_of(v.begin(), v.end(), [&](const auto& x) {
    return x.field == field && x.description.find(part) != std::string::npos;
  });
}

std::string listed(const core::Violations& v) {
  std::string out;
  for (const auto& x : v) out += "  " + x.field + ": " + x.description + "\n";
  return out;
}

TEST(JogValidation, CommandNamesTheField) {
  JogCommand good = joint_command(JointVector::Constant(7, 0.5));
  EXPECT_TRUE(core::validate_jog_command(good, 7, "jog").empty());
  EXPECT_TRUE(core::validate_jog_command(JogCommand{}, 7, "jog").empty());  // neither: stand still
  EXPECT_TRUE(core::validate_jog_command(twist_command(twist(1, -1, 0, 0.5, 0, -0.5), JogFrame::kTool), 7, "jog").empty());

  JogCommand bad = good;
  bad.joints(2) = 1.5;
  bad.joints(4) = std::numeric_limits<double>::quiet_NaN();
  auto v = core::validate_jog_command(bad, 7, "jog");
  EXPECT_TRUE(names(v, "jog.joints[2]", "got 1.5")) << listed(v);
  EXPECT_TRUE(names(v, "jog.joints[2]", "[-1, 1]")) << listed(v);
  EXPECT_TRUE(names(v, "jog.joints[4]", "NaN")) << listed(v);
  EXPECT_EQ(v.size(), 2u) << listed(v);

  v = core::validate_jog_command(joint_command(JointVector::Zero(6)), 7, "jog");
  EXPECT_TRUE(names(v, "jog.joints", "6 values for a robot of 7 joints")) << listed(v);

  JogCommand t = twist_command(twist(0, 0, -1.01, 0, std::numeric_limits<double>::infinity(), 0), JogFrame::kWorld);
  v = core::validate_jog_command(t, 7, "jog");
  EXPECT_TRUE(names(v, "jog.twist[2]", "got -1.01")) << listed(v);
  EXPECT_TRUE(names(v, "jog.twist[4]", "Infinity")) << listed(v);
  EXPECT_EQ(v.size(), 2u) << listed(v);

  JogCommand both = good;
  both.twist = Vector6d::Zero();
  v = core::validate_jog_command(both, 7, "jog");
  EXPECT_TRUE(names(v, "jog", "both joints and twist")) << listed(v);

  v = core::validate_jog_command(bad, 7, "");
  EXPECT_TRUE(names(v, "joints[2]")) << listed(v);
}

TEST(JogValidation, OptionsNameTheField) {
  EXPECT_TRUE(core::validate_jog_options(JogOptions{}, "jog.options").empty());
  JogOptions o;
  o.cycle_rate_hz = 0.0;
  o.velocity_scale = 1.5;
  o.max_linear_speed = -1.0;
  o.max_angular_speed = std::numeric_limits<double>::quiet_NaN();
  o.damping = -0.1;
  o.singular_threshold = 0.0;
  o.jerk_ramp_s = std::numeric_limits<double>::infinity();
  const auto v = core::validate_jog_options(o, "jog.options");
  EXPECT_TRUE(names(v, "jog.options.cycleRateHz", "got 0")) << listed(v);
  EXPECT_TRUE(names(v, "jog.options.velocityScale", "(0, 1], got 1.5")) << listed(v);
  EXPECT_TRUE(names(v, "jog.options.maxLinearSpeed", "> 0 [m/s], got -1")) << listed(v);
  EXPECT_TRUE(names(v, "jog.options.maxAngularSpeed", "NaN")) << listed(v);
  EXPECT_TRUE(names(v, "jog.options.damping", ">= 0, got -0.1")) << listed(v);
  EXPECT_TRUE(names(v, "jog.options.singularThreshold", "got 0")) << listed(v);
  EXPECT_TRUE(names(v, "jog.options.jerkRampS", "Infinity")) << listed(v);
  EXPECT_EQ(v.size(), 7u) << listed(v);
  JogOptions fast;
  fast.cycle_rate_hz = 2e5;
  EXPECT_TRUE(names(core::validate_jog_options(fast, "o"), "o.cycleRateHz", "] Hz, got 2"));
}

}  // namespace
}  // namespace geotraj::test
