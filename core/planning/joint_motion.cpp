// Joint tracking of a Cartesian motion and its report. See joint_motion.hpp.
#include "core/planning/joint_motion.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "core/error.hpp"
#include "core/robot/serial_chain.hpp"

namespace geotraj::core {

using Eigen::Matrix3d;
using Eigen::Vector3d;

CartesianState cartesian_state(const Path& path, const OrientationPlan& orientation, const MotionSample& sample) {
  const double u_local = sample.u - static_cast<double>(sample.segment);
  const OrientationSample o =
      orientation_at(orientation, path, sample.segment, u_local, sample.s, sample.speed, sample.s_ddot);
  CartesianState x;
  x.t = sample.t;
  x.s = sample.s;
  x.s_dot = sample.speed;
  x.s_ddot = sample.s_ddot;
  x.X_WT.linear() = o.q_WT.toRotationMatrix();
  x.X_WT.translation() = sample.p_W;
  x.v_WT = sample.v_W;
  x.a_WT = sample.a_W;
  x.omega_WT = o.omega_W;
  x.alpha_WT = o.alpha_W;
  return x;
}

bool PathMotionSource::state_at(double t, CartesianState& x) {
  scratch_ = sampler_;
  scratch_.at(t, sample_);
  x = cartesian_state(*path_, *orientation_, sample_);
  return true;
}

void roll_about_tool_axis(CartesianState& x, double phi, double phi_dot, double phi_ddot) {
  Matrix3d R = x.X_WT.linear();
  turn_about_tool_axis(R, x.omega_WT, x.alpha_WT, phi, phi_dot, phi_ddot);
  x.X_WT.linear() = R;
}

void apply_roll(const JointReference* roll, CartesianState& x) {
  if (roll == nullptr) return;
  JointVector phi(1), phi_dot(1), phi_ddot(1);
  roll->at(x.t, phi, phi_dot, phi_ddot);
  roll_about_tool_axis(x, phi(0), phi_dot(0), phi_ddot(0));
}

// ---------------------------------------------------------------------------------------
// JointTracker

// The residual [m] and [rad] the tracker polishes each converged sample towards: 1000
// rounding errors of a metre-sized arm's forward kinematics.
constexpr double kTrackingPolish = 1e-12;

struct JointTracker::State {
  State(const RobotModel& m, const JointVector& seed, const IkOptions& o)
      : model(&m), options(o), polish(o), chain(m), bounds(m), seed_q(seed) {
    polish.position_tolerance = std::min(o.position_tolerance, kTrackingPolish);
    polish.orientation_tolerance = std::min(o.orientation_tolerance, kTrackingPolish);
    polish.max_iterations = 2;
  }

  const RobotModel* model;
  IkOptions options;
  IkOptions polish;  // the polishing step's tolerances (kTrackingPolish)
  detail::SerialChain chain;
  detail::JointBounds bounds;
  detail::NewtonWorkspace ws;
  JointVector seed_q;
  bool first = true;
  // The last good sample.
  double t_prev = 0.0;
  JointVector q_prev, q_dot_prev, q_ddot_prev;
  Vector3d p_prev = Vector3d::Zero();
  // The last attempt: its tool position (FK at its q) and the Newton correction of the
  // predictor (largest |q_j - q_pred,j|; 0 for a cold solve).
  Vector3d p_attempt = Vector3d::Zero();
  double correction = 0.0;
  // follow(): the last good sample before the walk (the midpoint certificate's start, and
  // where a walk that fails starts again).
  double t_walk = 0.0;
  JointVector q_walk, qd_walk, qdd_walk;
  Vector3d p_walk = Vector3d::Zero();
  // Joints chosen ahead (set_reference), and their state at the attempt's time.
  const JointReference* reference = nullptr;
  JointVector ref_q, ref_qd, ref_qdd;
  // Scratch.
  JointVector q_guess, z, xi;
  JointJacobian J_dot;
};

JointTracker::JointTracker(const RobotModel& model, const JointVector& q_seed, const IkOptions& options)
    : state_(std::make_unique<State>(model, q_seed, options)) {
  GEOTRAJ_CHECK(q_seed.size() == static_cast<Eigen::Index>(model.dof()));
}

JointTracker::~JointTracker() = default;
JointTracker::JointTracker(JointTracker&&) noexcept = default;
JointTracker& JointTracker::operator=(JointTracker&&) noexcept = default;

void JointTracker::set_reference(const JointReference* reference) {
  GEOTRAJ_CHECK(reference == nullptr || reference->samples().front().size() == state_->chain.dof());
  state_->reference = reference;
}

void JointTracker::reset(const JointVector& q_seed) {
  GEOTRAJ_CHECK(q_seed.size() == state_->chain.dof());
  state_->seed_q = q_seed;
  state_->first = true;
}

bool JointTracker::track(const CartesianState& x, JointSample& out) {
  if (!attempt(x, out)) return false;
  commit(x, out);
  return true;
}

FollowResult JointTracker::follow(const CartesianState& x, CartesianSource& between, JointSample& out,
                                  const ContinuationRule& rule) {
  State& st = *state_;
  if (st.first || st.chain.dof() < 6) {
    const bool ok = track(x, out);
    return FollowResult{ok, 0, false, ok ? 0.0 : x.t};
  }
  st.t_walk = st.t_prev;
  st.q_walk = st.q_prev;
  st.qd_walk = st.q_dot_prev;
  st.qdd_walk = st.q_ddot_prev;
  st.p_walk = st.p_prev;
  const double t_end = x.t;
  const double min_step = rule.min_fraction * (t_end - st.t_prev);
  double t_good = st.t_prev, step = t_end - t_good;
  FollowResult result;
  CartesianState x_try;
  for (;;) {
    const bool at_end = !(step < t_end - t_good);
    const double t_try = at_end ? t_end : t_good + step;
    if (!at_end && !between.state_at(t_try, x_try)) {
      out.converged = false;
      return FollowResult{false, result.substeps, false, t_try};
    }
    const CartesianState& target = at_end ? x : x_try;
    const bool converged = attempt(target, out);
    const bool last_try = !(step > min_step);
    if (converged && (last_try || (out.midpoint_deviation <= rule.branch_tolerance &&
                                   st.correction <= rule.max_correction))) {
      commit(target, out);
      if (at_end) break;
      t_good = t_try;  // accepted: on from here, in a stride twice as long
      ++result.substeps;
      step *= 2.0;
      continue;
    }
    if (!last_try) {
      step = 0.5 * std::min(step, t_end - t_good);
      continue;
    }
    // The smallest stride does not converge (a singularity the branch crosses with unbounded
    // joint rates, or the workspace's edge): the sample in one stride from the last state
    // accepted, else from the last good sample (what track() does), the midpoint certificate
    // then telling whether it stayed on the branch.
    if (!at_end && attempt(x, out)) {
      commit(x, out);
      result.jumped = true;
      break;
    }
    if (result.substeps > 0) {  // from the last good sample
      st.t_prev = st.t_walk;
      st.q_prev = st.q_walk;
      st.q_dot_prev = st.qd_walk;
      st.q_ddot_prev = st.qdd_walk;
      st.p_prev = st.p_walk;
      if (attempt(x, out)) {
        commit(x, out);
        result.substeps = 0;
        result.jumped = true;
        break;
      }
    }
    out.converged = false;
    return FollowResult{false, result.substeps, false, t_try};
  }
  if (result.substeps > 0) {  // the certificate of the interval streamed, not of the last stride
    st.q_guess = 0.5 * (st.q_walk + out.q);
    Matrix3d R_mid;
    Vector3d p_mid;
    st.chain.pose(st.q_guess, R_mid, p_mid);
    out.midpoint_deviation = (p_mid - 0.5 * (st.p_walk + st.p_prev)).norm();
  }
  result.converged = true;
  return result;
}

bool JointTracker::attempt(const CartesianState& x, JointSample& out) {
  State& st = *state_;
  const Eigen::Index n = st.chain.dof();
  const Matrix3d R_target = x.X_WT.linear();
  const Vector3d p_target = x.X_WT.translation();
  detail::NewtonWorkspace& ws = st.ws;
  out.midpoint_deviation = 0.0;
  out.manipulability = 0.0;
  out.q_dot.setZero(n);
  out.q_ddot.setZero(n);

  // Positions: a cold solve on the first sample, else the Newton projection of the predictor.
  detail::NewtonOutcome ik;
  st.correction = 0.0;
  if (n < 6) {  // a general pose has no solution (ik.hpp)
    out.q = st.first ? st.seed_q : st.q_prev;
    st.chain.pose(out.q, ws.R, ws.p);
    ik.position_error = (p_target - ws.p).norm();
    ik.orientation_error = detail::rotation_vector(R_target * ws.R.transpose()).norm();
  } else if (st.first) {
    ik = detail::solve_cold(st.chain, st.bounds, R_target, p_target, st.seed_q, st.options, out.q, ws);
  } else {
    const double dt = x.t - st.t_prev;  // [s]
    if (st.reference) {
      if (st.reference->over() == ReferenceParameter::kArcLength) {
        // q_dot = q_s s_dot, q_ddot = q_ss s_dot^2 + q_s s_ddot (ref_qd holds q_s first).
        st.reference->at(x.s, st.ref_q, st.ref_qd, st.ref_qdd);
        st.ref_qdd *= x.s_dot * x.s_dot;
        st.ref_qdd += x.s_ddot * st.ref_qd;
        st.ref_qd *= x.s_dot;
      } else {
        st.reference->at(x.t, st.ref_q, st.ref_qd, st.ref_qdd);
      }
      st.q_guess = st.ref_q;
    } else {
      st.q_guess = st.q_prev + st.q_dot_prev * dt + st.q_ddot_prev * (0.5 * dt * dt);
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      st.q_guess(i) = std::clamp(st.q_guess(i), st.bounds.lo[k], st.bounds.hi[k]);
    }
    out.q = st.q_guess;
    ik = detail::newton(st.chain, st.bounds, R_target, p_target, st.options, false, out.q, ws);
    if (!ik.converged) {  // the predictor left the basin (e.g. a jump in the input): from q_prev
      out.q = st.q_prev;
      const int first_iterations = ik.iterations;
      ik = detail::newton(st.chain, st.bounds, R_target, p_target, st.options, false, out.q, ws);
      ik.iterations += first_iterations;
    }
    st.correction = (out.q - st.q_guess).cwiseAbs().maxCoeff();
  }
  // Polish: up to two more Newton steps towards kTrackingPolish. The IK tolerance (1e-9) lets
  // a sample's joints sit anywhere in that band, and differences of streamed joints amplify
  // it: a second difference at 10 kHz by 4 / dt^2 = 4e8 (0.4 rad/s^2 from 1e-9 rad). Newton
  // converges quadratically here, so one step usually suffices; a step that does not improve
  // is undone (the sample keeps the converged joints).
  if (ik.converged && n >= 6 &&
      (ik.position_error > st.polish.position_tolerance || ik.orientation_error > st.polish.orientation_tolerance)) {
    st.q_guess = out.q;
    const detail::NewtonOutcome polished =
        detail::newton(st.chain, st.bounds, R_target, p_target, st.polish, false, out.q, ws);
    if (polished.position_error <= ik.position_error && polished.orientation_error <= ik.orientation_error) {
      ik.position_error = polished.position_error;
      ik.orientation_error = polished.orientation_error;
      ik.iterations += polished.iterations;
    } else {
      out.q = st.q_guess;  // and ws back at it (converged: no iteration)
      (void)detail::newton(st.chain, st.bounds, R_target, p_target, st.options, false, out.q, ws);
    }
  }
  out.converged = ik.converged;
  out.iterations = ik.iterations;
  out.position_error = ik.position_error;
  out.orientation_error = ik.orientation_error;
  if (!out.converged) return false;

  // Velocities and accelerations at q (ws holds J, the axes and the pose there), first with
  // every joint, then, if a joint sits at a limit and would leave it, with that joint held
  // (W_ii = 0: the reduced arm J W, the same formulas), as the positions are projected.
  const JointJacobian& J = ws.J;
  out.manipulability = detail::factor(J, nullptr, ws);
  Vector6d twist, accel;
  twist << x.v_WT, x.omega_WT;
  accel << x.a_WT, x.alpha_WT;
  const double speed = x.v_WT.norm();                                                // |v| [m/s]
  const double speed_dot = speed > 0.0 ? x.v_WT.dot(x.a_WT) / speed : x.a_WT.norm();  // d|v|/dt [m/s^2]
  const double k = n > 6 ? st.options.limit_avoidance_gain : 0.0;                     // [rad^2/m]
  // The reference's velocity and acceleration as the null-space term (from the second
  // sample on: the first is the cold solve the reference starts from).
  const bool referenced = st.reference != nullptr && !st.first && n > 6;
  std::array<bool, kMaxJoints> active{};
  active.fill(true);
  auto rates = [&] {  // ws.llt holds J W J^T
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto j = static_cast<std::size_t>(i);
      const double r = st.bounds.range[j];
      const double grad = r > 0.0 ? 2.0 * (out.q(i) - st.bounds.mid[j]) / (r * r) : 0.0;  // grad H_i [1/rad]
      st.z(i) = !active[j] ? 0.0 : referenced ? st.ref_qd(i) : -k * speed * grad;          // [rad/s]
    }
    const Vector6d w = ws.llt.solve(twist - J * st.z);  // (J W J^T)^-1 ([v; omega] - J z)
    out.q_dot.noalias() = J.transpose() * w;
    for (Eigen::Index i = 0; i < n; ++i) {
      out.q_dot(i) = active[static_cast<std::size_t>(i)] ? out.q_dot(i) + st.z(i) : 0.0;  // J^+ [v; omega] + N z (1.8)
    }
    st.chain.jacobian_dot(ws.p, ws.z, ws.o, J, out.q_dot, st.J_dot);
    st.xi.noalias() = st.J_dot.transpose() * w;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto j = static_cast<std::size_t>(i);
      const double r = st.bounds.range[j];
      if (!active[j]) {
        st.xi(i) = 0.0;
        continue;
      }
      if (referenced) {
        st.xi(i) += st.ref_qdd(i);  // + z_dot_i [rad/s^2]
      } else if (r > 0.0) {
        const double grad = 2.0 * (out.q(i) - st.bounds.mid[j]) / (r * r);
        st.xi(i) -= k * (speed_dot * grad + speed * 2.0 * out.q_dot(i) / (r * r));  // + z_dot_i [rad/s^2]
      }
    }
    // xi = J_dot^T w + z_dot: the null-space part of d/dt q_dot
    const Vector6d b = accel - st.J_dot * out.q_dot;  // [a; alpha] - J_dot q_dot  (1.10)
    const Vector6d w2 = ws.llt.solve(b - J * st.xi);
    out.q_ddot.noalias() = J.transpose() * w2;
    for (Eigen::Index i = 0; i < n; ++i) {
      out.q_ddot(i) = active[static_cast<std::size_t>(i)] ? out.q_ddot(i) + st.xi(i) : 0.0;  // J^+ b + N xi
    }
  };
  st.z.resize(n);
  st.xi.resize(n);
  rates();
  int held = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto j = static_cast<std::size_t>(i);
    active[j] = !((out.q(i) <= st.bounds.lo[j] && out.q_dot(i) < 0.0) ||
                  (out.q(i) >= st.bounds.hi[j] && out.q_dot(i) > 0.0));
    held += active[j] ? 0 : 1;
  }
  if (held > 0 && n - held >= 6) {
    detail::factor(J, &active, ws);
    rates();
  }

  // Branch certificate: the joint-space midpoint against the Cartesian chord's midpoint.
  const Vector3d p = ws.p;
  if (!st.first) {
    st.q_guess = 0.5 * (st.q_prev + out.q);
    Matrix3d R_mid;
    Vector3d p_mid;
    st.chain.pose(st.q_guess, R_mid, p_mid);
    out.midpoint_deviation = (p_mid - 0.5 * (st.p_prev + p)).norm();
  }
  st.p_attempt = p;
  return true;
}

void JointTracker::commit(const CartesianState& x, const JointSample& out) {
  State& st = *state_;
  st.first = false;
  st.t_prev = x.t;
  st.q_prev = out.q;
  st.q_dot_prev = out.q_dot;
  st.q_ddot_prev = out.q_ddot;
  st.p_prev = st.p_attempt;
}

// ---------------------------------------------------------------------------------------
// JointReportBuilder

JointReportBuilder::JointReportBuilder(const RobotModel& model, double branch_tolerance, double ik_position_tolerance)
    : model_(&model), branch_tolerance_(branch_tolerance), ik_position_tolerance_(ik_position_tolerance) {
  GEOTRAJ_CHECK(model.limits.size() == model.dof());
  const std::size_t n = model.dof();
  report_.joints.resize(n);
  report_.violations.reserve(n * kKinds);  // at most one per (joint, kind): add() never allocates
  reported_.assign(n * kKinds, false);
  q_prev_ = JointVector::Zero(static_cast<Eigen::Index>(n));  // add() assigns, never allocates
  q_dot_prev_ = JointVector::Zero(static_cast<Eigen::Index>(n));
  q_ddot_prev_ = JointVector::Zero(static_cast<Eigen::Index>(n));
  jerk_ = JointVector::Zero(static_cast<Eigen::Index>(n));
  report_.binding.reserve(kMaxBindingStretches);  // add() never allocates
  constexpr double inf = std::numeric_limits<double>::infinity();
  report_.tightest_position.kind = LimitKind::kPosition;
  report_.tightest_position.margin = inf;
  report_.tightest_velocity.kind = LimitKind::kVelocity;
  report_.tightest_velocity.margin = inf;
  report_.tightest_acceleration.kind = LimitKind::kAcceleration;
  report_.tightest_acceleration.margin = inf;
}

void JointReportBuilder::record(LimitKind kind, std::size_t joint, std::size_t sample, double t, double value,
                                double limit, double margin) {
  const std::size_t key = joint * kKinds + static_cast<std::size_t>(kind);
  if (reported_[key]) return;  // the first sample of the (joint, kind) only
  reported_[key] = true;
  report_.violations.push_back(LimitEvent{kind, joint, sample, t, value, limit, margin});
}

void JointReportBuilder::record_held(std::size_t sample, double t, const JointVector& q, double range_fraction) {
  for (std::size_t j = 0; j < model_->dof(); ++j) {
    if (model_->joints[j].type == JointType::kContinuous) continue;
    const JointLimits& lim = model_->limits[j];
    const double qj = q(static_cast<Eigen::Index>(j));
    const bool above = lim.max_position - qj < qj - lim.min_position;
    const double bound = above ? lim.max_position : lim.min_position;
    const double margin = std::min(qj - lim.min_position, lim.max_position - qj);
    const double near = std::max(kLimitTolerance * std::max(1.0, std::abs(bound)),
                                 range_fraction * (lim.max_position - lim.min_position));
    if (margin <= near) {
      record(LimitKind::kPosition, j, sample, t, qj, bound, margin);
    }
  }
}

namespace {

// Before an IK failure, a joint this close to its limit (a fraction of its range) in the
// last good sample is named as the likely cause: the Newton steps are projected onto the
// limits, and the next pose needed more of its range (the PA-10's elbow 0.8 mrad from its
// limit on the thesis's path C, smoothest reading).
constexpr double kNearLimitBeforeIk = 0.01;

// The order of one sample's events: a joint at (or past) its position limit first, the
// cause of what follows (a joint held at its limit makes the others race, or the IK fail).
int cause_rank(LimitKind kind) {
  switch (kind) {
    case LimitKind::kPosition: return 0;
    case LimitKind::kBranch: return 1;
    case LimitKind::kVelocity: return 2;
    case LimitKind::kAcceleration: return 3;
    case LimitKind::kJerk: return 4;
    case LimitKind::kTorque: return 5;
    case LimitKind::kIk: return 6;
  }
  return 7;
}

// Stable insertion sort of [first, last) by cause_rank (no allocation, unlike stable_sort).
void order_by_cause(std::vector<LimitEvent>::iterator first, std::vector<LimitEvent>::iterator last) {
  const auto before = [](const LimitEvent& a, const LimitEvent& b) { return cause_rank(a.kind) < cause_rank(b.kind); };
  for (auto it = first; it != last; ++it) std::rotate(std::upper_bound(first, it, *it, before), it, it + 1);
}

}  // namespace

void JointReportBuilder::add(std::size_t sample, double t, double s_path, const JointSample& s,
                             const CartesianState* tool) {
  JointMotionReport& r = report_;
  ++r.samples;
  r.max_position_error = std::max(r.max_position_error, s.position_error);
  r.max_orientation_error = std::max(r.max_orientation_error, s.orientation_error);
  if (!s.converged) {
    // A joint at its limit in the last good sample first: the tracker held it there, and the
    // others could not follow the tool without it.
    if (has_prev_) record_held(sample_prev_, t_prev_, q_prev_, kNearLimitBeforeIk);
    record(LimitKind::kIk, 0, sample, t, s.position_error, ik_position_tolerance_,
           ik_position_tolerance_ - s.position_error);
    has_prev_ = false;
    return;  // q, q_dot, q_ddot of a failed sample are not a motion
  }
  const std::size_t first_new = r.violations.size();
  ++r.converged_samples;
  if (s.midpoint_deviation > r.max_midpoint_deviation) {
    r.max_midpoint_deviation = s.midpoint_deviation;
    r.max_midpoint_deviation_t = t;
  }
  if (s.midpoint_deviation > branch_tolerance_) {
    record(LimitKind::kBranch, 0, sample, t, s.midpoint_deviation, branch_tolerance_,
           branch_tolerance_ - s.midpoint_deviation);
  }
  if (s.manipulability < r.min_manipulability) {
    r.min_manipulability = s.manipulability;
    r.min_manipulability_t = t;
  }
  const std::size_t n = model_->dof();
  GEOTRAJ_CHECK(static_cast<std::size_t>(s.q.size()) == n && static_cast<std::size_t>(s.q_dot.size()) == n &&
                static_cast<std::size_t>(s.q_ddot.size()) == n);
  for (std::size_t j = 0; j < n; ++j) {
    const auto i = static_cast<Eigen::Index>(j);
    const JointLimits& lim = model_->limits[j];
    JointUsage& u = r.joints[j];
    const double q = s.q(i), v = std::abs(s.q_dot(i));
    double a = std::abs(s.q_ddot(i));
    if (has_prev_ && t > t_prev_) {  // the mean acceleration over the step: a velocity step shows here
      const double a_step = std::abs(s.q_dot(i) - q_dot_prev_(i)) / (t - t_prev_);
      if (a_step > lim.max_acceleration * (1.0 + kStepTolerance)) a = std::max(a, a_step);
    }
    u.min_position = std::min(u.min_position, q);
    u.max_position = std::max(u.max_position, q);
    u.peak_velocity = std::max(u.peak_velocity, v);
    u.peak_acceleration = std::max(u.peak_acceleration, a);
    u.velocity_usage = u.peak_velocity / lim.max_velocity;
    u.acceleration_usage = u.peak_acceleration / lim.max_acceleration;

    // Position: distance to the nearer limit (negative outside); a continuous joint has none.
    if (model_->joints[j].type != JointType::kContinuous) {
    const bool above = lim.max_position - q < q - lim.min_position;
    const double bound = above ? lim.max_position : lim.min_position;
    const double margin_p = std::min(q - lim.min_position, lim.max_position - q);
    u.position_margin = std::min(u.position_margin, margin_p);
    if (margin_p < r.tightest_position.margin) {
      r.tightest_position = LimitEvent{LimitKind::kPosition, j, sample, t, q, bound, margin_p};
    }
    if (margin_p < -kLimitTolerance * std::max(1.0, std::abs(bound))) {
      record(LimitKind::kPosition, j, sample, t, q, bound, margin_p);
    }
    }

    const double margin_v = lim.max_velocity - v;
    if (margin_v < r.tightest_velocity.margin) {
      r.tightest_velocity = LimitEvent{LimitKind::kVelocity, j, sample, t, v, lim.max_velocity, margin_v};
    }
    if (margin_v < -kLimitTolerance * lim.max_velocity) {
      record(LimitKind::kVelocity, j, sample, t, v, lim.max_velocity, margin_v);
    }

    const double margin_a = lim.max_acceleration - a;
    if (margin_a < r.tightest_acceleration.margin) {
      r.tightest_acceleration = LimitEvent{LimitKind::kAcceleration, j, sample, t, a, lim.max_acceleration, margin_a};
    }
    if (margin_a < -kLimitTolerance * lim.max_acceleration) {
      record(LimitKind::kAcceleration, j, sample, t, a, lim.max_acceleration, margin_a);
    }

    // Jerk, where the model gives a limit: the mean over the step (an acceleration step of a
    // trapezoid shows as its size times the rate).
    jerk_(i) = has_prev_ && t > t_prev_ ? std::abs(s.q_ddot(i) - q_ddot_prev_(i)) / (t - t_prev_) : 0.0;
    if (lim.max_jerk && has_prev_ && t > t_prev_) {
      const double jerk = jerk_(i);
      if (jerk > *lim.max_jerk * (1.0 + kStepTolerance)) {
        record(LimitKind::kJerk, j, sample, t, jerk, *lim.max_jerk, *lim.max_jerk - jerk);
      }
    }

    // Torque, where the sampler gave one (a model with mass properties).
    if (s.tau.size() == s.q.size()) {
      r.torques = true;
      const double tau = std::abs(s.tau(i));
      u.peak_torque = std::max(u.peak_torque, tau);
      if (lim.max_torque) {
        u.torque_usage = u.peak_torque / *lim.max_torque;
        if (tau > *lim.max_torque * (1.0 + kLimitTolerance))
          record(LimitKind::kTorque, j, sample, t, tau, *lim.max_torque, *lim.max_torque - tau);
      }
    }
  }
  if (r.violations.size() > first_new) {
    // A limit broken here: a joint at its position limit in this sample is named as well,
    // and the sample's events go in causal order (a position limit before the acceleration
    // it forces).
    record_held(sample, t, s.q, 0.0);
    order_by_cause(r.violations.begin() + static_cast<std::ptrdiff_t>(first_new), r.violations.end());
  }
  q_prev_ = s.q;
  q_dot_prev_ = s.q_dot;
  q_ddot_prev_ = s.q_ddot;
  t_prev_ = t;
  sample_prev_ = sample;
  has_prev_ = true;
  update_binding(sample, t, s_path, s, tool);
}

namespace {

// The tool's Cartesian quantities of the binding kinds at one sample [m/s, m/s^2, rad/s, rad/s^2].
struct ToolValues {
  double speed = 0.0, tangential = 0.0, centripetal = 0.0, angular_speed = 0.0, angular_acceleration = 0.0;
};

ToolValues tool_values(const CartesianState& tool) {
  ToolValues v;
  v.speed = tool.v_WT.norm();
  if (v.speed > 0.0) {
    const Eigen::Vector3d along = tool.v_WT / v.speed;
    const double tangential = tool.a_WT.dot(along);
    v.tangential = std::abs(tangential);
    v.centripetal = (tool.a_WT - tangential * along).norm();
  } else {
    v.tangential = tool.a_WT.norm();  // from rest the acceleration is along the path
  }
  v.angular_speed = tool.omega_WT.norm();
  v.angular_acceleration = tool.alpha_WT.norm();
  return v;
}

// `top` becomes the tool limit whose usage at this sample is the largest, where it passes
// top's.
void take_tool_limits(BindingStretch& top, const ToolValues& values, const CartesianLimits& limits) {
  const auto take = [&top](BindingKind kind, double value, double limit) {
    if (limit > 0.0 && value / limit > top.usage) {
      top.kind = kind, top.joint = 0, top.usage = value / limit, top.value = value, top.limit = limit;
    }
  };
  take(BindingKind::kCartesianSpeed, values.speed, limits.speed);
  take(BindingKind::kTangentialAcceleration, values.tangential, limits.acceleration);
  take(BindingKind::kCentripetalAcceleration, values.centripetal, limits.acceleration);
  take(BindingKind::kAngularSpeed, values.angular_speed, limits.angular_speed);
  take(BindingKind::kAngularAcceleration, values.angular_acceleration, limits.angular_acceleration);
}

// One sample's part of the binding stretches: `top` its most used limit, own(last) its value
// of the current stretch's limit. The stretch goes on (its largest usage kept) unless `top`
// is another limit used more than kUsageHysteresis times as much; at most
// kMaxBindingStretches.
template <class Own>
void extend_binding(std::vector<BindingStretch>& stretches, std::size_t sample, double t, double s_path,
                    BindingStretch top, Own own_value_of) {
  if (!stretches.empty()) {
    BindingStretch& last = stretches.back();
    last.sample_end = sample;
    last.t_end = t;
    last.s_end = s_path;
    const double own_value = own_value_of(last);
    const double own = own_value / last.limit;
    if (own > last.usage) {
      last.usage = own;
      last.value = own_value;
    }
    const bool same = top.kind == last.kind && top.joint == last.joint;
    if (same || top.usage <= kUsageHysteresis * own || stretches.size() == kMaxBindingStretches) return;
  } else if (top.usage == 0.0) {
    return;  // at rest before anything moves
  }
  top.sample_start = top.sample_end = sample;
  top.t_start = top.t_end = t;
  top.s_start = top.s_end = s_path;
  stretches.push_back(top);
}

double tool_value(const ToolValues& v, BindingKind kind) {
  switch (kind) {
    case BindingKind::kCartesianSpeed: return v.speed;
    case BindingKind::kTangentialAcceleration: return v.tangential;
    case BindingKind::kCentripetalAcceleration: return v.centripetal;
    case BindingKind::kAngularSpeed: return v.angular_speed;
    case BindingKind::kAngularAcceleration: return v.angular_acceleration;
    default: return 0.0;
  }
}

}  // namespace

void JointReportBuilder::update_binding(std::size_t sample, double t, double s_path, const JointSample& s,
                                        const CartesianState* tool) {
  // The most used limit at this sample: the joints', and the tool's where they are given.
  BindingStretch top;
  const auto take = [&top](BindingKind kind, std::size_t joint, double value, double limit) {
    if (limit > 0.0 && value / limit > top.usage) {
      top.kind = kind, top.joint = joint, top.usage = value / limit, top.value = value, top.limit = limit;
    }
  };
  for (std::size_t j = 0; j < model_->dof(); ++j) {
    const auto i = static_cast<Eigen::Index>(j);
    const JointLimits& lim = model_->limits[j];
    take(BindingKind::kJointVelocity, j, std::abs(s.q_dot(i)), lim.max_velocity);
    take(BindingKind::kJointAcceleration, j, std::abs(s.q_ddot(i)), lim.max_acceleration);
    if (lim.max_jerk) take(BindingKind::kJointJerk, j, jerk_(i), *lim.max_jerk);
    if (lim.max_torque && s.tau.size() == s.q.size()) take(BindingKind::kJointTorque, j, std::abs(s.tau(i)), *lim.max_torque);
  }
  const bool cartesian = tool != nullptr && cartesian_.any();
  const ToolValues values = cartesian ? tool_values(*tool) : ToolValues{};
  if (cartesian) take_tool_limits(top, values, cartesian_);
  // The current stretch's own limit at this sample (a Cartesian one counts where this sample
  // has Cartesian limits; a joint move after a path does not measure the path's).
  extend_binding(report_.binding, sample, t, s_path, top, [&](const BindingStretch& last) {
    const auto i = static_cast<Eigen::Index>(last.joint);
    return last.kind == BindingKind::kJointVelocity       ? std::abs(s.q_dot(i))
           : last.kind == BindingKind::kJointAcceleration ? std::abs(s.q_ddot(i))
           : last.kind == BindingKind::kJointJerk         ? jerk_(i)
           : last.kind == BindingKind::kJointTorque       ? (s.tau.size() == s.q.size() ? std::abs(s.tau(i)) : 0.0)
           : cartesian                                   ? tool_value(values, last.kind)
                                                         : 0.0;
  });
}

void ToolBindingBuilder::add(std::size_t sample, double t, double s_path, const CartesianState& tool) {
  BindingStretch top;
  const ToolValues values = limits_.any() ? tool_values(tool) : ToolValues{};
  take_tool_limits(top, values, limits_);
  extend_binding(binding_, sample, t, s_path, top, [&](const BindingStretch& last) {
    return limits_.any() ? tool_value(values, last.kind) : 0.0;
  });
}

}  // namespace geotraj::core
