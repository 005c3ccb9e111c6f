// The thesis's basic moves (6.2.2): joint-interpolated and Cartesian straight-line. See
// moves.hpp.
#include "core/planning/moves.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <string>

#include "core/robot/dynamics.hpp"
#include "core/robot/kinematics.hpp"

#include "core/robot/serial_chain.hpp"
#include "core/format.hpp"

namespace geotraj::core {
namespace {


std::string indexed(const std::string& field, std::size_t i) { return field + "[" + std::to_string(i) + "]"; }

/// Largest |coordinate| of a move's positions [m] (as PathLimits::max_coordinate).
constexpr double kMaxMoveCoordinate = 1e6;
/// A quaternion within this of unit length is normalised; others are rejected.
constexpr double kUnitQuaternionTolerance = 1e-3;

// The profile state at t: at rest before the start (s = 0) and exactly at the end (s =
// length, v = a = 0) from the duration on; at t = 0 the one-sided acceleration of the
// first piece, as MotionSampler's first sample.
ProfileState state_at(const SpeedProfile& profile, double t, ProfileCursor& cursor, bool at_end) {
  if (at_end) return {profile.length, 0.0, 0.0, 0.0};
  return evaluate(profile, t, cursor);
}

void check_pose(const ToolPose& pose, const std::string& field, Violations& v) {
  const std::string position = field + ".position", orientation = field + ".orientation";
  if (!pose.p_WT.allFinite()) {
    v.push_back({position, "must have finite components"});
  } else if (!(pose.p_WT.cwiseAbs().maxCoeff() <= kMaxMoveCoordinate)) {
    v.push_back({position, "must be within " + number(kMaxMoveCoordinate) + " m of the origin in every coordinate"});
  }
  if (!pose.q_WT.coeffs().allFinite()) {
    v.push_back({orientation, "must have finite components"});
  } else if (const double norm = pose.q_WT.norm(); !(std::abs(norm - 1.0) <= kUnitQuaternionTolerance)) {
    v.push_back({orientation, "must be a unit quaternion (|q| within " + number(kUnitQuaternionTolerance) +
                                  " of 1), got |q| = " + number(norm)});
  }
}

// The move's samples on the one grid (core/motion/motion.hpp), once its profile is timed:
// refused, naming motion.durationS, when a peak rate (`peaks`, or the profile's jerk)
// overflows double precision or when there would be more samples than a stream may hold.
Expected<std::size_t> move_samples(const MotionSpec& motion, double duration, const SpeedProfile& profile,
                                   std::initializer_list<double> peaks) {
  const bool finite = std::isfinite(peak_jerk(profile)) &&
                      std::all_of(peaks.begin(), peaks.end(), [](double x) { return std::isfinite(x); });
  if (!finite && motion.duration_s > 0.0) {
    return tl::make_unexpected(Violations{{"motion.durationS", "is too short for this move (" + number(duration) +
                                                                   " s): the speeds overflow double precision"}});
  }
  if (!finite) {
    return tl::make_unexpected(Violations{{"motion.durationS", "is 0, and the minimum-time move (" + number(duration) +
                                                                   " s) is too short to time: its rates overflow double "
                                                                   "precision"}});
  }
  const double grid = duration * motion.cycle_rate_hz;
  if (!(grid < kMaxMotionSamples)) {
    // The request's own durationS is a field to change; a minimum-time move's length is what
    // the limits make of it.
    return tl::make_unexpected(Violations{
        {"motion.durationS",
         "the move lasts " + number(duration) + " s, " + number(grid) + " samples, more than " +
             number(kMaxMotionSamples) + " per stream: shorten the move, lower cycleRateHz or raise the limits",
         motion.duration_s > 0.0 ? ViolationKind::kInvalid : ViolationKind::kUnattainable}});
  }
  return grid_sample_count(duration, motion.cycle_rate_hz);
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Joint-interpolated move (6.2.2.1)

Expected<JointMovePlan> plan_joint_move(const ValidRobot& robot, const JointMoveSpec& spec, const MotionSpec& motion) {
  const RobotModel& model = robot;
  Violations v;
  const std::size_t n = model.dof();
  const auto check_joints = [&](const std::vector<double>& q, const std::string& field) {
    if (q.size() != n) {
      v.push_back({field, "has " + std::to_string(q.size()) + " values for " + std::to_string(n) +
                              " joints: give one per joint"});
      return;
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(q[i])) {
        v.push_back({indexed(field, i), "must be finite, got " + number(q[i])});
      } else if (i < model.limits.size() && !within_position_limits(model.joints[i].type, model.limits[i], q[i])) {
        v.push_back({indexed(field, i), number(q[i]) + " is outside joint " + std::to_string(i) + "'s position limits [" +
                                            number(model.limits[i].min_position) + ", " +
                                            number(model.limits[i].max_position) + "]"});
      }
    }
  };
  check_joints(spec.start, "jointMove.start");
  check_joints(spec.goal, "jointMove.goal");
  // A joint move is bounded by the joints' limits, not by the Cartesian maxSpeed,
  // maxAcceleration and maxJerk that validate_motion asks of a minimum-time path motion.
  for (auto& x : validate_motion(motion, motion.duration_s == 0.0 ? MotionTiming::kLimits : MotionTiming::kProfile))
    v.push_back(std::move(x));
  if (!v.empty()) return tl::make_unexpected(v);

  JointMovePlan plan{.model = robot,
                     .spec = motion,
                     .q0 = JointVector(),
                     .q1 = JointVector(),
                     .profile = SpeedProfile(),
                     .duration_s = 0.0,
                     .sample_count = 0,
                     .limiting_joint = 0,
                     .velocity_usage = 0.0,
                     .acceleration_usage = 0.0};
  const auto dof = static_cast<Eigen::Index>(n);
  plan.q0.resize(dof);
  plan.q1.resize(dof);
  for (Eigen::Index i = 0; i < dof; ++i) {
    plan.q0(i) = spec.start[static_cast<std::size_t>(i)];
    plan.q1(i) = spec.goal[static_cast<std::size_t>(i)];
  }
  const double scale = motion.speed_scale;
  Expected<SpeedProfile> profile = SpeedProfile{};
  if (motion.duration_s > 0.0) {
    const double T = motion.duration_s / scale;
    profile = motion.profile == ProfileShape::kTrapezoidal ? trapezoid_profile(1.0, T, motion.ramp_fraction)
                                                           : scurve_profile(1.0, T, motion.ramp_fraction);
  } else {
    // The tightest normalised limits over the moving joints (the speed scale is a time
    // scaling: v s, a s^2, j s^3). Quotients that overflow are capped: they bind nothing.
    constexpr double kHuge = std::numeric_limits<double>::max();
    double v_x = kHuge, a_x = kHuge, j_x = kHuge, slowest = -1.0;
    bool moving = false, jerk_limited = false;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = std::abs(plan.q1(static_cast<Eigen::Index>(i)) - plan.q0(static_cast<Eigen::Index>(i)));
      if (!(d > 0.0)) continue;
      moving = true;
      const JointLimits& lim = model.limits[i];
      const double v_i = std::min(kHuge, lim.max_velocity * scale / d);
      const double a_i = std::min(kHuge, lim.max_acceleration * scale * scale * motion.acceleration_scale / d);
      v_x = std::min(v_x, v_i);
      a_x = std::min(a_x, a_i);
      double j_i = kHuge;
      if (lim.max_jerk) {
        jerk_limited = true;
        j_i = std::min(kHuge, *lim.max_jerk * scale * scale * scale * motion.acceleration_scale / d);
        j_x = std::min(j_x, j_i);
      }
      // This joint's own minimum time (its profile of x), to name the slowest joint.
      const double own = motion.profile == ProfileShape::kSCurve && lim.max_jerk
                             ? min_time_double_s_duration(1.0, v_i, a_i, j_i)
                             : min_time_trapezoid_duration(1.0, v_i, a_i);
      if (own > slowest) {
        slowest = own;
        plan.limiting_joint = i;
      }
    }
    if (moving) {
      if (motion.profile == ProfileShape::kTrapezoidal) {
        profile = min_time_trapezoid(1.0, v_x, a_x);
      } else if (jerk_limited) {
        profile = min_time_double_s(1.0, v_x, a_x, j_x);
      } else {
        profile = min_time_scurve(1.0, motion.ramp_fraction, v_x, a_x);
      }
    }
  }
  if (!profile) return tl::make_unexpected(prefixed(profile.error(), "motion."));
  plan.profile = std::move(*profile);
  plan.duration_s = motion.duration_s > 0.0 ? motion.duration_s / scale : plan.profile.duration;

  const double x_dot = peak_speed(plan.profile), x_ddot = peak_acceleration(plan.profile);
  for (std::size_t i = 0; i < n; ++i) {
    const double d = std::abs(plan.q1(static_cast<Eigen::Index>(i)) - plan.q0(static_cast<Eigen::Index>(i)));
    plan.velocity_usage = std::max(plan.velocity_usage, x_dot * d / model.limits[i].max_velocity);
    plan.acceleration_usage = std::max(plan.acceleration_usage, x_ddot * d / model.limits[i].max_acceleration);
  }
  auto samples = move_samples(motion, plan.duration_s, plan.profile, {plan.velocity_usage, plan.acceleration_usage});
  if (!samples) return tl::make_unexpected(std::move(samples.error()));
  plan.sample_count = *samples;
  return plan;
}

void joint_move_at(const JointMovePlan& plan, double t, ProfileCursor& cursor, MoveSample& out) {
  GEOTRAJ_CHECK(static_cast<std::size_t>(plan.q0.size()) == plan.model->dof());
  const RobotModel& model = plan.model;
  const bool at_end = t >= plan.duration_s;
  const ProfileState x = state_at(plan.profile, t, cursor, at_end);
  const Eigen::Index n = plan.q0.size();
  out.q.resize(n);
  out.q_dot.resize(n);
  out.q_ddot.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double q0 = plan.q0(i), q1 = plan.q1(i), dq = q1 - q0;
    // 6.2.2.1: q = q0 + x (q1 - q0), kept between q0 and q1 against rounding (so within the
    // limits), exactly q1 at the end.
    out.q(i) = at_end ? q1 : std::clamp(q0 + x.s * dq, std::min(q0, q1), std::max(q0, q1));
    out.q_dot(i) = x.v * dq;
    out.q_ddot(i) = x.a * dq;
  }
  joint_tool_state(model, out);
  out.t = t;
  out.u = at_end ? 1.0 : x.s;
  out.s = 0.0;
}

void joint_tool_state(const RobotModel& model, MoveSample& out) {
  // One walk of the chain for the pose, the Jacobian and its derivative.
  const detail::SerialChain chain(model);
  Eigen::Matrix3d R_WT;
  Eigen::Vector3d p_WT;
  detail::JointAxes z, o;
  JointJacobian J, J_dot;
  chain.jacobian(out.q, R_WT, p_WT, z, o, J);
  chain.jacobian_dot(p_WT, z, o, J, out.q_dot, J_dot);
  const Vector6d V = J * out.q_dot;                        // (1.8)
  const Vector6d A = J * out.q_ddot + J_dot * out.q_dot;  // (1.10, 1.11)
  out.p_W = p_WT;
  out.v_W = V.head<3>();
  out.a_W = A.head<3>();
  out.speed = out.v_W.norm();
  out.q_WT = Eigen::Quaterniond(R_WT).normalized();
  out.omega_W = V.tail<3>();
  out.alpha_W = A.tail<3>();
  out.manipulability = manipulability(J);
  out.has_joints = true;
}

void joint_move_at(const JointMovePlan& plan, double t, MoveSample& out) {
  ProfileCursor cursor{plan.profile.pieces.size()};  // forces a binary search
  joint_move_at(plan, t, cursor, out);
}


// ---------------------------------------------------------------------------------------
// Cartesian straight-line move (6.2.2.2)

double torque_stretch(const JointMovePlan& plan, double rate_hz) {
  const RobotModel& model = plan.model;
  if (!torque_limited(model) || !(plan.duration_s > 0.0)) return 1.0;
  const JointVector dq = plan.q1 - plan.q0;
  const JointVector zero = JointVector::Zero(dq.size());
  JointVector q, q_dot, q_ddot, tau, gravity;
  double f2 = 1.0;
  const auto at = [&](const ProfileState& x) {
    q = plan.q0 + x.s * dq;
    q_dot = x.v * dq;
    q_ddot = x.a * dq;
    const DynamicsOptions options = dynamics_options(model);
    inverse_dynamics(model, q, q_dot, q_ddot, options, tau);
    inverse_dynamics(model, q, zero, zero, options, gravity);
    for (Eigen::Index j = 0; j < dq.size(); ++j) {
      const std::optional<double>& T = model.limits[static_cast<std::size_t>(j)].max_torque;
      if (!T) continue;
      f2 = std::max(f2, dynamic_torque_usage(tau(j), gravity(j), *T));
    }
  };
  const auto n = static_cast<std::size_t>(std::ceil(plan.duration_s * std::max(rate_hz, 1.0)));
  ProfileCursor cursor;
  for (std::size_t k = 0; k <= n && std::isfinite(f2); ++k)
    at(evaluate(plan.profile, plan.duration_s * static_cast<double>(k) / static_cast<double>(n), cursor));
  for (const ProfilePiece& piece : plan.profile.pieces) {  // each piece's start, with its own acceleration
    ProfileState x{piece.s0, piece.v0, piece.a0, piece.j};
    if (std::isfinite(f2)) at(x);
  }
  return std::sqrt(f2);
}

Expected<LinearMovePlan> plan_linear_move(const LinearMoveSpec& spec, const MotionSpec& motion) {
  Violations v;
  check_pose(spec.start, "linearMove.start", v);
  check_pose(spec.goal, "linearMove.goal", v);
  for (auto& x : validate_motion(motion)) v.push_back(std::move(x));
  if (!v.empty()) return tl::make_unexpected(v);

  LinearMovePlan plan;
  plan.spec = motion;
  plan.p0 = spec.start.p_WT;
  plan.p1 = spec.goal.p_WT;
  plan.q0 = spec.start.q_WT.normalized();
  plan.q1 = spec.goal.q_WT.normalized();
  if (plan.q0.coeffs().dot(plan.q1.coeffs()) < 0.0) plan.q1.coeffs() = -plan.q1.coeffs();  // the shorter way round
  const Eigen::Vector3d d = plan.p1 - plan.p0;
  plan.length = d.stableNorm();
  if (plan.length > 0.0) plan.direction_W = d / plan.length;  // (6.1) d_hat
  // q1 q0^-1 = exp(theta a / 2) in W, w >= 0 (same hemisphere).
  const Eigen::Quaterniond rel = plan.q1 * plan.q0.conjugate();
  const double sin_half = rel.vec().norm();
  plan.theta = 2.0 * std::atan2(sin_half, std::max(rel.w(), 0.0));
  if (sin_half > 0.0) plan.axis_W = rel.vec() / sin_half;

  const double scale = motion.speed_scale;
  const double distance = plan.length > 0.0 ? plan.length : plan.theta;
  Expected<SpeedProfile> profile = SpeedProfile{};
  if (motion.duration_s > 0.0) {
    const double T = motion.duration_s / scale;
    profile = motion.profile == ProfileShape::kTrapezoidal ? trapezoid_profile(distance, T, motion.ramp_fraction)
                                                           : scurve_profile(distance, T, motion.ramp_fraction);
  } else if (!(plan.length > 0.0)) {
    return tl::make_unexpected(Violations{
        {"motion.durationS",
         std::string(plan.theta > 0.0 ? "is 0 for a pure rotation (the start and goal positions coincide)"
                                      : "is 0 for a move whose start and goal poses coincide") +
             ": give a duration; maxSpeed, maxAcceleration and maxJerk bound the translation only"}});
  } else {
    const double reserve = motion.acceleration_scale;  // Execute's room for speed changes
    double v_lim = *motion.max_speed * scale, a_lim = *motion.max_acceleration * scale * scale * reserve;
    // The tool turns at theta / L per metre (6.2): its angular limits cap the line's speed
    // and acceleration at omega_max L / theta and alpha_max L / theta.
    if (plan.theta > 0.0 && motion.max_angular_speed) {
      v_lim = std::min(v_lim, *motion.max_angular_speed * scale * plan.length / plan.theta);
    }
    if (plan.theta > 0.0 && motion.max_angular_acceleration) {
      a_lim = std::min(a_lim, *motion.max_angular_acceleration * scale * scale * reserve * plan.length / plan.theta);
    }
    profile = motion.profile == ProfileShape::kTrapezoidal
                  ? min_time_trapezoid(plan.length, v_lim, a_lim)
                  : min_time_double_s(plan.length, v_lim, a_lim, *motion.max_jerk * scale * scale * scale * reserve);
  }
  if (!profile) return tl::make_unexpected(prefixed(profile.error(), "motion."));
  plan.profile = std::move(*profile);
  plan.duration_s = motion.duration_s > 0.0 ? motion.duration_s / scale : plan.profile.duration;

  const double v_peak = peak_speed(plan.profile), a_peak = peak_acceleration(plan.profile);
  if (plan.length > 0.0) {
    plan.peak_speed = v_peak;
    plan.peak_acceleration = a_peak;
    plan.peak_angular_speed = plan.theta * (v_peak / plan.length);
    plan.peak_angular_acceleration = plan.theta * (a_peak / plan.length);
  } else {
    plan.peak_angular_speed = v_peak;
    plan.peak_angular_acceleration = a_peak;
  }
  auto samples = move_samples(motion, plan.duration_s, plan.profile,
                              {plan.peak_speed, plan.peak_acceleration, plan.peak_angular_speed,
                               plan.peak_angular_acceleration});
  if (!samples) return tl::make_unexpected(std::move(samples.error()));
  plan.sample_count = *samples;
  return plan;
}

void linear_move_at(const LinearMovePlan& plan, double t, ProfileCursor& cursor, MoveSample& out) {
  const bool at_end = t >= plan.duration_s;
  const ProfileState st = state_at(plan.profile, t, cursor, at_end);
  // Progress sigma in [0, 1] and its rates [1/s, 1/s^2]: over L, or over theta for a pure
  // rotation.
  const double distance = plan.length > 0.0 ? plan.length : plan.theta;
  double sigma = at_end ? 1.0 : 0.0, sigma_dot = 0.0, sigma_ddot = 0.0;
  if (distance > 0.0 && !at_end) {
    sigma = std::clamp(st.s / distance, 0.0, 1.0);
    sigma_dot = st.v / distance;
    sigma_ddot = st.a / distance;
  }
  out.t = t;
  out.u = sigma;
  if (plan.length > 0.0) {
    out.s = at_end ? plan.length : st.s;
    out.p_W = at_end ? plan.p1 : Eigen::Vector3d(plan.p0 + st.s * plan.direction_W);  // (6.1)
    out.v_W = st.v * plan.direction_W;
    out.a_W = st.a * plan.direction_W;
  } else {
    out.s = 0.0;
    out.p_W = at_end ? plan.p1 : plan.p0;
    out.v_W.setZero();
    out.a_W.setZero();
  }
  out.speed = out.v_W.norm();
  // (6.2) SLERP as a rotation about the fixed axis: q(sigma) = exp(sigma theta a / 2) q0,
  // exactly q1 at the end.
  if (at_end) {
    out.q_WT = plan.q1;
  } else if (plan.theta > 0.0 && sigma > 0.0) {
    out.q_WT = Eigen::Quaterniond(Eigen::AngleAxisd(sigma * plan.theta, plan.axis_W) * plan.q0).normalized();
  } else {
    out.q_WT = plan.q0;
  }
  out.omega_W = plan.axis_W * (plan.theta * sigma_dot);    // [rad/s]
  out.alpha_W = plan.axis_W * (plan.theta * sigma_ddot);  // [rad/s^2]
  out.q.resize(0);
  out.q_dot.resize(0);
  out.q_ddot.resize(0);
  out.manipulability = 0.0;
  out.has_joints = false;
}

void linear_move_at(const LinearMovePlan& plan, double t, MoveSample& out) {
  ProfileCursor cursor{plan.profile.pieces.size()};  // forces a binary search
  linear_move_at(plan, t, cursor, out);
}

namespace {
void move_at(const JointMovePlan& plan, double t, ProfileCursor& cursor, MoveSample& out) {
  joint_move_at(plan, t, cursor, out);
}
void move_at(const LinearMovePlan& plan, double t, ProfileCursor& cursor, MoveSample& out) {
  linear_move_at(plan, t, cursor, out);
}
}  // namespace

template <class MovePlan>
MoveSampler<MovePlan>::MoveSampler(const MovePlan& plan) : plan_(&plan) {
  GEOTRAJ_CHECK(plan.sample_count > 0);
  reset();
}

template <class MovePlan>
void MoveSampler<MovePlan>::reset() {
  k_ = 0;
  cursor_ = {};
}

template <class MovePlan>
bool MoveSampler<MovePlan>::next(MoveSample& out) {
  const MovePlan& p = *plan_;
  if (k_ >= p.sample_count) return false;
  move_at(p, grid_time(k_, p.sample_count, p.duration_s, p.spec.cycle_rate_hz), cursor_, out);
  if (k_ > 0 && out.q_WT.coeffs().dot(q_prev_.coeffs()) < 0.0) out.q_WT.coeffs() = -out.q_WT.coeffs();
  q_prev_ = out.q_WT;
  ++k_;
  return true;
}

template <class MovePlan>
void MoveSampler<MovePlan>::at(double t, MoveSample& out) {
  const MovePlan& p = *plan_;
  move_at(p, std::clamp(t, 0.0, p.duration_s), cursor_, out);
  if (k_ > 0 && out.q_WT.coeffs().dot(q_prev_.coeffs()) < 0.0) out.q_WT.coeffs() = -out.q_WT.coeffs();
  q_prev_ = out.q_WT;
  ++k_;
}

template class MoveSampler<JointMovePlan>;
template class MoveSampler<LinearMovePlan>;

}  // namespace geotraj::core
