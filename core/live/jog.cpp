// Jogging: joint and Cartesian velocity commands, cycle by cycle. See jog.hpp.
#include "core/live/jog.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/SVD>

#include "core/live/rate_profile.hpp"
#include "core/robot/serial_chain.hpp"

namespace geotraj::core {
namespace {

/// Bisection steps for the braking moment x in [0, h]: h 2^-60 < 1e-18 s, far below any
/// position that rounding can tell apart.
constexpr int kBrakeBisections = 60;

/// The share of what D's drift leaves of each joint's acceleration and jerk limit that a
/// Cartesian jog's ramp may use: the rest keeps each joint on its reference where D changes
/// beyond its estimate (ramp_limits). A joint jog's D is constant: its ramp uses the whole
/// limits.
constexpr double kCartesianRampShare = 0.8;

/// A Cartesian jog's margin on how far braking carries a joint toward a position limit
/// (relative): D's change beyond D_sigma would otherwise let the prediction come late, and the
/// joint's own braking then stop it ahead of the others (off the line). It comes to rest
/// short of the limit by about this fraction of its braking travel instead.
constexpr double kCartesianBrakeMargin = 0.02;

/// The least room a Cartesian jog's ramp keeps of a joint's acceleration or jerk limit when
/// D's drift would take more (near a singularity, fast): the joint's own profile then keeps
/// its limits (step_joint), off the line.
constexpr double kMinRoom = 0.25;

/// Bound on A_s and J_s [1/s^2, 1/s^3]: a command of a few joint velocities of 1e-300 would
/// otherwise ask for a ramp beyond any double's range.
constexpr double kMaxRampLimit = 1e100;

/// r when c = r a (the same line as a; r < 0: reversed), else 0; |r| below 1e-9 counts as
/// another line (s / r would leave the ramp's range).
template <typename V>
double ratio_along(const V& c, const V& a) {
  const double aa = a.squaredNorm();
  if (!(aa > 0.0)) return 0.0;
  const double r = c.dot(a) / aa;
  if (!(std::abs(r) >= 1e-9)) return 0.0;
  return (c - r * a).norm() <= 1e-12 * c.norm() ? r : 0.0;
}

/// How far braking from (v, a) (RateProfile::plan(v, a, 0, a_max, j_max)) carries a joint in
/// direction `dir` (+1 up, -1 down) [rad or m], >= 0: the braking's end, or, when an
/// acceleration against the motion carries v through zero first (v + a |a| / (2 j) of the
/// other sign), where v crosses zero. That crossing lies in the first phase, whose jerk
/// brings a back toward 0: dir v(t) = v_d + a_d t + j t^2 / 2 = 0 with v_d = dir v > 0,
/// a_d = dir a < 0, at t = (-a_d - sqrt(a_d^2 - 2 j v_d)) / j.
double braking_reach(const RateProfile& braking, double v, double a, double j_max, double dir) {
  double reach = std::max(0.0, dir * braking.distance());
  const double vd = dir * v, ad = dir * a;
  if (vd > 0.0 && ad < 0.0 && ad * ad > 2.0 * j_max * vd) {
    const double t = (-ad - std::sqrt(ad * ad - 2.0 * j_max * vd)) / j_max;
    reach = std::max(reach, t * (vd + t * (ad / 2.0 + t * j_max / 6.0)));
  }
  return reach;
}

}  // namespace

// The chain precomputed once (serial_chain.hpp: kinematics.hpp's forward kinematics and
// Jacobian, Eq. 1.9) and its fixed-size workspace, so that a cycle does not allocate.
struct Jogger::Kinematics {
  Kinematics(const RobotModel& model, Eigen::Index n)
      : chain(model), svd(6, n, Eigen::ComputeThinU | Eigen::ComputeThinV) {}
  detail::SerialChain chain;
  Eigen::Matrix3d R_WT = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_WT = Eigen::Vector3d::Zero();
  detail::JointAxes z, o;
  JointJacobian J;
  // Of a matrix with both sizes dynamic (bounded, so no allocation): Eigen 3.4's QR
  // preconditioner asserts (and writes past its workspace) on a 6 x n matrix of fixed rows
  // when n < 6, an arm of fewer than six joints.
  Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, 6, static_cast<int>(kMaxJoints)>>
      svd;
};

// One joint over one cycle (t [s] from its start): its reference s(t) D + g t + g_dot t^2 / 2
// plus an error profile that brings it back to the reference (to 0, within what the
// reference leaves of the joint's limits), or, when that cannot keep the limits (`ramp`
// null), its own profile to the reference at the cycle's end, within its whole limits.
// Pinned: past the profile's end v is its target.
struct Jogger::JointMotion {
  const Ramp* ramp = nullptr;
  double dir = 0.0, drift = 0.0, drift_rate = 0.0;  // D, g, g_dot
  RateProfile profile;
  double target = 0.0;
  RateState at(double t) const {
    RateState p = profile.at(t);
    if (t >= profile.duration()) {
      p.v = target;
      p.a = 0.0;
    }
    if (ramp == nullptr) return p;
    const RateState s = ramp->at(t);
    const double gx = t * t * (drift / 2.0 + t * drift_rate / 6.0), gv = t * (drift + t * drift_rate / 2.0);
    return {dir * s.x + gx + p.x, dir * s.v + gv + p.v, dir * s.a + drift + t * drift_rate + p.a,
            dir * s.j + drift_rate + p.j};
  }
};

RateState Jogger::Ramp::at(double t) const {
  if (t > brake_at) {
    const double u = t - brake_at;
    RateState s = brake.at(u);
    if (u >= brake.duration()) {
      s.v = 0.0;
      s.a = 0.0;
    }
    s.x += brake_x;
    return s;
  }
  RateState s = follow.at(t);
  if (t >= follow.duration()) {
    s.v = goal;
    s.a = 0.0;
  }
  return s;
}

Jogger::~Jogger() = default;
Jogger::Jogger(Jogger&&) noexcept = default;
Jogger& Jogger::operator=(Jogger&&) noexcept = default;

Jogger::Jogger(const RobotModel& model, JointVector q0, JogOptions options)
    : options_(options),
      h_(1.0 / options.cycle_rate_hz),
      n_(static_cast<Eigen::Index>(model.dof())),
      q_(std::move(q0)),
      kin_(std::make_unique<Kinematics>(model, static_cast<Eigen::Index>(model.dof()))) {
  GEOTRAJ_CHECK(validate_jog_options(options_, "").empty());
  GEOTRAJ_CHECK(n_ > 0 && model.dof() <= kMaxJoints && model.limits.size() == model.dof());
  GEOTRAJ_CHECK(q_.size() == n_);
  GEOTRAJ_CHECK(validate_jog_limits(model, options_, "").empty());
  v_.setZero(n_);
  a_.setZero(n_);
  dir_.setZero(n_);
  slope_.setZero(n_);
  drift_.setZero(n_);
  drift_rate_.setZero(n_);
  v_max_.resize(n_);
  a_max_.resize(n_);
  j_max_.resize(n_);
  q_min_.resize(n_);
  q_max_.resize(n_);
  for (Eigen::Index j = 0; j < n_; ++j) {
    const auto i = static_cast<std::size_t>(j);
    const JointLimits& l = model.limits[i];
    v_max_(j) = l.max_velocity * options_.velocity_scale;
    a_max_(j) = l.max_acceleration;
    j_max_(j) = l.max_jerk ? *l.max_jerk : l.max_acceleration / options_.jerk_ramp_s;
    bounded_[i] = model.joints[i].type != JointType::kContinuous;
    q_min_(j) = l.min_position;
    q_max_(j) = l.max_position;
    GEOTRAJ_CHECK(std::isfinite(q_(j)) && within_position_limits(model.joints[i].type, l, q_(j)));
  }
  update_kinematics();
}

void Jogger::command(const JogCommand& c) {
  GEOTRAJ_CHECK(validate_jog_command(c, static_cast<std::size_t>(n_), "").empty());
  const bool joints = c.joints.size() == n_;
  if (joints ? c.joints.isZero(0.0) : !(c.twist && !c.twist->isZero(0.0))) {
    goal_ = 0.0;  // a release: active_ slows to rest along its line
    return;
  }
  // The same line (c = r active_, the same frame): s is rescaled, so that the reference s D
  // stays where it is and ramps to the new command along the line (through rest if r < 0).
  double r = 0.0;
  if (joints && active_.joints.size() == n_) {
    r = ratio_along(c.joints, active_.joints);
  } else if (!joints && active_.twist && active_.frame == c.frame) {
    r = ratio_along(*c.twist, *active_.twist);
  }
  if (r != 0.0) {
    s_ /= r;
    s_dot_ /= r;
  }
  active_ = c;
  dir_known_ = false;  // D changes with the command, not with q
  goal_ = 1.0;
}

void Jogger::stop() { goal_ = 0.0; }

bool Jogger::at_rest() const { return (v_.array() == 0.0).all() && (a_.array() == 0.0).all(); }

double Jogger::stopping_time() const {
  double t = 0.0;
  double accel = 0.0, jerk = 0.0;
  ramp_limits(s_ > 0.0 ? -1.0 : 1.0, accel, jerk);
  if (jerk > 0.0 && s_ * s_dot_ < 0.0) {
    jerk = std::max(jerk, std::min(kMaxRampLimit, s_dot_ * s_dot_ / (2.0 * std::abs(s_))));  // as plan_ramp
  }
  if ((s_ != 0.0 || s_dot_ != 0.0) && accel > 0.0 && jerk > 0.0) {
    t = RateProfile::plan(s_, s_dot_, 0.0, accel, jerk).duration();
  }
  for (Eigen::Index j = 0; j < n_; ++j) {
    t = std::max(t, RateProfile::plan(v_(j), a_(j), 0.0, a_max_(j), j_max_(j)).duration());
  }
  return t;
}

// A_s and J_s for ds/dt of sign d, from what D's drift leaves of each joint's limits at S =
// max(|s|, 1), the full command's speed or faster (S and not s, so that a stop's limits are
// those of the jog before it and stopping_time() holds). With g = s^2 D_sigma, a joint's
// acceleration ds/dt D + g takes the drift's share only where the two add (d D_j D_sigma_j
// > 0); its jerk d2s/dt2 D + 3 s ds/dt D_sigma + ... always. Times the share, each room at
// least kMinRoom of the limit:
//   A_s = share min_j (a_max_j - [d D_j D_sigma_j > 0] S^2 |D_sigma_j|) / |D_j|
//   J_s = share min_j (j_max_j - 3 S A_s |D_sigma_j|) / |D_j|
// 0 when D = 0 (nothing to ramp).
void Jogger::ramp_limits(double d, double& accel, double& jerk) const {
  const double S = std::max(std::abs(s_), 1.0);
  const double share = cartesian_ ? kCartesianRampShare : 1.0;
  double a = 0.0, j = 0.0;  // max_i |D_i| / room_i
  for (Eigen::Index i = 0; i < n_; ++i) {
    const double drift = d * dir_(i) * slope_(i) > 0.0 ? S * S * std::abs(slope_(i)) : 0.0;
    a = std::max(a, std::abs(dir_(i)) / std::max(a_max_(i) - drift, kMinRoom * a_max_(i)));
  }
  accel = a > 0.0 ? std::min(kMaxRampLimit, share / a) : 0.0;
  for (Eigen::Index i = 0; i < n_; ++i) {
    const double room = std::max(j_max_(i) - 3.0 * S * accel * std::abs(slope_(i)), kMinRoom * j_max_(i));
    j = std::max(j, std::abs(dir_(i)) / room);
  }
  jerk = j > 0.0 ? std::min(kMaxRampLimit, share / j) : 0.0;
}

void Jogger::plan_ramp() {
  lambda_ = 0.0;
  Kinematics& k = *kin_;
  const bool idle = goal_ == 0.0 && s_ == 0.0 && s_dot_ == 0.0;
  const bool cartesian = !idle && active_.joints.size() != n_ && active_.twist.has_value();
  cartesian_ = cartesian;
  slope_.setZero();
  if (idle) {
    dir_.setZero();
  } else if (!cartesian) {
    dir_ = active_.joints.cwiseProduct(v_max_);  // c_j v_max_j s
  } else {
    const JointVector last = dir_;
    const Vector6d& c = *active_.twist;
    Vector6d xi;
    xi << c.head<3>() * options_.max_linear_speed, c.tail<3>() * options_.max_angular_speed;
    if (active_.frame == JogFrame::kTool) {
      xi.head<3>() = k.R_WT * xi.head<3>().eval();
      xi.tail<3>() = k.R_WT * xi.tail<3>().eval();
    }
    const double eps = options_.singular_threshold;
    if (sigma_min_ < eps) {
      const double ratio = sigma_min_ / eps;
      lambda_ = std::sqrt(1.0 - ratio * ratio) * options_.damping;  // lambda^2 = (1 - (sigma_min/eps)^2) lambda_max^2
    }
    // Damped least squares through the SVD at q: D = sum_i v_i s_i / (s_i^2 + lambda^2) u_i^T xi.
    const auto& sv = k.svd.singularValues();
    Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 6, 1> coefficients = k.svd.matrixU().transpose() * xi;
    for (Eigen::Index i = 0; i < coefficients.size(); ++i) {
      const double denominator = sv(i) * sv(i) + lambda_ * lambda_;
      coefficients(i) = denominator > 0.0 ? coefficients(i) * sv(i) / denominator : 0.0;
    }
    dir_.noalias() = k.svd.matrixV() * coefficients;
    // The largest |D_j| / (v_max_j s): scale D down when above 1 (the direction kept).
    double worst = 0.0;
    for (Eigen::Index j = 0; j < n_; ++j) worst = std::max(worst, std::abs(dir_(j)) / v_max_(j));
    if (worst > 1.0) {
      dir_ /= worst;
      // Rounding may leave a component a hair above its bound.
      dir_ = dir_.cwiseMax(-v_max_).cwiseMin(v_max_);
    }
    // D_sigma = dD/dsigma (sigma = int s dt [s], the command's path): D's change over the
    // last cycle (the same command) per unit of the path it covered.
    if (dir_known_ && step_ != 0.0) slope_ = (dir_ - last) / step_;
  }
  // The reference's drift, d(s D)/dt = ds/dt D + s^2 D_sigma: g = s^2 D_sigma and its rate
  // g_dot = 2 s ds/dt D_sigma, fed forward so that s D + g t + g_dot t^2 / 2 reaches
  // s D(q + h q_dot) at the cycle's end to O(h^2), where its twist is the command's.
  drift_ = (s_ * s_) * slope_;
  drift_rate_ = (2.0 * s_ * s_dot_) * slope_;
  dir_known_ = cartesian;
  // Joints braking for or held at a limit: while the command pushes one of them at it, the
  // whole command's goal is 0; released once neither the command nor the velocity points at
  // the limit.
  bool held = false;
  for (Eigen::Index j = 0; j < n_; ++j) {
    auto& side = limited_[static_cast<std::size_t>(j)];
    if (side == 0) continue;
    const double pushes = side * goal_ * dir_(j);
    if (pushes <= 0.0 && side * v_(j) <= 0.0) {
      side = 0;
    } else if (pushes > 0.0) {
      held = true;
    }
  }
  Ramp& r = ramp_;
  r.goal = held ? 0.0 : goal_;
  r.brake_at = std::numeric_limits<double>::infinity();
  r.brake_x = 0.0;
  r.moving = false;
  // The ramp's limits toward its goal and, for a release or a position limit, toward 0
  // (ds/dt of sign d = +1 up, -1 down). Slowing to rest, J_s is at least ds/dt^2 / (2 |s|),
  // the jerk that brings s to rest on 0: limits smaller than the last cycle's (D grown
  // meanwhile) never make the slowing overshoot into a reversal.
  ramp_limits(s_ > 0.0 ? -1.0 : 1.0, r.brake_accel, r.brake_jerk);
  if (r.brake_jerk > 0.0 && s_ * s_dot_ < 0.0) {
    r.brake_jerk = std::max(r.brake_jerk, std::min(kMaxRampLimit, s_dot_ * s_dot_ / (2.0 * std::abs(s_))));
  }
  if (r.goal == 0.0) {
    r.accel = r.brake_accel;
    r.jerk = r.brake_jerk;
  } else {
    ramp_limits(r.goal > s_ ? 1.0 : -1.0, r.accel, r.jerk);
  }
  if (r.accel == 0.0 || r.jerk == 0.0) {
    // Nothing moves with the command (D = 0): s is at its goal at once.
    s_ = r.goal;
    s_dot_ = 0.0;
    r.follow = RateProfile(s_);
    r.lo = r.hi = s_;
    return;
  }
  r.follow = RateProfile::plan(s_, s_dot_, r.goal, r.accel, r.jerk);
  // A position limit ahead: if following the ramp for this cycle and then braking s to 0
  // (with A_s, J_s) would carry a joint past a limit, s brakes from the latest moment x in
  // [0, h] (bisection) at which that stops the joint at or before it, as a joint's own
  // braking does (step_joint): all joints slow together, that one comes to rest on its limit.
  struct Braking {
    RateState s;      // s at x
    double up, down;  // how far braking from there carries int s dt up and down (>= 0)
  };
  const auto braking_from = [&](double x) {
    Braking b{r.at(x), 0.0, 0.0};
    const RateProfile p = RateProfile::plan(b.s.v, b.s.a, 0.0, r.brake_accel, r.brake_jerk);
    b.up = braking_reach(p, b.s.v, b.s.a, r.brake_jerk, 1.0);
    b.down = braking_reach(p, b.s.v, b.s.a, r.brake_jerk, -1.0);
    return b;
  };
  // Past max (dir +1) or below min (dir -1) [rad or m], > 0 when beyond: the joint's
  // reference up to x, then braking, along which it moves by D sigma + D_sigma sigma^2 / 2
  // for the path sigma in [-down, up] (its farthest toward the limit: at an end or where
  // D + D_sigma sigma = 0), for a Cartesian jog with a margin against D's higher terms.
  const double margin = cartesian ? 1.0 + kCartesianBrakeMargin : 1.0;
  const auto overshoot = [&](Eigen::Index j, double x, const Braking& b, double dir) {
    const double D = dir_(j), curve = slope_(j);
    const auto toward = [&](double sigma) { return dir * sigma * (D + curve * sigma / 2.0); };
    double reach = std::max({0.0, toward(b.up), toward(-b.down)});
    if (curve != 0.0 && -D / curve > -b.down && -D / curve < b.up) reach = std::max(reach, toward(-D / curve));
    reach *= margin;
    const double drift = x * x * (drift_(j) / 2.0 + x * drift_rate_(j) / 6.0);
    const double end = q_(j) + D * b.s.x + drift + dir * reach;
    return dir > 0.0 ? end - q_max_(j) : q_min_(j) - end;
  };
  const Braking at_end = braking_from(h_);
  for (Eigen::Index j = 0; j < n_; ++j) {
    if (!bounded_[static_cast<std::size_t>(j)] || dir_(j) == 0.0) continue;
    double dir = 0.0;
    if (overshoot(j, h_, at_end, 1.0) > 0.0) {
      dir = 1.0;
    } else if (overshoot(j, h_, at_end, -1.0) > 0.0) {
      dir = -1.0;
    }
    if (dir == 0.0) continue;
    double lo = 0.0, hi = h_;
    if (overshoot(j, 0.0, braking_from(0.0), dir) <= 0.0) {
      for (int i = 0; i < kBrakeBisections && hi - lo > 0.0; ++i) {
        const double mid = 0.5 * (lo + hi);
        (overshoot(j, mid, braking_from(mid), dir) <= 0.0 ? lo : hi) = mid;
      }
    }
    r.brake_at = std::min(r.brake_at, lo);
    limited_[static_cast<std::size_t>(j)] = static_cast<int>(dir);
  }
  const auto [follow_lo, follow_hi] = r.follow.range();
  r.lo = std::min(follow_lo, r.goal);
  r.hi = std::max(follow_hi, r.goal);
  if (r.brake_at <= h_) {
    const RateState s = r.at(r.brake_at);
    r.brake = RateProfile::plan(s.v, s.a, 0.0, r.brake_accel, r.brake_jerk);
    r.brake_x = s.x;
    const auto [brake_lo, brake_hi] = r.brake.range();
    r.lo = std::min({r.lo, brake_lo, 0.0});
    r.hi = std::max({r.hi, brake_hi, 0.0});
  }
  r.moving = r.follow.duration() > 0.0 || r.brake_at <= h_;
  // At rest at the cycle's end: no drift (it would keep the joints from rest).
  if (r.at(h_).v == 0.0) {
    drift_.setZero();
    drift_rate_.setZero();
  }
}

void Jogger::step_joint(Eigen::Index j) {
  const double A = a_max_(j), Jk = j_max_(j), h = h_, D = dir_(j), g = drift_(j), g_dot = drift_rate_(j);
  const Ramp& ramp = ramp_;
  const RateState s0 = ramp.at(0.0);
  JointMotion motion;
  motion.ramp = &ramp;
  motion.dir = D;
  motion.drift = g;
  motion.drift_rate = g_dot;
  // The joint's difference from its reference, and the difference's rate.
  const double e = v_(j) - s0.v * D, e_dot = a_(j) - (s0.a * D + g);
  // What the reference takes of the joint's limits over the cycle: its acceleration ds/dt D
  // + g + g_dot t, affine in ds/dt and t, with ds/dt within max(A_s, |ds/dt(0)|) and within
  // J_s h of ds/dt(0) (RateProfile), and its jerk d2s/dt2 D + g_dot, |d2s/dt2| <= J_s.
  double rate_lo = s0.a, rate_hi = s0.a;
  const bool brakes = ramp.brake_at <= h;
  const double accel = brakes ? std::max(ramp.accel, ramp.brake_accel) : ramp.accel;
  const double jerk = brakes ? std::max(ramp.jerk, ramp.brake_jerk) : ramp.jerk;
  if (ramp.moving) {
    const double most = std::max(accel, std::abs(s0.a));
    rate_lo = std::max(-most, s0.a - jerk * h);
    rate_hi = std::min(most, s0.a + jerk * h);
  }
  double ramp_a = 0.0;
  for (const double rate : {rate_lo, rate_hi}) {
    ramp_a = std::max({ramp_a, std::abs(rate * D + g), std::abs(rate * D + g + g_dot * h)});
  }
  const double ramp_j = (ramp.moving ? jerk * std::abs(D) : 0.0) + std::abs(g_dot);
  bool own = true;
  if (std::abs(e) <= 1e-14 * v_max_(j) && std::abs(e_dot) <= 1e-14 * A) {
    // On the reference (to rounding: s of a rescaled command times its D is the joint's
    // velocity to a few ulps).
    motion.profile = RateProfile(0.0);
    own = false;
  } else if (A - ramp_a > 0.0 && Jk - ramp_j > 0.0 && std::abs(e_dot) <= A - ramp_a) {
    // |q_ddot| <= ramp_a + (A - ramp_a), |q_dddot| <= ramp_j + (Jk - ramp_j).
    motion.profile = RateProfile::plan(e, e_dot, 0.0, A - ramp_a, Jk - ramp_j);
    own = false;
  }
  if (!own) {
    // |q_dot| within v_max over the cycle (s in [lo, hi]; the error within its range), and
    // at the cycle's end a state from which the joint's own profile can still stop within it
    // (v + a |a| / (2 j_max)).
    const auto [e_lo, e_hi] = motion.profile.range();
    const double peak = std::max(std::abs(ramp.lo), std::abs(ramp.hi)) * std::abs(D) +
                        h * (std::abs(g) + h * std::abs(g_dot) / 2.0) + std::max(std::abs(e_lo), std::abs(e_hi));
    const RateState end = motion.at(h);
    const double rest = end.v + end.a * std::abs(end.a) / (2.0 * Jk);
    // (To rounding: s of a rescaled command times its D is the old velocity to a few ulps.)
    const double bound = v_max_(j) * (1.0 + 1e-14);
    own = !(peak <= bound && std::abs(rest) <= bound);
  }
  if (own) {
    motion.ramp = nullptr;
    motion.target = std::clamp(ramp.at(h).v * D + h * (g + h * g_dot / 2.0), -v_max_(j), v_max_(j));
    motion.profile = RateProfile::plan(v_(j), a_(j), motion.target, A, Jk);
  }
  RateState end = motion.at(h);
  const auto i = static_cast<std::size_t>(j);
  if (bounded_[i]) {
    // Would one more cycle of the motion and then braking pass a limit?
    const RateProfile braking = RateProfile::plan(end.v, end.a, 0.0, A, Jk);
    double dir = 0.0;
    if (q_(j) + end.x + braking_reach(braking, end.v, end.a, Jk, 1.0) > q_max_(j)) {
      dir = 1.0;
    } else if (q_(j) + end.x - braking_reach(braking, end.v, end.a, Jk, -1.0) < q_min_(j)) {
      dir = -1.0;
    }
    if (dir != 0.0) {
      // The latest x in [0, h] from which braking stops at or before the limit:
      // f(x) = dir x_P(x) + reach(P(x)) - margin <= 0, f(0) <= 0 (the last cycle's check).
      const double margin = dir > 0.0 ? q_max_(j) - q_(j) : q_(j) - q_min_(j);
      const auto overshoot = [&](double x) {
        const RateState s = motion.at(x);
        const RateProfile b = RateProfile::plan(s.v, s.a, 0.0, A, Jk);
        return dir * s.x + braking_reach(b, s.v, s.a, Jk, dir) - margin;
      };
      double lo = 0.0, hi = h;
      if (overshoot(0.0) <= 0.0) {
        for (int k = 0; k < kBrakeBisections && hi - lo > 0.0; ++k) {
          const double mid = 0.5 * (lo + hi);
          (overshoot(mid) <= 0.0 ? lo : hi) = mid;
        }
      }
      const RateState s = motion.at(lo);
      const RateProfile b = RateProfile::plan(s.v, s.a, 0.0, A, Jk);
      end = b.at(h - lo);
      end.x += s.x;
      if (b.duration() <= h - lo) {
        end.v = 0.0;
        end.a = 0.0;
      }
      limited_[i] = static_cast<int>(dir);
    }
  }
  q_(j) += end.x;
  v_(j) = end.v;
  a_(j) = end.a;
  if (bounded_[i]) q_(j) = std::clamp(q_(j), q_min_(j), q_max_(j));  // against rounding
}

void Jogger::update_kinematics() {
  Kinematics& k = *kin_;
  k.chain.jacobian(q_, k.R_WT, k.p_WT, k.z, k.o, k.J);  // (1.9)
  k.svd.compute(k.J, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const auto& s = k.svd.singularValues();
  sigma_min_ = s.size() > 0 ? s(s.size() - 1) : 0.0;  // sorted, largest first
}

void Jogger::next(JogSample& out) {
  plan_ramp();
  for (Eigen::Index j = 0; j < n_; ++j) step_joint(j);
  const RateState s = ramp_.at(h_);
  s_ = s.v;
  s_dot_ = s.a;
  step_ = s.x;
  update_kinematics();
  ++cycles_;
  out.t = static_cast<double>(cycles_) * h_;
  out.q = q_;
  out.q_dot = v_;
  out.q_ddot = a_;
  out.X_WT.setIdentity();
  out.X_WT.linear() = kin_->R_WT;
  out.X_WT.translation() = kin_->p_WT;
  out.twist_W.noalias() = kin_->J * v_;  // (1.8)
  out.damping = lambda_;
  out.sigma_min = sigma_min_;
  out.limited.reset();
  for (Eigen::Index j = 0; j < n_; ++j) out.limited[static_cast<std::size_t>(j)] = limited_[static_cast<std::size_t>(j)] != 0;
  out.at_rest = at_rest();
}

}  // namespace geotraj::core
