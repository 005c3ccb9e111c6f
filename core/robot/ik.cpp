// Inverse kinematics: the serial chain evaluator, the projected Newton iteration and cold solves
// with restarts. See ik.hpp and serial_chain.hpp.
#include "core/robot/ik.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#include "core/error.hpp"
#include "core/robot/serial_chain.hpp"

namespace geotraj::core {
namespace detail {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// R * RotX(alpha) (columns 1 and 2 turn about column 0).
inline void rotate_x(Matrix3d& R, double c, double s) {
  const Vector3d y = R.col(1);
  R.col(1) = c * y + s * R.col(2);
  R.col(2) = c * R.col(2) - s * y;
}

// R * RotZ(theta) (columns 0 and 1 turn about column 2).
inline void rotate_z(Matrix3d& R, double c, double s) {
  const Vector3d x = R.col(0);
  R.col(0) = c * x + s * R.col(1);
  R.col(1) = c * R.col(1) - s * x;
}

}  // namespace

namespace {

// A rotation taking z to the unit axis a, exact (entries 0 and +-1) when a is a coordinate
// axis: columns x' (the coordinate axis least along a, made perpendicular), a x x', a.
Matrix3d align_z_with(const Vector3d& a) {
  Eigen::Index k = 0;
  a.cwiseAbs().minCoeff(&k);
  Vector3d x = Vector3d::Unit(k) - a(k) * a;
  x.normalize();
  Matrix3d R;
  R.col(0) = x;
  R.col(1) = a.cross(x);
  R.col(2) = a;
  return R;
}

}  // namespace

SerialChain::SerialChain(const RobotModel& model)
    : n_(static_cast<Eigen::Index>(model.dof())),
      R_base_(model.base.linear()),
      p_base_(model.base.translation()) {
  GEOTRAJ_CHECK(model.dof() <= kMaxJoints);
  // No trigonometry here: a per-call entry point builds a chain for every new model (cached_chain).
  Matrix3d A_prev = Matrix3d::Identity();
  bool prev_z = true;  // A_prev is the identity
  for (std::size_t i = 0; i < model.dof(); ++i) {
    const Joint& j = model.joints[i];
    const bool z = j.axis == Vector3d::UnitZ();
    const Matrix3d A = z ? Matrix3d::Identity() : align_z_with(j.axis.normalized());
    Link& l = links_[i];
    l.revolute = turns(j.type);
    l.p = prev_z ? Vector3d(j.origin.translation()) : Vector3d(A_prev.transpose() * j.origin.translation());
    l.R = prev_z ? Matrix3d(j.origin.linear()) : Matrix3d(A_prev.transpose() * j.origin.linear());
    if (!z) l.R = l.R * A;
    // A rotation whose row 0 ends in 0 is RotX(alpha) RotZ(phi) =
    //   [c_phi -s_phi 0; c_a s_phi c_a c_phi -s_a; s_a s_phi s_a c_phi c_a].
    constexpr double kExact = 1e-14;
    const bool x_then_z = std::abs(l.R(0, 2)) <= kExact;
    const bool phi_zero = std::abs(l.R(0, 1)) <= kExact && l.R(0, 0) > 0.0;
    if (x_then_z && (l.revolute || phi_zero)) {
      l.ca = l.R(2, 2);
      l.sa = -l.R(1, 2);
      l.cphi = l.revolute ? l.R(0, 0) : 1.0;
      l.sphi = l.revolute ? -l.R(0, 1) : 0.0;
      l.phi = !phi_zero;
      l.turn = std::abs(l.sa) <= kExact && l.ca > 0.0 ? Turn::kNone : Turn::kX;
    } else {
      l.turn = Turn::kGeneral;
    }
    A_prev = A;
    prev_z = z;
  }
  const Eigen::Isometry3d end = model.flange * model.tool;
  R_tool_ = A_prev.transpose() * end.linear();
  p_tool_ = A_prev.transpose() * end.translation();
}

namespace {

// Whether two fixed-size arrays of doubles are the same bit for bit.
template <class Fixed>
bool same_bits(const Fixed& a, const Fixed& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * Fixed::SizeAtCompileTime) == 0;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

// What a SerialChain is built from, bit for bit (cached_chain).
struct ChainSource {
  std::size_t n = kMaxJoints + 1;  // no model's: the first call builds
  std::array<JointType, kMaxJoints> type{};
  std::array<Eigen::Matrix4d, kMaxJoints> origin;
  std::array<Vector3d, kMaxJoints> axis;
  Eigen::Matrix4d base, flange, tool;

  bool same(const RobotModel& model) const {
    if (n != model.dof() || !same_bits(base, model.base.matrix()) || !same_bits(flange, model.flange.matrix()) ||
        !same_bits(tool, model.tool.matrix())) {
      return false;
    }
    for (std::size_t i = 0; i < n; ++i) {
      const Joint& j = model.joints[i];
      if (type[i] != j.type || !same_bits(origin[i], j.origin.matrix()) || !same_bits(axis[i], j.axis)) return false;
    }
    return true;
  }
  void record(const RobotModel& model) {
    n = model.dof();
    for (std::size_t i = 0; i < n; ++i) {
      type[i] = model.joints[i].type;
      origin[i] = model.joints[i].origin.matrix();
      axis[i] = model.joints[i].axis;
    }
    base = model.base.matrix();
    flange = model.flange.matrix();
    tool = model.tool.matrix();
  }
};

// What JointBounds are built from, bit for bit (cached_bounds).
struct BoundsSource {
  std::size_t n = kMaxJoints + 1;
  std::array<JointType, kMaxJoints> type{};
  std::array<double, kMaxJoints> lo{}, hi{};

  bool same(const RobotModel& model) const {
    if (n != model.dof() || model.limits.size() != n) return false;
    for (std::size_t i = 0; i < n; ++i) {
      if (type[i] != model.joints[i].type || !same_bits(lo[i], model.limits[i].min_position) ||
          !same_bits(hi[i], model.limits[i].max_position)) {
        return false;
      }
    }
    return true;
  }
  void record(const RobotModel& model) {
    n = model.dof();
    for (std::size_t i = 0; i < n; ++i) {
      type[i] = model.joints[i].type;
      lo[i] = model.limits[i].min_position;
      hi[i] = model.limits[i].max_position;
    }
  }
};

// Value(model), kept per thread and built again when the model's Source differs.
template <class Value, class Source>
const Value& cached(const RobotModel& model) {
  struct Cache {
    Source source;
    Value value;
  };
  thread_local Cache cache;
  if (!cache.source.same(model)) {
    cache.value = Value(model);  // checks the model before its source is recorded
    cache.source.record(model);
  }
  return cache.value;
}

}  // namespace

const SerialChain& cached_chain(const RobotModel& model) { return cached<SerialChain, ChainSource>(model); }

const JointBounds& cached_bounds(const RobotModel& model) { return cached<JointBounds, BoundsSource>(model); }

// The chain joint by joint from the base: O_i' (translation, then RotX(alpha) or the
// general rotation) | axis | RotZ(phi + q_i) or TransZ(q_i). on_axis(i, R, p) sees the frame
// at the bar: joint i turns about (slides along) its z column through its origin. Leaves
// R, p at the last joint's frame after its motion.
template <class OnAxis>
void SerialChain::walk(const JointVector& q, Matrix3d& R, Vector3d& p, OnAxis&& on_axis) const {
  GEOTRAJ_CHECK(q.size() == n_);
  // Every joint's cos and sin first: the walk below then runs without calls (no registers
  // saved around them).
  std::array<double, kMaxJoints> cos_q, sin_q;
  for (Eigen::Index i = 0; i < n_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const Link& l = links_[k];
    if (!l.revolute) continue;
    double c = std::cos(q(i)), s = std::sin(q(i));
    if (l.phi) {  // RotZ(phi + q)
      const double c_q = c;
      c = l.cphi * c_q - l.sphi * s;
      s = l.sphi * c_q + l.cphi * s;
    }
    cos_q[k] = c;
    sin_q[k] = s;
  }
  R = R_base_;
  p = p_base_;
  for (Eigen::Index i = 0; i < n_; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const Link& l = links_[k];
    p.noalias() += R * l.p;
    if (l.turn == Turn::kX) {
      rotate_x(R, l.ca, l.sa);
    } else if (l.turn == Turn::kGeneral) {
      R = R * l.R;
    }
    on_axis(i, R, p);
    if (l.revolute) {
      rotate_z(R, cos_q[k], sin_q[k]);
    } else {
      p.noalias() += q(i) * R.col(2);
    }
  }
}

void SerialChain::pose(const JointVector& q, Matrix3d& R_WT, Vector3d& p_WT) const {
  Matrix3d R;
  Vector3d p;
  walk(q, R, p, [](Eigen::Index, const Matrix3d&, const Vector3d&) {});
  p_WT = p + R * p_tool_;
  R_WT = R * R_tool_;
}

void SerialChain::jacobian(const JointVector& q, Matrix3d& R_WT, Vector3d& p_WT, JointAxes& z, JointAxes& o,
                       JointJacobian& J) const {
  z.resize(3, n_);
  o.resize(3, n_);
  J.resize(6, n_);
  Matrix3d R;
  Vector3d p;
  walk(q, R, p, [&](Eigen::Index i, const Matrix3d& Ri, const Vector3d& pi) {
    z.col(i) = Ri.col(2);
    o.col(i) = pi;
  });
  p_WT = p + R * p_tool_;
  R_WT = R * R_tool_;
  for (Eigen::Index i = 0; i < n_; ++i) {
    const Vector3d zi = z.col(i);
    if (links_[static_cast<std::size_t>(i)].revolute) {
      J.block<3, 1>(0, i) = zi.cross(p_WT - o.col(i));  // (1.9), revolute column
      J.block<3, 1>(3, i) = zi;
    } else {
      J.block<3, 1>(0, i) = zi;  // (1.9), prismatic column
      J.block<3, 1>(3, i).setZero();
    }
  }
}

void SerialChain::jacobian_dot(const Vector3d& p_WT, const JointAxes& z, const JointAxes& o, const JointJacobian& J,
                           const JointVector& q_dot, JointJacobian& J_dot) const {
  GEOTRAJ_CHECK(q_dot.size() == n_ && J.cols() == n_);
  J_dot.resize(6, n_);
  const Vector3d p_dot = J.topRows<3>() * q_dot;  // tool velocity [m/s]
  Vector3d omega = Vector3d::Zero();              // angular velocity of the frame carrying axis i
  Vector3d v_o = Vector3d::Zero();                // velocity of the point o_i
  Vector3d o_prev = p_base_;
  for (Eigen::Index i = 0; i < n_; ++i) {
    const Vector3d zi = z.col(i);
    const Vector3d oi = o.col(i);
    v_o += omega.cross(oi - o_prev);  // o_i rides on the body after joint i-1 (1.10)
    o_prev = oi;
    const Vector3d z_dot = omega.cross(zi);
    if (links_[static_cast<std::size_t>(i)].revolute) {
      J_dot.block<3, 1>(0, i) = z_dot.cross(p_WT - oi) + zi.cross(p_dot - v_o);  // (1.11)
      J_dot.block<3, 1>(3, i) = z_dot;
      omega += zi * q_dot(i);
    } else {
      J_dot.block<3, 1>(0, i) = z_dot;
      J_dot.block<3, 1>(3, i).setZero();
      v_o += zi * q_dot(i);
    }
  }
}

JointBounds::JointBounds(const RobotModel& model) {
  GEOTRAJ_CHECK(model.limits.size() == model.dof() && model.dof() <= kMaxJoints);
  for (std::size_t i = 0; i < model.dof(); ++i) {
    lo[i] = model.limits[i].min_position;
    hi[i] = model.limits[i].max_position;
    mid[i] = 0.5 * (lo[i] + hi[i]);
    range[i] = hi[i] - lo[i];
    revolute[i] = turns(model.joints[i].type);
    if (model.joints[i].type == JointType::kContinuous) {  // every angle: no bound, no centre
      lo[i] = -std::numeric_limits<double>::infinity();
      hi[i] = std::numeric_limits<double>::infinity();
      mid[i] = 0.0;
      range[i] = std::numeric_limits<double>::infinity();
    }
  }
}

Vector3d rotation_vector(const Matrix3d& R) {
  Eigen::Quaterniond q(R);
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // angle in [0, pi]
  const double s = q.vec().norm();            // sin(angle / 2)
  // angle / sin(angle / 2) = 2 atan2(s, w) / s; for s < 1e-7 its series 2 / w (1 - s^2 / (3 w^2)
  // + ...) is 2 / w to 4e-15 relative.
  const double scale = s < 1e-7 ? 2.0 / q.w() : 2.0 * std::atan2(s, q.w()) / s;
  return scale * q.vec();
}

double factor(const JointJacobian& J, const std::array<bool, kMaxJoints>* active, NewtonWorkspace& ws) {
  if (active == nullptr) {
    ws.A.noalias() = J * J.transpose();
  } else {
    ws.A.setZero();
    for (Eigen::Index i = 0; i < J.cols(); ++i) {
      if ((*active)[static_cast<std::size_t>(i)]) ws.A.noalias() += J.col(i) * J.col(i).transpose();
    }
  }
  ws.llt.compute(ws.A);
  double p_min = 0.0, sqrt_det = 0.0;
  if (ws.llt.info() == Eigen::Success) {
    const auto L = ws.llt.matrixLLT().diagonal();
    p_min = L.cwiseAbs2().minCoeff();
    sqrt_det = L.prod();
  }
  if (p_min < kSingularPivot) {
    const double r = 1.0 - p_min / kSingularPivot;
    ws.A.diagonal().array() += kSingularPivot * r * r;  // lambda^2, continuous at the threshold
    ws.llt.compute(ws.A);
  }
  return sqrt_det;
}

NewtonOutcome newton(const SerialChain& chain, const JointBounds& bounds, const Matrix3d& R_target,
                     const Vector3d& p_target, const IkOptions& options, bool wrap, JointVector& q,
                     NewtonWorkspace& ws) {
  const Eigen::Index n = chain.dof();
  constexpr double two_pi = 2.0 * std::numbers::pi;
  NewtonOutcome out;
  Vector6d e;
  JointVector dq(n), q_base(n);
  std::array<bool, kMaxJoints> active{};
  double merit_base = std::numeric_limits<double>::infinity();  // |e|^2 at q_base [m^2 + rad^2]
  int halvings = 0;
  auto step_to = [&](double scale) {  // q = projection of q_base + scale dq onto the limits
    q = q_base + scale * dq;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (wrap && bounds.revolute[k] && bounds.range[k] >= two_pi) {
        if (q(i) > bounds.hi[k] && q(i) - two_pi >= bounds.lo[k]) q(i) -= two_pi;
        if (q(i) < bounds.lo[k] && q(i) + two_pi <= bounds.hi[k]) q(i) += two_pi;
      }
      q(i) = std::clamp(q(i), bounds.lo[k], bounds.hi[k]);
    }
  };
  for (int it = 0;; ++it) {
    chain.jacobian(q, ws.R, ws.p, ws.z, ws.o, ws.J);
    e.head<3>() = p_target - ws.p;
    e.tail<3>() = rotation_vector(R_target * ws.R.transpose());
    out.iterations = it;
    out.position_error = e.head<3>().norm();
    out.orientation_error = e.tail<3>().norm();
    if (out.position_error <= options.position_tolerance && out.orientation_error <= options.orientation_tolerance) {
      out.converged = true;
      return out;
    }
    if (it >= options.max_iterations || !std::isfinite(out.position_error + out.orientation_error)) return out;

    // Backtracking: a step that increased the error (far from the solution, where the
    // linearisation fails) is halved, up to kMaxHalvings times, then taken anyway.
    const double merit = e.squaredNorm();
    if (merit > merit_base && halvings < kMaxHalvings) {
      ++halvings;
      step_to(std::ldexp(1.0, -halvings));
      continue;
    }
    halvings = 0;
    merit_base = merit;
    q_base = q;

    factor(ws.J, nullptr, ws);
    dq.noalias() = ws.J.transpose() * ws.llt.solve(e);  // minimum-norm step
    bool held = false;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      active[k] = !((q(i) <= bounds.lo[k] && dq(i) < 0.0) || (q(i) >= bounds.hi[k] && dq(i) > 0.0));
      held |= !active[k];
    }
    if (held) {  // hold those joints at their bound; the others take the step
      factor(ws.J, &active, ws);
      dq.noalias() = ws.J.transpose() * ws.llt.solve(e);
      for (Eigen::Index i = 0; i < n; ++i) {
        if (!active[static_cast<std::size_t>(i)]) dq(i) = 0.0;
      }
    }
    const double largest = dq.cwiseAbs().maxCoeff();
    if (largest > options.max_step) dq *= options.max_step / largest;  // trust region
    step_to(1.0);  // projection onto the limits
  }
}

void random_configuration(const JointBounds& bounds, SplitMix64& random, JointVector& q) {
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    q(i) = std::isfinite(bounds.range[k]) ? bounds.lo[k] + random.uniform() * bounds.range[k]
                                          : (2.0 * random.uniform() - 1.0) * std::numbers::pi;  // continuous
  }
}

NewtonOutcome solve_cold(const SerialChain& chain, const JointBounds& bounds, const Matrix3d& R_target,
                         const Vector3d& p_target, const JointVector& seed, const IkOptions& options, JointVector& q,
                         NewtonWorkspace& ws) {
  const Eigen::Index n = chain.dof();
  GEOTRAJ_CHECK(seed.size() == n);
  q = seed;
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    q(i) = std::clamp(q(i), bounds.lo[k], bounds.hi[k]);
  }
  NewtonOutcome best = newton(chain, bounds, R_target, p_target, options, true, q, ws);
  if (best.converged || options.restarts <= 0) return best;
  SplitMix64 random(options.restart_seed);
  JointVector best_q = q, trial(n);
  bool last_is_best = true;
  for (int r = 0; r < options.restarts; ++r) {
    random_configuration(bounds, random, trial);
    const NewtonOutcome out = newton(chain, bounds, R_target, p_target, options, true, trial, ws);
    const int iterations = best.iterations + out.iterations;
    last_is_best = out.converged || out.position_error + out.orientation_error <
                                        best.position_error + best.orientation_error;
    if (last_is_best) {
      best = out;
      best_q = trial;
    }
    best.iterations = iterations;
    if (best.converged) break;
  }
  q = best_q;
  if (!last_is_best) chain.jacobian(q, ws.R, ws.p, ws.z, ws.o, ws.J);  // ws describes the returned q
  return best;
}

}  // namespace detail

IkResult solve_ik(const RobotModel& model, const Eigen::Isometry3d& X_WT_target, const JointVector& seed,
                  const IkOptions& options) {
  GEOTRAJ_CHECK(seed.size() == static_cast<Eigen::Index>(model.dof()));
  const detail::SerialChain& chain = detail::cached_chain(model);
  const detail::JointBounds& bounds = detail::cached_bounds(model);
  const Eigen::Matrix3d R_target = X_WT_target.linear();
  const Eigen::Vector3d p_target = X_WT_target.translation();
  IkResult result;
  detail::NewtonWorkspace ws;
  if (model.dof() < 6) {  // a general pose has no solution: report the seed
    result.q = seed;
    chain.pose(seed, ws.R, ws.p);
    result.position_error = (p_target - ws.p).norm();
    result.orientation_error = detail::rotation_vector(R_target * ws.R.transpose()).norm();
  } else {
    const detail::NewtonOutcome out =
        detail::solve_cold(chain, bounds, R_target, p_target, seed, options, result.q, ws);
    result.converged = out.converged;
    result.iterations = out.iterations;
    result.position_error = out.position_error;
    result.orientation_error = out.orientation_error;
  }
  result.within_limits = true;
  for (std::size_t i = 0; i < model.dof(); ++i) {
    const double qi = result.q(static_cast<Eigen::Index>(i));
    result.within_limits &= qi >= bounds.lo[i] && qi <= bounds.hi[i];
  }
  return result;
}

}  // namespace geotraj::core
