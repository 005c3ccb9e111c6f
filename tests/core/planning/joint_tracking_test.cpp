// Joint tracking (joint_motion.hpp, thesis 6.4: IK at every sample) of the thesis's demo
// paths A, B and C (Table 7.18; 10 s, trapezoidal profile, 100 Hz, the tool orientation of
// Table 6.3) on the PA-10 with its base at the world origin, started from its home (the
// thesis's start pose, frame 1 of Table 7.8):
//  - every sample converges to 1e-9 m and 1e-9 rad (checked with the public FK), within the
//    position and velocity limits, on one branch (elbow sign; midpoint deviation; per-sample
//    joint steps below the joints' speed limits times the period);
//  - J q_dot = [v; omega] and J q_ddot + J_dot q_dot = [a; alpha] (Eqs. 1.8-1.11) to 1e-9;
//  - q_dot against central differences of q, q_ddot against central differences of q_dot
//    (bounds derived below from the next derivative);
//  - the null-space term never increases the limit cost, and the joints rest where the
//    tool rests.
// Also: the UR5 recovers a joint motion whose Cartesian image it is given (closed-form
// oracle for q, q_dot, q_ddot), a jump in the input shows as a midpoint deviation, the
// report names the joint, time and sample of deliberately shrunk limits (one event per
// joint and kind), and track() and the report make no heap allocation.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/QR>
#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "test_support.hpp"
#include "thesis_paths.hpp"

namespace geotraj::test {
namespace {

using core::CartesianState;
using core::JointSample;
using core::JointVector;
using core::LimitKind;
using core::RobotModel;
using core::Vector6d;

const RobotModel& pa10() { return *core::find_builtin_robot("pa10"); }
const RobotModel& ur5() { return *core::find_builtin_robot("ur5"); }

/// The Cartesian samples of a thesis demo path (10 s, trapezoidal, 100 Hz) and the segment
/// of each sample.
struct Motion {
  std::vector<CartesianState> xs;
  std::vector<std::size_t> segment;
};

/// `custom_turn` = 0: the thesis's tool orientation (kFixed, tool z along +x throughout).
/// Else every segment turns the tool (kCustom SLERP) to the start orientation turned by
/// +-custom_turn [rad] about x, y, z, then (1, 1, 0), one axis per frame.
Motion demo_motion(char which, double custom_turn = 0.0) {
  auto spec = testing::thesis_demo_path(which);
  if (custom_turn != 0.0) {
    const Eigen::Quaterniond q0 = core::tool_frame(spec.frames[0].T_W, *spec.frames[0].N_W);
    const Eigen::Vector3d axes[] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(),
                                    Eigen::Vector3d(1, 1, 0).normalized()};
    for (std::size_t k = 0; k < spec.frames.size(); ++k) {
      spec.frames[k].orientation_mode = core::OrientationMode::kCustom;
      spec.frames[k].orientation =
          Eigen::Quaterniond(Eigen::AngleAxisd(k % 2 ? -custom_turn : custom_turn, axes[k % 4])) * q0;
    }
  }
  const core::Path path = build_or_fail(spec);
  core::MotionSpec motion;
  motion.duration_s = 10.0;
  const auto timing = core::plan_motion(path, motion);
  const auto orientation = core::plan_orientation(path);
  EXPECT_TRUE(timing && orientation);
  if (!timing || !orientation) return {};
  core::MotionSampler sampler(path, *timing);
  Motion out;
  out.xs.reserve(timing->sample_count);
  core::MotionSample s;
  while (sampler.next(s)) {
    out.xs.push_back(core::cartesian_state(path, *orientation, s));
    out.segment.push_back(s.segment);
  }
  return out;
}

std::vector<JointSample> track_all(const RobotModel& m, const std::vector<CartesianState>& xs, const JointVector& seed,
                                   const core::IkOptions& options = {}) {
  core::JointTracker tracker(m, seed, options);
  std::vector<JointSample> out(xs.size());
  for (std::size_t k = 0; k < xs.size(); ++k) tracker.track(xs[k], out[k]);
  return out;
}

Vector6d twist(const CartesianState& x) { return (Vector6d() << x.v_WT, x.omega_WT).finished(); }
Vector6d accel(const CartesianState& x) { return (Vector6d() << x.a_WT, x.alpha_WT).finished(); }

/// Samples k whose neighbours are one period away (the last sample may be off the grid) on
/// the same segment (the angular velocity of a SLERP jumps at a frame the motion passes
/// through without stopping: a difference across it measures the jump).
bool differentiable_at(const Motion& m, std::size_t k, double dt) {
  const auto& xs = m.xs;
  return k > 0 && k + 1 < xs.size() && std::abs(xs[k + 1].t - xs[k].t - dt) < 1e-9 &&
         std::abs(xs[k].t - xs[k - 1].t - dt) < 1e-9 && m.segment[k - 1] == m.segment[k] &&
         m.segment[k + 1] == m.segment[k];
}

/// Central differences of the joint samples against their analytic rates, as vectors
/// (Euclidean norms over the joints). Where a function f is smooth, (f_{k+1} - f_{k-1}) / 2dt
/// errs by dt^2/6 |f'''|; where f'' jumps by D between samples (a corner of the trapezoidal
/// profile), by at most dt |D| / 4.
///  - q_dot: f''' and D are read from the analytic q_ddot: |q_ddot_{k+1} - q_ddot_{k-1}| is
///    2 dt |q'''| or |D|. The q samples also carry the predictor's local error (dt^3/6 q''',
///    or dt^2/2 D at a corner) projected by the Newton correction into the null space of J,
///    which mixes the joints (hence norms, not joint by joint) and at most doubles the
///    error: bound dt |q_ddot_{k+1} - q_ddot_{k-1}| (>= 3x the total where smooth, 2x at a
///    corner).
///  - q_ddot: f'' is q_ddot's slope; where q_ddot itself jumps by D the difference of q_dot
///    errs by up to |D| / 2. |q_ddot_{k+1} - 2 q_ddot_k + q_ddot_{k-1}| is dt^2 |q''''|
///    where smooth (6x the error) and |D| at a jump (2x): that is the bound.
/// Plus rounding: q is converged to ~1e-9 rad, so ~1e-7 in the differences; 1e-6 covers it.
/// Samples next to another segment are skipped (differentiable_at). Returns the worst
/// error / bound ratios (measured: <= 0.45 on the demo paths).
std::pair<double, double> check_differences(const Motion& m, const std::vector<JointSample>& js, double dt,
                                            const std::string& what) {
  const auto& xs = m.xs;
  double worst_v = 0.0, worst_a = 0.0;
  for (std::size_t k = 1; k + 1 < xs.size(); ++k) {
    if (!differentiable_at(m, k, dt)) continue;
    const JointVector fd_v = (js[k + 1].q - js[k - 1].q) / (2.0 * dt);
    const JointVector fd_a = (js[k + 1].q_dot - js[k - 1].q_dot) / (2.0 * dt);
    const double bound_v = dt * (js[k + 1].q_ddot - js[k - 1].q_ddot).norm() + 1e-6;
    const double bound_a = (js[k + 1].q_ddot - 2.0 * js[k].q_ddot + js[k - 1].q_ddot).norm() + 1e-6;
    const double err_v = (fd_v - js[k].q_dot).norm();
    const double err_a = (fd_a - js[k].q_ddot).norm();
    worst_v = std::max(worst_v, err_v / bound_v);
    worst_a = std::max(worst_a, err_a / bound_a);
    EXPECT_LE(err_v, bound_v) << what << " t " << xs[k].t << ":\n q_dot       " << js[k].q_dot.transpose()
                              << "\n differences " << fd_v.transpose();
    EXPECT_LE(err_a, bound_a) << what << " t " << xs[k].t << ":\n q_ddot      " << js[k].q_ddot.transpose()
                              << "\n differences " << fd_a.transpose();
  }
  return {worst_v, worst_a};
}

/// grad H of the limit cost (joint_motion.hpp) at q.
JointVector limit_cost_gradient(const RobotModel& m, const JointVector& q) {
  JointVector g(q.size());
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    const auto& l = m.limits[static_cast<std::size_t>(i)];
    const double r = l.max_position - l.min_position;
    g(i) = 2.0 * (q(i) - 0.5 * (l.min_position + l.max_position)) / (r * r);
  }
  return g;
}

class DemoPath : public ::testing::TestWithParam<char> {};

TEST_P(DemoPath, TrackedOnThePa10) {
  const char which = GetParam();
  const std::string what = std::string("path ") + which;
  const RobotModel& m = pa10();
  const Motion motion = demo_motion(which);
  const auto& xs = motion.xs;
  ASSERT_EQ(xs.size(), 1001u);
  const auto js = track_all(m, xs, core::home_configuration(m));
  const double dt = 0.01;
  core::JointReportBuilder report(m);
  double worst_twist = 0.0, worst_accel = 0.0, worst_step = 0.0, worst_mid = 0.0;
  int max_iterations = 0;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    const auto& x = xs[k];
    const auto& s = js[k];
    report.add(k, x.t, s);
    ASSERT_TRUE(s.converged) << what << " sample " << k << " t " << x.t;
    max_iterations = std::max(max_iterations, s.iterations);
    // Residuals, by the public forward kinematics.
    Eigen::Isometry3d X;
    core::JointJacobian J;
    core::forward_kinematics(m, s.q, X, J);
    EXPECT_LE((X.translation() - x.X_WT.translation()).norm(), 1e-9 + 1e-14) << what << " t " << x.t;
    EXPECT_LE(Eigen::AngleAxisd(x.X_WT.linear() * X.linear().transpose()).angle(), 1e-9 + 1e-14) << what;
    // Within the position limits; one branch (the elbow stays bent the same way).
    for (std::size_t i = 0; i < m.dof(); ++i) {
      const double qi = s.q(static_cast<Eigen::Index>(i));
      EXPECT_GE(qi, m.limits[i].min_position) << what << " joint " << i << " t " << x.t;
      EXPECT_LE(qi, m.limits[i].max_position) << what << " joint " << i << " t " << x.t;
    }
    EXPECT_GT(s.q(3), 0.5) << what << " t " << x.t;
    // Eqs. 1.8 and 1.10: the joint rates reproduce the Cartesian ones.
    const double e_twist = (J * s.q_dot - twist(x)).cwiseAbs().maxCoeff();
    const Vector6d a = J * s.q_ddot + core::jacobian_dot_qdot(m, s.q, s.q_dot);
    const double e_accel = (a - accel(x)).cwiseAbs().maxCoeff();
    worst_twist = std::max(worst_twist, e_twist);
    worst_accel = std::max(worst_accel, e_accel);
    EXPECT_LE(e_twist, 1e-9) << what << " t " << x.t;
    EXPECT_LE(e_accel, 1e-9) << what << " t " << x.t;
    // The joints rest where the tool rests (start, the cusp at frame 3, the end).
    if (x.v_WT.norm() == 0.0 && x.omega_WT.norm() == 0.0) {
      EXPECT_EQ(s.q_dot.norm(), 0.0) << what << " t " << x.t;
    }
    // No jumps: each joint moves less per period than its speed limit allows, and the joint
    // midpoint is on the Cartesian chord to 1e-4 m (a smooth branch deviates by O(dt^2):
    // the chord's sagitta kappa ds^2 / 8 <= 150 1/m (2 mm)^2 / 8 = 7.5e-5 m at most).
    if (k > 0) {
      for (std::size_t i = 0; i < m.dof(); ++i) {
        const auto ii = static_cast<Eigen::Index>(i);
        const double step = std::abs(s.q(ii) - js[k - 1].q(ii));
        worst_step = std::max(worst_step, step / (m.limits[i].max_velocity * dt));
        EXPECT_LE(step, m.limits[i].max_velocity * (x.t - xs[k - 1].t)) << what << " joint " << i << " t " << x.t;
      }
      worst_mid = std::max(worst_mid, s.midpoint_deviation);
      EXPECT_LE(s.midpoint_deviation, 1e-4) << what << " t " << x.t;
    }
  }
  const auto [ratio_v, ratio_a] = check_differences(motion, js, dt, what);
  const auto& r = report.report();
  EXPECT_EQ(r.samples, xs.size());
  for (const auto& v : r.violations) {
    EXPECT_EQ(v.kind, LimitKind::kAcceleration) << what << ": joint " << v.joint << " t " << v.t;
  }
  EXPECT_GT(r.tightest_position.margin, 0.0);
  EXPECT_GT(r.tightest_velocity.margin, 0.0);
  double peak_accel_usage = 0.0;
  for (const auto& u : r.joints) peak_accel_usage = std::max(peak_accel_usage, u.acceleration_usage);
  std::printf("%s on the PA-10: %zu samples, all converged (<= %d Newton steps), worst |J q_dot - twist| %.2g, "
              "|J q_ddot + J_dot q_dot - accel| %.2g, midpoint deviation %.2g m, step / speed limit %.2f, "
              "differences / bound %.2f (q_dot) %.2f (q_ddot); tightest position margin %.3f rad (joint %zu, t %.2f s), "
              "min manipulability %.4f, peak acceleration usage %.2f\n",
              what.c_str(), xs.size(), max_iterations, worst_twist, worst_accel, worst_mid, worst_step, ratio_v, ratio_a,
              r.tightest_position.margin, r.tightest_position.joint, r.tightest_position.t, r.min_manipulability,
              peak_accel_usage);
}

INSTANTIATE_TEST_SUITE_P(Thesis, DemoPath, ::testing::Values('A', 'B', 'C'),
                         [](const auto& param_info) { return std::string("Path") + param_info.param; });

// The tool turning as well (custom SLERP by 0.4 rad per segment; the thesis's frame-based
// turn to each key frame's [-B N T] takes the PA-10's S2 to its limit on these paths):
// omega and alpha are not zero, and the same identities and differences hold.
TEST(JointTracker, TurningToolOnPathC) {
  const RobotModel& m = pa10();
  const Motion motion = demo_motion('C', 0.4);
  const auto& xs = motion.xs;
  const auto js = track_all(m, xs, core::home_configuration(m));
  double peak_omega = 0.0, peak_alpha = 0.0;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    ASSERT_TRUE(js[k].converged) << "t " << xs[k].t;
    Eigen::Isometry3d X;
    core::JointJacobian J;
    core::forward_kinematics(m, js[k].q, X, J);
    EXPECT_LE((J * js[k].q_dot - twist(xs[k])).cwiseAbs().maxCoeff(), 1e-9);
    const Vector6d a = J * js[k].q_ddot + core::jacobian_dot_qdot(m, js[k].q, js[k].q_dot);
    EXPECT_LE((a - accel(xs[k])).cwiseAbs().maxCoeff(), 1e-9);
    if (k > 0) {
      EXPECT_LE(js[k].midpoint_deviation, 1e-4);
    }
    peak_omega = std::max(peak_omega, xs[k].omega_WT.norm());
    peak_alpha = std::max(peak_alpha, xs[k].alpha_WT.norm());
  }
  EXPECT_GT(peak_omega, 0.1);
  EXPECT_GT(peak_alpha, 0.1);
  const auto [ratio_v, ratio_a] = check_differences(motion, js, 0.01, "path C, turning tool");
  std::printf("path C with a turning tool: peak |omega| %.2f rad/s, |alpha| %.2f rad/s^2, differences / bound %.2f "
              "(q_dot) %.2f (q_ddot)\n",
              peak_omega, peak_alpha, ratio_v, ratio_a);
}

// The null-space term: its part of q_dot, q_dot - J^+ [v; omega] = N z, never increases
// the limit cost H (grad H . N z = -k |v| |N grad H|^2 <= 0), and it is zero without gain.
TEST(JointTracker, NullSpaceTermDescendsTheLimitCost) {
  const RobotModel& m = pa10();
  const auto xs = demo_motion('B').xs;
  for (const double gain : {0.0, 1.0, 5.0}) {
    core::IkOptions options;
    options.limit_avoidance_gain = gain;
    const auto js = track_all(m, xs, core::home_configuration(m), options);
    double largest = 0.0;
    for (std::size_t k = 0; k < xs.size(); ++k) {
      ASSERT_TRUE(js[k].converged);
      const core::JointJacobian J = [&] {
        Eigen::Isometry3d X;
        core::JointJacobian out;
        core::forward_kinematics(m, js[k].q, X, out);
        return out;
      }();
      const Eigen::MatrixXd J_pinv = Eigen::MatrixXd(J).completeOrthogonalDecomposition().pseudoInverse();
      const Eigen::VectorXd self_motion = js[k].q_dot - J_pinv * twist(xs[k]);
      largest = std::max(largest, self_motion.norm());
      EXPECT_LE(limit_cost_gradient(m, js[k].q).dot(self_motion), 1e-12) << "gain " << gain << " t " << xs[k].t;
      if (gain == 0.0) {
        EXPECT_LE(self_motion.norm(), 1e-9) << "t " << xs[k].t;
      }
    }
    if (gain > 0.0) {
      EXPECT_GT(largest, 1e-3) << "gain " << gain;  // the term is at work
    }
  }
}

// A non-redundant arm has one solution near the previous one: the UR5 given the Cartesian
// image of a smooth joint motion q(t) = q0 + A sin(w t) (pose FK(q), twist J q_dot,
// acceleration J q_ddot + J_dot q_dot) recovers q, q_dot and q_ddot.
// The tool's state of the UR5 moving its joints along q0 + amp sin(w t) [rad]: the Cartesian
// motion of a known joint motion: v = J q_dot, a = J q_ddot + J_dot q_dot.
struct KnownJointMotion {
  JointVector q0 = (JointVector(6) << 0.2, -1.3, 1.6, -1.7, -1.4, 0.3).finished();
  JointVector amp = (JointVector(6) << 0.4, 0.3, -0.5, 0.6, 0.5, -0.7).finished();
  double w = 1.3;  // [rad/s]
  JointVector q(double t) const { return q0 + amp * std::sin(w * t); }
  CartesianState state(const RobotModel& m, double t) const {
    const JointVector qt = q(t), q_dot = amp * (w * std::cos(w * t)), q_ddot = amp * (-w * w * std::sin(w * t));
    CartesianState x;
    x.t = t;
    core::JointJacobian J;
    core::forward_kinematics(m, qt, x.X_WT, J);
    const Vector6d v = J * q_dot;
    const Vector6d a = J * q_ddot + core::jacobian_dot_qdot(m, qt, q_dot);
    x.v_WT = v.head<3>();
    x.omega_WT = v.tail<3>();
    x.a_WT = a.head<3>();
    x.alpha_WT = a.tail<3>();
    return x;
  }
};

TEST(JointTracker, Ur5RecoversAJointMotion) {
  const RobotModel& m = ur5();
  const KnownJointMotion motion;
  core::JointTracker tracker(m, motion.q0);
  double worst_q = 0.0, worst_v = 0.0, worst_a = 0.0;
  for (int k = 0; k <= 500; ++k) {
    const double t = 0.01 * k;
    const double c = std::cos(motion.w * t), sn = std::sin(motion.w * t);
    JointSample s;
    ASSERT_TRUE(tracker.track(motion.state(m, t), s)) << "t " << t;
    worst_q = std::max(worst_q, (s.q - motion.q(t)).cwiseAbs().maxCoeff());
    worst_v = std::max(worst_v, (s.q_dot - motion.amp * (motion.w * c)).cwiseAbs().maxCoeff());
    worst_a = std::max(worst_a, (s.q_ddot + motion.amp * (motion.w * motion.w * sn)).cwiseAbs().maxCoeff());
  }
  // q to the IK tolerance over the smallest singular value (J^-1 amplifies 1e-9 by ~10 here).
  EXPECT_LE(worst_q, 1e-7);
  EXPECT_LE(worst_v, 1e-7);
  EXPECT_LE(worst_a, 1e-6);
}

// Samples far apart (a slow controller, or live execution's steps): one Newton projection
// from the predictor leaves the branch or does not converge, and follow() walks the
// interval through the motion's states between them, landing on the joints the motion has
// there (the UR5 is not redundant: one branch, one solution).
TEST(JointTracker, FollowWalksAnIntervalTooLongForOneStep) {
  const RobotModel& m = ur5();
  KnownJointMotion motion;
  // The wrist comes within 0.01 rad of its singularity (q_4 = 0) while joints 3 and 5 swing
  // by 1.8 and 2.5 rad.
  motion.q0(4) = 0.1;
  motion.amp << 0.8, 0.6, -0.9, 1.8, 0.09, -2.5;
  int states = 0;
  auto between = core::cartesian_source([&](double t, CartesianState& x) {
    x = motion.state(m, t);
    ++states;
    return true;
  });
  int one_step_lost = 0;
  long walk_allocations = 0;
  for (const double dt : {0.25, 0.5, 1.0}) {  // [s]; at 1 s one Newton projection lands on the flipped wrist
    core::JointTracker walked(m, motion.q0), one_step(m, motion.q0);
    double worst_walked = 0.0, worst_one_step = 0.0;
    int walks = 0;
    bool one_step_failed = false;
    JointVector q_prev = motion.q0;
    for (int k = 0; k * dt <= 6.0; ++k) {
      const double t = k * dt;
      const CartesianState x = motion.state(m, t);
      JointSample s;
      s.q.resize(6);
      const long before = geotraj::testing::allocation_count();
      const core::FollowResult r = walked.follow(x, between, s, core::kSampleContinuation);
      walk_allocations += geotraj::testing::allocation_count() - before;
      ASSERT_TRUE(r.converged) << "dt " << dt << " t " << t;
      EXPECT_FALSE(r.jumped) << "dt " << dt << " t " << t;
      walks += r.substeps > 0 ? 1 : 0;
      worst_walked = std::max(worst_walked, (s.q - motion.q(t)).cwiseAbs().maxCoeff());
      if (k > 0) {  // the certificate spans the whole interval, whatever the walk tracked
        const Eigen::Vector3d p_mid = core::forward_kinematics(m, JointVector(0.5 * (q_prev + s.q))).translation();
        const Eigen::Vector3d chord_mid =
            0.5 * (core::forward_kinematics(m, q_prev).translation() + x.X_WT.translation());
        EXPECT_NEAR(s.midpoint_deviation, (p_mid - chord_mid).norm(), 1e-9) << "dt " << dt << " t " << t;
      }
      q_prev = s.q;
      JointSample o;
      if (one_step.track(x, o)) worst_one_step = std::max(worst_one_step, (o.q - motion.q(t)).cwiseAbs().maxCoeff());
      else one_step_failed = true;
    }
    std::printf("dt %.2f s: walked %d intervals, worst joint error %.3g rad; one step: %s, worst %.3g rad\n", dt, walks,
                worst_walked, one_step_failed ? "failed" : "converged", worst_one_step);
    EXPECT_LE(worst_walked, 1e-7) << "dt " << dt;
    one_step_lost += one_step_failed || worst_one_step > 1e-3 ? 1 : 0;
  }
  EXPECT_GT(states, 0);
  EXPECT_EQ(walk_allocations, 0) << "a walk allocates nothing";
  EXPECT_GT(one_step_lost, 0) << "a case one Newton projection per sample follows tests nothing";
}

// A jump in the input (the tool asked to be 0.15 m away at the next sample) is followed if
// the IK converges, but the joint-space interpolation between the two samples strays from
// the chord: the midpoint deviation flags it and the report raises kBranch.
TEST(JointTracker, JumpShowsAsMidpointDeviation) {
  const RobotModel& m = pa10();
  const auto xs = demo_motion('A').xs;
  core::JointTracker tracker(m, core::home_configuration(m));
  core::JointReportBuilder report(m);
  JointSample s;
  for (std::size_t k = 0; k < 300; ++k) {
    ASSERT_TRUE(tracker.track(xs[k], s));
    report.add(k, xs[k].t, s);
  }
  CartesianState jump = xs[300];
  jump.X_WT.translation() += Eigen::Vector3d(0.0, 0.15, 0.0);
  jump.X_WT.linear() = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitY()) * jump.X_WT.linear();
  ASSERT_TRUE(tracker.track(jump, s));
  EXPECT_GT(s.midpoint_deviation, 1e-3);
  report.add(300, jump.t, s);
  const auto& r = report.report();
  // The branch event, and the joint velocities' step as accelerations: all at the jump.
  const auto branch = std::find_if(r.violations.begin(), r.violations.end(),
                                   [](const core::LimitEvent& e) { return e.kind == LimitKind::kBranch; });
  ASSERT_NE(branch, r.violations.end());
  for (const auto& e : r.violations) {
    EXPECT_EQ(e.sample, 300u);
    EXPECT_TRUE(e.kind == LimitKind::kBranch || e.kind == LimitKind::kAcceleration);
  }
  EXPECT_DOUBLE_EQ(branch->t, jump.t);
  EXPECT_DOUBLE_EQ(branch->value, s.midpoint_deviation);
  EXPECT_DOUBLE_EQ(r.max_midpoint_deviation, s.midpoint_deviation);
  EXPECT_DOUBLE_EQ(r.max_midpoint_deviation_t, jump.t);
}

// The report against deliberately shrunk limits: the first sample of each broken (joint,
// kind), named with its joint, time and sample, once, whatever the run's length.
TEST(JointReport, NamesShrunkLimits) {
  const RobotModel& m = pa10();
  const auto xs = demo_motion('C').xs;
  const auto js = track_all(m, xs, core::home_configuration(m));
  RobotModel shrunk = m;
  shrunk.limits[0].min_position = -1.0;  // joint 0 goes down to about -1.5 rad on path C
  shrunk.limits[2].max_velocity = 0.5;   // joint 2 peaks near 0.8 rad/s
  for (auto& l : shrunk.limits) l.max_acceleration = 1e3;  // no acceleration events
  core::JointReportBuilder builder(shrunk);
  for (std::size_t k = 0; k < xs.size(); ++k) builder.add(k, xs[k].t, js[k]);
  const auto& r = builder.report();

  // The expected events, by scanning the samples.
  std::size_t first_p = xs.size(), first_v = xs.size(), count_p = 0;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    if (js[k].q(0) < -1.0) {
      ++count_p;
      first_p = std::min(first_p, k);
    }
    if (std::abs(js[k].q_dot(2)) > 0.5) first_v = std::min(first_v, k);
  }
  ASSERT_LT(first_p, xs.size());
  ASSERT_LT(first_v, xs.size());
  EXPECT_GT(count_p, 10u);  // a long run, reported once
  ASSERT_EQ(r.violations.size(), 2u);
  EXPECT_FALSE(r.feasible());
  const auto& p = r.violations[first_p < first_v ? 0 : 1];
  const auto& v = r.violations[first_p < first_v ? 1 : 0];
  EXPECT_EQ(p.kind, LimitKind::kPosition);
  EXPECT_EQ(p.joint, 0u);
  EXPECT_EQ(p.sample, first_p);
  EXPECT_DOUBLE_EQ(p.t, xs[first_p].t);
  EXPECT_DOUBLE_EQ(p.value, js[first_p].q(0));
  EXPECT_DOUBLE_EQ(p.limit, -1.0);
  EXPECT_DOUBLE_EQ(p.margin, js[first_p].q(0) + 1.0);
  EXPECT_LT(p.margin, 0.0);
  EXPECT_EQ(v.kind, LimitKind::kVelocity);
  EXPECT_EQ(v.joint, 2u);
  EXPECT_EQ(v.sample, first_v);
  EXPECT_DOUBLE_EQ(v.t, xs[first_v].t);
  EXPECT_DOUBLE_EQ(v.value, std::abs(js[first_v].q_dot(2)));
  EXPECT_DOUBLE_EQ(v.limit, 0.5);
  EXPECT_LE(r.violations[0].t, r.violations[1].t);  // in time order

  // Usage and the tightest margins agree with the samples.
  double min_q0 = 1e9, peak_v2 = 0.0, tightest = 1e9, min_manip = 1e9;
  std::size_t tightest_joint = 0, tightest_sample = 0;
  for (std::size_t k = 0; k < xs.size(); ++k) {
    min_q0 = std::min(min_q0, js[k].q(0));
    peak_v2 = std::max(peak_v2, std::abs(js[k].q_dot(2)));
    min_manip = std::min(min_manip, js[k].manipulability);
    for (std::size_t i = 0; i < m.dof(); ++i) {
      const double q = js[k].q(static_cast<Eigen::Index>(i));
      const double margin = std::min(q - shrunk.limits[i].min_position, shrunk.limits[i].max_position - q);
      if (margin < tightest) {
        tightest = margin;
        tightest_joint = i;
        tightest_sample = k;
      }
    }
  }
  EXPECT_DOUBLE_EQ(r.joints[0].min_position, min_q0);
  EXPECT_DOUBLE_EQ(r.joints[0].position_margin, min_q0 + 1.0);
  EXPECT_DOUBLE_EQ(r.joints[2].peak_velocity, peak_v2);
  EXPECT_DOUBLE_EQ(r.joints[2].velocity_usage, peak_v2 / 0.5);
  EXPECT_DOUBLE_EQ(r.tightest_position.margin, tightest);
  EXPECT_EQ(r.tightest_position.joint, tightest_joint);
  EXPECT_EQ(r.tightest_position.sample, tightest_sample);
  EXPECT_EQ(r.tightest_position.joint, 0u);
  EXPECT_DOUBLE_EQ(r.min_manipulability, min_manip);
  EXPECT_EQ(r.tightest_velocity.joint, 2u);
  EXPECT_LT(r.tightest_velocity.margin, 0.0);
}

// A sample that did not converge raises kIk (once), with its residual; the rest of the
// sample is not counted as motion.
TEST(JointReport, FailedSampleRaisesIk) {
  core::JointReportBuilder builder(pa10());
  JointSample s;
  s.q = core::home_configuration(pa10());
  s.q_dot = JointVector::Zero(7);
  s.q_ddot = JointVector::Zero(7);
  s.converged = true;
  s.manipulability = 0.1;
  builder.add(0, 0.0, s);
  s.converged = false;
  s.position_error = 0.02;
  s.q(0) = 100.0;  // garbage of a failed solve: not a position event
  builder.add(1, 0.01, s);
  builder.add(2, 0.02, s);
  const auto& r = builder.report();
  ASSERT_EQ(r.violations.size(), 1u);
  EXPECT_EQ(r.violations[0].kind, LimitKind::kIk);
  EXPECT_EQ(r.violations[0].sample, 1u);
  EXPECT_DOUBLE_EQ(r.violations[0].value, 0.02);
  EXPECT_DOUBLE_EQ(r.violations[0].limit, 1e-9);
  EXPECT_DOUBLE_EQ(r.max_position_error, 0.02);
  EXPECT_EQ(r.samples, 3u);
  EXPECT_LT(r.joints[0].max_position, 1.0);
}

// A joint held at its position limit is named first where it forces another limit (the
// tracker holds it, and the others race to follow the tool) or before an IK failure (the
// others could not follow without it); reaching the limit alone breaks nothing.
TEST(JointReport, AJointHeldAtItsLimitIsNamedBeforeWhatItForces) {
  const RobotModel& m = pa10();
  const auto sample = [&] {
    JointSample s;
    s.q = core::home_configuration(m);
    s.q_dot = JointVector::Zero(7);
    s.q_ddot = JointVector::Zero(7);
    s.converged = true;
    s.manipulability = 0.1;
    return s;
  };
  core::JointReportBuilder forced(m);
  forced.add(0, 0.0, sample());
  JointSample held = sample();
  held.q(6) = m.limits[6].max_position;
  forced.add(1, 0.01, held);
  EXPECT_TRUE(forced.report().feasible()) << "at the limit, not past it";
  held.q_ddot(0) = 2.0 * m.limits[0].max_acceleration;
  forced.add(2, 0.02, held);
  const auto& r = forced.report();
  ASSERT_EQ(r.violations.size(), 2u);
  EXPECT_EQ(r.violations[0].kind, LimitKind::kPosition);
  EXPECT_EQ(r.violations[0].joint, 6u);
  EXPECT_EQ(r.violations[0].sample, 2u);
  EXPECT_DOUBLE_EQ(r.violations[0].margin, 0.0);
  EXPECT_EQ(r.violations[1].kind, LimitKind::kAcceleration);
  EXPECT_EQ(r.violations[1].joint, 0u);

  core::JointReportBuilder lost(m);
  JointSample at_limit = sample();
  at_limit.q(3) = m.limits[3].min_position;
  lost.add(0, 0.0, at_limit);
  JointSample failed = at_limit;
  failed.converged = false;
  failed.position_error = 1e-4;
  lost.add(1, 0.01, failed);
  const auto& l = lost.report();
  ASSERT_EQ(l.violations.size(), 2u);
  EXPECT_EQ(l.violations[0].kind, LimitKind::kPosition);
  EXPECT_EQ(l.violations[0].joint, 3u);
  EXPECT_EQ(l.violations[0].sample, 0u) << "the last good sample";
  EXPECT_EQ(l.violations[1].kind, LimitKind::kIk);
  EXPECT_EQ(l.violations[1].sample, 1u);
}

// A joint velocity that steps between samples (each sample's own q_ddot within the limit)
// is an acceleration of the step over the sample time: reported; a change the limit allows
// is not; nor is a step across a failed sample.
TEST(JointReport, AVelocityStepBetweenSamplesIsAnAcceleration) {
  const RobotModel& m = pa10();
  const double a_max = m.limits[0].max_acceleration, dt = 0.001;
  const auto sample = [&](double v0) {
    JointSample s;
    s.q = core::home_configuration(m);
    s.q_dot = JointVector::Zero(7);
    s.q_dot(0) = v0;
    s.q_ddot = JointVector::Zero(7);
    s.converged = true;
    s.manipulability = 0.1;
    return s;
  };
  core::JointReportBuilder smooth(m);
  smooth.add(0, 0.0, sample(0.0));
  smooth.add(1, dt, sample(0.999 * a_max * dt));  // within the limit over the step
  EXPECT_TRUE(smooth.report().feasible());
  EXPECT_DOUBLE_EQ(smooth.report().joints[0].peak_acceleration, 0.0);  // the samples' own q_ddot

  core::JointReportBuilder step(m);
  step.add(0, 0.0, sample(0.0));
  step.add(1, dt, sample(0.3));  // 0.3 rad/s in 1 ms: 300 rad/s^2
  const auto& r = step.report();
  ASSERT_EQ(r.violations.size(), 1u);
  EXPECT_EQ(r.violations[0].kind, LimitKind::kAcceleration);
  EXPECT_EQ(r.violations[0].joint, 0u);
  EXPECT_EQ(r.violations[0].sample, 1u);
  EXPECT_NEAR(r.violations[0].value, 300.0, 1e-9);
  EXPECT_NEAR(r.joints[0].peak_acceleration, 300.0, 1e-9);

  core::JointReportBuilder gap(m);
  gap.add(0, 0.0, sample(0.0));
  JointSample failed = sample(0.0);
  failed.converged = false;
  failed.position_error = 1e-3;
  gap.add(1, dt, failed);
  gap.add(2, 2 * dt, sample(0.3));
  for (const auto& v : gap.report().violations) EXPECT_NE(v.kind, LimitKind::kAcceleration);
}

TEST(JointTracker, NoHeapAllocationPerSample) {
  const RobotModel& m = pa10();
  const auto xs = demo_motion('C').xs;
  core::JointTracker tracker(m, core::home_configuration(m));
  core::JointReportBuilder report(m);
  JointSample s;
  s.q.resize(7);  // capacity is fixed: resizing never allocates either
  double sink = 0.0;
  const long before = geotraj::testing::allocation_count();
  for (std::size_t k = 0; k < xs.size(); ++k) {  // the first call (a cold solve) included
    tracker.track(xs[k], s);
    report.add(k, xs[k].t, s);
    sink += s.q_ddot.sum();
  }
  tracker.reset(core::home_configuration(m));
  tracker.track(xs[0], s);
  EXPECT_EQ(geotraj::testing::allocation_count(), before);
  EXPECT_TRUE(std::isfinite(sink));
}

}  // namespace
}  // namespace geotraj::test

namespace geotraj::test {
namespace {

using core::JointMotionReport;
using core::JointReportBuilder;
using core::JointUsage;
using core::BindingKind;
using core::BindingStretch;
using core::home_configuration;
using core::kMaxBindingStretches;

// Which limit sets the pace: the stretches follow each other in time, cover the motion from
// the first moving sample to the end, and their peaks are the joint report's peaks for the
// limit they name; the overall most used limit is the peak of one stretch.
TEST(JointReport, BindingStretchesCoverTheMotion) {
  const RobotModel& m = pa10();
  const auto motion = demo_motion('C');
  const auto js = track_all(m, motion.xs, home_configuration(m));
  JointReportBuilder builder(m);
  for (std::size_t k = 0; k < js.size(); ++k) builder.add(k, motion.xs[k].t, js[k]);
  const JointMotionReport& r = builder.report();
  ASSERT_FALSE(r.binding.empty());
  ASSERT_LE(r.binding.size(), kMaxBindingStretches);
  EXPECT_EQ(r.binding.back().sample_end, js.size() - 1);
  EXPECT_DOUBLE_EQ(r.binding.back().t_end, motion.xs.back().t);
  double top_usage = 0.0;
  for (const auto& u : r.joints) top_usage = std::max({top_usage, u.velocity_usage, u.acceleration_usage});
  double top_stretch = 0.0;
  for (std::size_t i = 0; i < r.binding.size(); ++i) {
    const BindingStretch& b = r.binding[i];
    if (i > 0) {
      EXPECT_EQ(b.sample_start, r.binding[i - 1].sample_end) << "stretch " << i;
    }
    EXPECT_LE(b.t_start, b.t_end);
    const JointUsage& u = r.joints[b.joint];
    const double peak = b.kind == BindingKind::kJointVelocity ? u.velocity_usage : u.acceleration_usage;
    EXPECT_LE(b.usage, peak * (1 + 1e-12)) << "stretch " << i;
    EXPECT_NEAR(b.value / b.limit, b.usage, 1e-12);
    top_stretch = std::max(top_stretch, b.usage);
  }
  EXPECT_NEAR(top_stretch, top_usage, 1e-12 * top_usage);
}

}  // namespace
}  // namespace geotraj::test
