// Jogging: joint and Cartesian velocity commands, cycle by cycle. See jog.hpp.
#include "core/live/jog.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include <Eigen/SVD>

#include "core/format.hpp"
#include "core/live/rate_profile.hpp"
#include "core/motion/motion.hpp"
#include "core/robot/serial_chain.hpp"

namespace geotraj::core {
namespace {

/// Bisection steps for the braking moment x in [0, h]: h 2^-60 < 1e-18 s, far below any
/// position that rounding can tell apart.
constexpr int kBrakeBisections = 60;

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

std::string join(std::string_view field, std::string_view name) {
  std::string out(field);
  if (!out.empty()) out += '.';
  out += name;
  return out;
}

std::string indexed(std::string_view field, std::string_view name, std::size_t i) {
  return join(field, name) + "[" + std::to_string(i) + "]";
}

}  // namespace

// The chain precomputed once (serial_chain.hpp: kinematics.hpp's forward kinematics and
// Jacobian, Eq. 1.9, and the Jacobian's time derivative, Eqs. 1.10-1.11) and its fixed-size
// workspace, so that a cycle does not allocate.
struct Jogger::Kinematics {
  Kinematics(const RobotModel& model, Eigen::Index n)
      : chain(model), svd(6, n, Eigen::ComputeThinU | Eigen::ComputeThinV) {}
  detail::SerialChain chain;
  Eigen::Matrix3d R_WT = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_WT = Eigen::Vector3d::Zero();
  detail::JointAxes z, o;
  JointJacobian J, J_dot;
  // Of a matrix with both sizes dynamic (bounded, so no allocation): Eigen 3.4's QR
  // preconditioner asserts (and writes past its workspace) on a 6 x n matrix of fixed rows
  // when n < 6, an arm of fewer than six joints.
  Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, 6, static_cast<int>(kMaxJoints)>>
      svd;
};

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
  target_.setZero(n_);
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
  command_ = c;
}

void Jogger::stop() { command_ = JogCommand{}; }

bool Jogger::at_rest() const { return (v_.array() == 0.0).all() && (a_.array() == 0.0).all(); }

double Jogger::stopping_time() const {
  double t = 0.0;
  for (Eigen::Index j = 0; j < n_; ++j) {
    t = std::max(t, RateProfile::plan(v_(j), a_(j), 0.0, a_max_(j), j_max_(j)).duration());
  }
  return t;
}

void Jogger::compute_targets() {
  lambda_ = 0.0;
  if (command_.joints.size() == n_) {
    target_ = command_.joints.cwiseProduct(v_max_);  // c_j v_max_j s
  } else if (command_.twist) {
    const Vector6d& c = *command_.twist;
    Kinematics& k = *kin_;
    Vector6d xi;
    xi << c.head<3>() * options_.max_linear_speed, c.tail<3>() * options_.max_angular_speed;
    if (command_.frame == JogFrame::kTool) {
      xi.head<3>() = k.R_WT * xi.head<3>().eval();
      xi.tail<3>() = k.R_WT * xi.tail<3>().eval();
    }
    // For the cycle's end, where J(q + h q_dot) = J + h J_dot + O(h^2): J q_dot* = xi - h J_dot q_dot.
    k.chain.jacobian_dot(k.p_WT, k.z, k.o, k.J, v_, k.J_dot);  // (1.10, 1.11)
    xi.noalias() -= h_ * (k.J_dot * v_);
    // Damped least squares through the SVD at q: q_dot* = sum_i v_i s_i / (s_i^2 + lambda^2) u_i^T xi.
    const double eps = options_.singular_threshold;
    if (sigma_min_ < eps) {
      const double ratio = sigma_min_ / eps;
      lambda_ = std::sqrt(1.0 - ratio * ratio) * options_.damping;  // lambda^2 = (1 - (sigma_min/eps)^2) lambda_max^2
    }
    const auto& s = k.svd.singularValues();
    Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 6, 1> coefficients = k.svd.matrixU().transpose() * xi;
    for (Eigen::Index i = 0; i < coefficients.size(); ++i) {
      const double denominator = s(i) * s(i) + lambda_ * lambda_;
      coefficients(i) = denominator > 0.0 ? coefficients(i) * s(i) / denominator : 0.0;
    }
    target_.noalias() = k.svd.matrixV() * coefficients;
    // The largest |q_dot*_j| / (v_max_j s): scale the whole vector down when above 1.
    double worst = 0.0;
    for (Eigen::Index j = 0; j < n_; ++j) worst = std::max(worst, std::abs(target_(j)) / v_max_(j));
    if (worst > 1.0) {
      target_ /= worst;
      // Rounding may leave a component a hair above its bound.
      target_ = target_.cwiseMax(-v_max_).cwiseMin(v_max_);
    }
  } else {
    target_.setZero();
  }
  // Joints braking for or held at a limit: no target toward it; released once neither the
  // command nor the velocity points at the limit.
  for (Eigen::Index j = 0; j < n_; ++j) {
    auto& side = limited_[static_cast<std::size_t>(j)];
    if (side == 0) continue;
    if (side * target_(j) <= 0.0 && side * v_(j) <= 0.0) {
      side = 0;
    } else if (side * target_(j) > 0.0) {
      target_(j) = 0.0;
    }
  }
}

void Jogger::step_joint(Eigen::Index j) {
  const double A = a_max_(j), Jk = j_max_(j), h = h_;
  const RateProfile profile = RateProfile::plan(v_(j), a_(j), target_(j), A, Jk);
  RateState end = profile.at(h);
  if (profile.duration() <= h) {
    // At the target within the cycle (the profile pins v there; a gap below its rounding
    // threshold leaves none).
    end.v = target_(j);
    end.a = 0.0;
  }
  const auto i = static_cast<std::size_t>(j);
  if (bounded_[i]) {
    // Would one more cycle of the profile and then braking pass a limit?
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
        const RateState s = profile.at(x);
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
      const RateState s = profile.at(lo);
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
  compute_targets();
  for (Eigen::Index j = 0; j < n_; ++j) step_joint(j);
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

Violations validate_jog_command(const JogCommand& command, std::size_t dof, std::string_view field) {
  Violations v;
  // (The path is written only for a violation: Jogger::command checks every command.)
  const auto fraction = [&](std::string_view name, Eigen::Index i, double x) {
    if (!(std::isfinite(x) && x >= -1.0 && x <= 1.0)) {
      v.push_back({indexed(field, name, static_cast<std::size_t>(i)),
                   "must be a fraction of the maximum speed in [-1, 1], got " + number(x)});
    }
  };
  if (command.joints.size() > 0 && command.twist) {
    v.push_back({std::string(field), "gives both joints and twist: a jog moves joints or the tool, give one"});
  }
  if (command.joints.size() > 0) {
    if (static_cast<std::size_t>(command.joints.size()) != dof) {
      v.push_back({join(field, "joints"), "has " + std::to_string(command.joints.size()) + " values for a robot of " +
                                              std::to_string(dof) + " joints: give one per joint"});
    }
    for (Eigen::Index i = 0; i < command.joints.size(); ++i) fraction("joints", i, command.joints(i));
  }
  if (command.twist) {
    for (Eigen::Index i = 0; i < 6; ++i) fraction("twist", i, (*command.twist)(i));
  }
  return v;
}

Violations validate_jog_limits(const RobotModel& model, const JogOptions& options, std::string_view field) {
  Violations v;
  const auto named = [&](std::size_t i) {
    return "joint " + std::to_string(i) + (i < model.joints.size() ? " (" + model.joints[i].name + ")" : "");
  };
  // The largest jerk bound a ramp may make: the widest ratio of two limits.
  constexpr double kMaxRampJerk = kMaxJointLimit / kMinJointLimit;
  for (std::size_t i = 0; i < model.limits.size(); ++i) {
    const JointLimits& l = model.limits[i];
    const double v_max = l.max_velocity * options.velocity_scale;
    if (!(v_max >= kMinJointLimit)) {
      v.push_back({join(field, "velocityScale"),
                   number(options.velocity_scale) + " makes " + named(i) + "'s jog speed (maxVelocity " +
                       number(l.max_velocity) + " times it) " + number(v_max) + ", below " + number(kMinJointLimit) +
                       ": give a larger scale"});
      break;
    }
  }
  for (std::size_t i = 0; i < model.limits.size(); ++i) {
    const JointLimits& l = model.limits[i];
    if (l.max_jerk) continue;
    const double j_max = l.max_acceleration / options.jerk_ramp_s;
    if (!(j_max > 0.0 && j_max <= kMaxRampJerk)) {
      v.push_back({join(field, "jerkRampS"), number(options.jerk_ramp_s) + " s makes " + named(i) +
                                                 "'s jerk bound (maxAcceleration over it) " + number(j_max) +
                                                 ", outside (0, " + number(kMaxRampJerk) + "]"});
      break;
    }
  }
  return v;
}

Violations validate_jog_options(const JogOptions& options, std::string_view field) {
  Violations v;
  const auto positive = [&](const char* name, double x, const char* unit) {
    if (!(std::isfinite(x) && x > 0.0)) {
      v.push_back({join(field, name), std::string("must be finite and > 0 ") + unit + ", got " + number(x)});
    }
  };
  if (!(std::isfinite(options.cycle_rate_hz) && options.cycle_rate_hz > 0.0 && options.cycle_rate_hz <= kMaxCycleRateHz)) {
    v.push_back({join(field, "cycleRateHz"),
                 "must be in (0, " + number(kMaxCycleRateHz) + "] Hz, got " + number(options.cycle_rate_hz)});
  }
  if (!(std::isfinite(options.velocity_scale) && options.velocity_scale > 0.0 && options.velocity_scale <= 1.0)) {
    v.push_back({join(field, "velocityScale"),
                 "must be a fraction of each joint's maxVelocity in (0, 1], got " + number(options.velocity_scale)});
  }
  positive("maxLinearSpeed", options.max_linear_speed, "[m/s]");
  positive("maxAngularSpeed", options.max_angular_speed, "[rad/s]");
  if (!(std::isfinite(options.damping) && options.damping >= 0.0)) {
    v.push_back({join(field, "damping"), "must be finite and >= 0, got " + number(options.damping)});
  }
  positive("singularThreshold", options.singular_threshold, "(a singular value of the Jacobian)");
  positive("jerkRampS", options.jerk_ramp_s, "[s]");
  return v;
}

}  // namespace geotraj::core
