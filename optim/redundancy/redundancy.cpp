// Whole-path redundancy resolution on Ceres Solver. See redundancy.hpp.
#include "optim/redundancy/redundancy.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <string>
#include <utility>

#include <ceres/ceres.h>

#include "core/format.hpp"
#include "core/planning/joint_reference.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"

namespace geotraj::optim {

namespace {

using core::JointVector;
using Eigen::Isometry3d;
using Eigen::Vector3d;

// The pose error [p(q) - p_t; r(R(q) R_t^T)] [m; rad] of joints with tool pose X.
core::Vector6d pose_error(const Isometry3d& X, const Isometry3d& target) {
  core::Vector6d e;
  e.head<3>() = X.translation() - target.translation();
  const Eigen::AngleAxisd turn(X.linear() * target.linear().transpose());
  e.tail<3>() = turn.angle() * turn.axis();
  return e;
}

// The per-joint scales of each criterion (0 where it does not apply).
struct Scales {
  JointVector velocity, acceleration, jerk, range, mid, goal;
  double manipulability = 0.0;  // w_m m_0
};

Scales scales_of(const core::RobotModel& model, double dt, const RedundancyOptions& o, const JointVector& q0) {
  const std::size_t n = model.dof();
  Scales s;
  s.velocity = s.acceleration = s.jerk = s.range = s.mid = s.goal = JointVector::Zero(static_cast<Eigen::Index>(n));
  const RedundancyWeights& w = o.weights;
  for (std::size_t i = 0; i < n; ++i) {
    const auto j = static_cast<Eigen::Index>(i);
    const core::JointLimits& l = model.limits[i];
    s.velocity(j) = w.velocity / (dt * l.max_velocity);
    s.acceleration(j) = w.acceleration / (dt * dt * l.max_acceleration);
    s.jerk(j) = l.max_jerk ? w.jerk / (dt * dt * dt * *l.max_jerk) : 0.0;
    const bool bounded = model.joints[i].type != core::JointType::kContinuous;
    const double range = bounded ? l.max_position - l.min_position : 2.0 * std::numbers::pi;
    s.mid(j) = bounded ? 0.5 * (l.min_position + l.max_position) : 0.0;
    s.range(j) = bounded && range > 0.0 ? w.joint_range / range : 0.0;
    s.goal(j) = o.goal && range > 0.0 ? o.goal_weight / range : 0.0;
  }
  if (w.manipulability > 0.0) {
    Isometry3d X;
    core::JointJacobian J;
    core::forward_kinematics(model, q0, X, J);
    s.manipulability = w.manipulability * std::max(core::manipulability(J), 1e-12);
  }
  return s;
}

// A finite-difference stencil of the joint trajectory with rests beyond its ends: the
// coefficients of the samples it touches (indices clamped to [0, K], repeats merged).
struct Stencil {
  std::vector<std::size_t> samples;
  std::vector<double> coefficients;
  double centre = 0.0;  // the time it measures, in steps (unclamped)
};

std::vector<Stencil> stencils(std::size_t K, std::initializer_list<double> c, long first, long last) {
  std::vector<Stencil> out;
  for (long k = first; k <= last; ++k) {
    Stencil st;
    st.centre = static_cast<double>(k) + 0.5 * static_cast<double>(c.size() - 1);
    long index = k;
    for (const double coefficient : c) {
      const auto at = static_cast<std::size_t>(std::clamp<long>(index++, 0, static_cast<long>(K)));
      const auto it = std::find(st.samples.begin(), st.samples.end(), at);
      if (it == st.samples.end()) {
        st.samples.push_back(at);
        st.coefficients.push_back(coefficient);
      } else {
        st.coefficients[static_cast<std::size_t>(it - st.samples.begin())] += coefficient;
      }
    }
    // Drop merged zeros; a stencil of rests alone measures nothing.
    for (std::size_t i = st.samples.size(); i-- > 0;) {
      if (st.coefficients[i] == 0.0) {
        st.samples.erase(st.samples.begin() + static_cast<long>(i));
        st.coefficients.erase(st.coefficients.begin() + static_cast<long>(i));
      }
    }
    if (!st.samples.empty() && !(st.samples.size() == 1 && st.samples[0] == 0)) out.push_back(std::move(st));
  }
  return out;
}

// The stencils of the three derivative criteria over samples 0 .. K.
struct Differences {
  std::vector<Stencil> velocity, acceleration, jerk;
};
Differences differences(std::size_t K) {
  return {stencils(K, {-1.0, 1.0}, 0, static_cast<long>(K) - 1), stencils(K, {1.0, -2.0, 1.0}, -1, static_cast<long>(K) - 1),
          stencils(K, {-1.0, 3.0, -3.0, 1.0}, -2, static_cast<long>(K) - 1)};
}

// r_i = w (s_i d_i)^p with d = sum_j c_j q_{samples[j]} (n residuals, one block per sample):
// p = 1, w = 1 a derivative criterion (s its scale); p > 1 the limits' term of the rounds
// (s the limit's unit over kPeakUsage, so s_i d_i is the usage over it): r^2 = w^2 u^{2p}, a
// smooth stand-in for the largest usage (a high norm), negligible well below 1, steep above.
class DifferenceCost final : public ceres::CostFunction {
 public:
  DifferenceCost(const Stencil& stencil, const JointVector& scale, int power = 1)
      : c_(stencil.coefficients), scale_(scale), power_(power) {
    set_num_residuals(static_cast<int>(scale.size()));
    for (std::size_t j = 0; j < c_.size(); ++j) mutable_parameter_block_sizes()->push_back(static_cast<int>(scale.size()));
  }
  bool Evaluate(double const* const* q, double* r, double** jac) const override {
    const Eigen::Index n = scale_.size();
    JointVector slope(n);  // dr_i / dd_i (a fixed-capacity vector: no allocation)
    for (Eigen::Index i = 0; i < n; ++i) {
      double sum = 0.0;
      for (std::size_t j = 0; j < c_.size(); ++j) sum += c_[j] * q[j][i];
      const double u = scale_(i) * sum;
      double below = 1.0;  // u^(p - 1), by multiplication (std::pow costs more here)
      for (int k = 1; k < power_; ++k) below *= u;
      r[i] = weight_ * below * u;
      slope(i) = weight_ * power_ * below * scale_(i);
    }
    if (jac) {
      for (std::size_t j = 0; j < c_.size(); ++j) {
        if (!jac[j]) continue;
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> block(jac[j], n, n);
        block.setZero();
        block.diagonal() = slope * c_[j];
      }
    }
    return true;
  }
  double weight() const { return weight_; }
  void set_weight(double weight) { weight_ = weight; }

 private:
  std::vector<double> c_;
  JointVector scale_;
  int power_;
  double weight_ = 1.0;
};

// r = scale .* (q - centre) (the range, or the goal).
class OffsetCost final : public ceres::CostFunction {
 public:
  OffsetCost(const JointVector& centre, const JointVector& scale) : centre_(centre), scale_(scale) {
    set_num_residuals(static_cast<int>(scale.size()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(scale.size()));
  }
  bool Evaluate(double const* const* q, double* r, double** jac) const override {
    const auto n = static_cast<std::size_t>(scale_.size());
    for (std::size_t i = 0; i < n; ++i) {
      const auto j = static_cast<Eigen::Index>(i);
      r[i] = scale_(j) * (q[0][i] - centre_(j));
    }
    if (jac && jac[0]) {
      std::fill(jac[0], jac[0] + n * n, 0.0);
      for (std::size_t i = 0; i < n; ++i) jac[0][i * n + i] = scale_(static_cast<Eigen::Index>(i));
    }
    return true;
  }

 private:
  JointVector centre_, scale_;
};

// The joints that hold a pose: a manifold of dimension n - 6 in joint space (the arm's
// self-motion through the pose). Its tangent at q is J(q)'s null space, with the basis N(q)
// (n x (n - 6), orthonormal: the last columns of J^T's QR factor); a step delta moves to
// q + N delta and back onto the pose by the IK's Newton projection (minimum-norm
// corrections, within the position limits). So the pose is held at every iterate, not penalised.
constexpr double kLongestSelfMotionStep = 0.5;  // [rad], of one sample's joints

class SelfMotion final : public ceres::Manifold {
 public:
  SelfMotion(const core::RobotModel& model, const Isometry3d& target) : model_(model), target_(target) {
    ik_.position_tolerance = ik_.orientation_tolerance = 1e-9;
    ik_.max_iterations = 12;
  }
  int AmbientSize() const override { return static_cast<int>(model_.dof()); }
  int TangentSize() const override { return static_cast<int>(model_.dof()) - 6; }
  bool Plus(const double* x, const double* delta, double* out) const override {
    const auto n = static_cast<Eigen::Index>(model_.dof());
    const JointVector q = Eigen::Map<const Eigen::VectorXd>(x, n);
    const Eigen::MatrixXd& N = basis(q);
    const JointVector step = N * Eigen::Map<const Eigen::VectorXd>(delta, N.cols());
    // A step too long for the projection (Ceres tries the whole gradient once, to measure
    // it) is cut to kLongestSelfMotionStep and halved until the IK brings it back: the
    // retraction saturates far from x, and the trust region judges such steps by what they
    // achieve.
    double scale = std::min(1.0, kLongestSelfMotionStep / std::max(step.norm(), 1e-300));
    for (int attempt = 0; attempt < 12; ++attempt, scale *= 0.5) {
      const core::IkResult ik = core::solve_ik(model_, target_, q + scale * step, ik_);
      if (!ik.converged) continue;
      std::copy(ik.q.data(), ik.q.data() + n, out);
      return true;
    }
    return false;
  }
  bool PlusJacobian(const double* x, double* jacobian) const override {
    const auto n = static_cast<Eigen::Index>(model_.dof());
    const Eigen::MatrixXd& N = basis(Eigen::Map<const Eigen::VectorXd>(x, n));
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(jacobian, n, N.cols()) = N;
    return true;
  }
  bool Minus(const double* y, const double* x, double* delta) const override {
    const auto n = static_cast<Eigen::Index>(model_.dof());
    const Eigen::MatrixXd& N = basis(Eigen::Map<const Eigen::VectorXd>(x, n));
    Eigen::Map<Eigen::VectorXd>(delta, N.cols()) =
        N.transpose() * (Eigen::Map<const Eigen::VectorXd>(y, n) - Eigen::Map<const Eigen::VectorXd>(x, n));
    return true;
  }
  bool MinusJacobian(const double* x, double* jacobian) const override {
    const auto n = static_cast<Eigen::Index>(model_.dof());
    const Eigen::MatrixXd& N = basis(Eigen::Map<const Eigen::VectorXd>(x, n));
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(jacobian, N.cols(), n) =
        N.transpose();
    return true;
  }

 private:
  // N(q): from the projector P = I - J^T (J J^T)^-1 J onto J's null space (J J^T 6 x 6,
  // Cholesky), Gram-Schmidt over P's columns, largest diagonal first (P e_i is in the null
  // space; n - 6 of them span it). Near a singularity (J J^T not positive definite, or the
  // columns too short) from J^T's QR factor instead. The last basis is kept: Ceres asks for
  // it at the same q in PlusJacobian, Plus and Minus.
  const Eigen::MatrixXd& basis(const JointVector& q) const {
    if (have_basis_ && q == basis_q_) return basis_;
    using Square = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, static_cast<int>(core::kMaxJoints),
                                 static_cast<int>(core::kMaxJoints)>;
    Isometry3d X;
    core::JointJacobian J;
    core::forward_kinematics(model_, q, X, J);
    const Eigen::Index n = q.size(), r = n - 6;
    basis_.resize(n, r);
    Eigen::Index found = 0;
    const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(J * J.transpose());
    if (llt.info() == Eigen::Success) {
      // Fixed-capacity matrices and lazy products: these are at most 12 x 12, where Eigen's
      // general matrix kernels (and the heap) cost more than the arithmetic.
      const core::JointJacobian solved = llt.solve(J);
      Square P = -J.transpose().lazyProduct(solved);
      P.diagonal().array() += 1.0;
      std::array<Eigen::Index, core::kMaxJoints> order{};
      for (Eigen::Index i = 0; i < n; ++i) order[static_cast<std::size_t>(i)] = i;
      std::sort(order.begin(), order.begin() + n, [&](Eigen::Index a, Eigen::Index b) { return P(a, a) > P(b, b); });
      JointVector v(n);
      for (Eigen::Index o = 0; o < n && found < r; ++o) {
        v = P.col(order[static_cast<std::size_t>(o)]);
        for (Eigen::Index k = 0; k < found; ++k) v -= basis_.col(k).dot(v) * basis_.col(k);
        const double norm = v.norm();
        if (norm < 1e-3) continue;
        basis_.col(found++) = v / norm;
      }
    }
    if (found < r) {
      const Eigen::MatrixXd Jt = J.transpose();
      const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Jt);
      const Eigen::MatrixXd Q = qr.householderQ();
      basis_ = Q.rightCols(r);
    }
    basis_q_ = q;
    have_basis_ = true;
    return basis_;
  }

  const core::RobotModel& model_;
  Isometry3d target_;
  core::IkOptions ik_;
  mutable bool have_basis_ = false;
  mutable JointVector basis_q_;
  mutable Eigen::MatrixXd basis_;
};

double manipulability_at(const core::RobotModel& model, const JointVector& q) {
  Isometry3d X;
  core::JointJacobian J;
  core::forward_kinematics(model, q, X, J);
  return core::manipulability(J);
}

// r = w_m m_0 / m(q), its gradient by central differences of m (h = 1e-6 rad).
class ManipulabilityCost final : public ceres::CostFunction {
 public:
  ManipulabilityCost(const core::RobotModel& model, double scale) : model_(model), scale_(scale) {
    set_num_residuals(1);
    mutable_parameter_block_sizes()->push_back(static_cast<int>(model.dof()));
  }
  bool Evaluate(double const* const* q, double* r, double** jac) const override {
    const auto n = static_cast<Eigen::Index>(model_.dof());
    JointVector joints = Eigen::Map<const Eigen::VectorXd>(q[0], n);
    const double m = std::max(manipulability_at(model_, joints), 1e-12);
    r[0] = scale_ / m;
    if (jac && jac[0]) {
      constexpr double h = 1e-6;
      for (Eigen::Index i = 0; i < n; ++i) {
        const double keep = joints(i);
        joints(i) = keep + h;
        const double up = manipulability_at(model_, joints);
        joints(i) = keep - h;
        const double down = manipulability_at(model_, joints);
        joints(i) = keep;
        jac[0][i] = -scale_ / (m * m) * (up - down) / (2.0 * h);
      }
    }
    return true;
  }

 private:
  const core::RobotModel& model_;
  double scale_;
};

// Ends the solve when the caller's stop says so.
class StopCallback final : public ceres::IterationCallback {
 public:
  explicit StopCallback(const std::function<bool()>& stopped) : stopped_(stopped) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return stopped_ && stopped_() ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
  }
  bool fired() const { return stopped_ && stopped_(); }

 private:
  const std::function<bool()>& stopped_;
};

double difference_objective(const std::vector<Stencil>& all, const std::vector<JointVector>& q, const JointVector& scale) {
  double sum = 0.0;
  if (scale.isZero()) return 0.0;
  for (const Stencil& st : all) {
    JointVector d = JointVector::Zero(scale.size());
    for (std::size_t j = 0; j < st.samples.size(); ++j) d += st.coefficients[j] * q[st.samples[j]];
    sum += d.cwiseProduct(scale).squaredNorm();
  }
  return sum;
}

// The limits' reciprocals per derivative, at the step dt: a difference of order p times
// these is the usage (1 at the limit); 0 where the joint has no such limit (jerk).
struct Units {
  JointVector velocity, acceleration, jerk;
};
Units units_of(const core::RobotModel& model, double dt) {
  const auto n = static_cast<Eigen::Index>(model.dof());
  Units u{JointVector::Zero(n), JointVector::Zero(n), JointVector::Zero(n)};
  for (Eigen::Index j = 0; j < n; ++j) {
    const core::JointLimits& l = model.limits[static_cast<std::size_t>(j)];
    u.velocity(j) = 1.0 / (dt * l.max_velocity);
    u.acceleration(j) = 1.0 / (dt * dt * l.max_acceleration);
    u.jerk(j) = l.max_jerk ? 1.0 / (dt * dt * dt * *l.max_jerk) : 0.0;
  }
  return u;
}

// One derivative criterion in the problem: its stencils, the user's scale, the limits' units.
struct Derivative {
  const std::vector<Stencil>* stencils;
  JointVector scale;
  JointVector unit;
};

// The largest usage of each derivative's limits over the samples k = 0 .. K, as the samples
// will move: along the C2 spline through the joints that the samplers follow
// (core::JointReference): the velocity at the sample and half a step on, the acceleration at
// the sample (the spline's is linear between samples), the jerk on the steps either side
// (constant on each).
Peaks peaks_of(const Derivative (&derivatives)[3], const std::vector<JointVector>& q, double dt) {
  const core::JointReference spline(q, dt);
  const std::vector<JointVector>& m = spline.second_derivatives();
  const std::size_t K = q.size() - 1;
  JointVector at_q, v0, v1, a;
  Peaks peaks;
  for (std::size_t k = 0; k <= K; ++k) {
    const double t = static_cast<double>(k) * dt;
    spline.at(t, at_q, v0, a);
    spline.at(std::min(t + 0.5 * dt, spline.duration()), at_q, v1, a);
    // units are per difference at the step dt: the derivative times dt^p.
    peaks.velocity = std::max(peaks.velocity, (v0.cwiseAbs().cwiseMax(v1.cwiseAbs()).cwiseProduct(derivatives[0].unit) * dt).maxCoeff());
    peaks.acceleration = std::max(peaks.acceleration, (m[k].cwiseAbs().cwiseProduct(derivatives[1].unit) * (dt * dt)).maxCoeff());
    if (k > 0)
      peaks.jerk = std::max(peaks.jerk, ((m[k] - m[k - 1]).cwiseAbs().cwiseProduct(derivatives[2].unit) * (dt * dt)).maxCoeff());
  }
  return peaks;
}

// The rounds that bring peaks within the limits (optimize_redundancy): the power of the
// usage they penalise, the usage they aim at, lambda's growth per round; they end when no
// usage exceeds kAcceptedUsage (a margin for the 1 kHz samples between the optimised
// steps), after kMaxRounds, or after kStalledRounds rounds in a row that lower the peak by
// less than kStallGain (limits out of reach of the self-motion at this timing); each round
// takes kRoundIterations iterations at most. kPeakUsage aims below kAcceptedUsage so that one
// round mostly suffices (the thesis's paths A and B: 0.95 took a second round).
constexpr int kPeakPower = 8;
constexpr double kPeakUsage = 0.93;
constexpr double kPeakGrowth = 4.0;
constexpr double kAcceptedUsage = 0.98;
constexpr int kMaxRounds = 8;
constexpr int kStalledRounds = 1;
constexpr double kStallGain = 5e-3;
constexpr double kWatchedUsage = 0.8;
constexpr double kEarlyUsage = 2.0;
constexpr int kRoundIterations = 40;  // per round: a limit out of reach must not take them all

bool solver_available(ceres::SparseLinearAlgebraLibraryType type) {
  return ceres::IsSparseLinearAlgebraLibraryTypeAvailable(type);
}

}  // namespace

double redundancy_objective(const core::RobotModel& model, const std::vector<JointVector>& q, double dt,
                            const RedundancyOptions& options) {
  if (q.size() < 2) return 0.0;
  const std::size_t K = q.size() - 1;
  const Scales s = scales_of(model, dt, options, q[0]);
  const Differences d = differences(K);
  double sum = difference_objective(d.velocity, q, s.velocity) + difference_objective(d.acceleration, q, s.acceleration) +
               difference_objective(d.jerk, q, s.jerk);
  for (std::size_t k = 1; k <= K; ++k) {
    sum += (q[k] - s.mid).cwiseProduct(s.range).squaredNorm();
    if (s.manipulability > 0.0) sum += std::pow(s.manipulability / std::max(manipulability_at(model, q[k]), 1e-12), 2);
  }
  if (options.goal) sum += (q[K] - *options.goal).cwiseProduct(s.goal).squaredNorm();
  return 0.5 * sum;
}

core::Expected<RedundancyResult> optimize_redundancy(const core::ValidRobot& robot, const std::vector<Isometry3d>& poses,
                                                     double dt, const std::vector<JointVector>& initial,
                                                     const RedundancyOptions& options) {
  const core::RobotModel& model = robot;
  const std::size_t n = model.dof();
  core::Violations v;
  const RedundancyWeights& w = options.weights;
  const double weights[] = {w.joint_range, w.velocity, w.acceleration, w.jerk, w.manipulability};
  if (std::any_of(std::begin(weights), std::end(weights),
                  [](double x) { return !std::isfinite(x) || x < 0.0 || x > kMaxRedundancyWeight; }))
    v.push_back({"weights", "must be in [0, " + core::number(kMaxRedundancyWeight) + "]"});
  else if (std::all_of(std::begin(weights), std::end(weights), [](double x) { return x == 0.0; }))
    v.push_back({"weights", "at least one weight must be > 0"});
  if (!std::isfinite(dt) || !(dt > 0.0)) v.push_back({"dt", "must be a finite time > 0 s, got " + core::number(dt)});
  if (!(options.limit_scale > 0.0 && options.limit_scale <= 1.0))
    v.push_back({"limit_scale", "must be in (0, 1], got " + core::number(options.limit_scale)});
  if (poses.size() < 2 || initial.size() != poses.size())
    v.push_back({"initial", "needs one joint vector per pose, at least 2 (got " + std::to_string(initial.size()) +
                                " for " + std::to_string(poses.size()) + " poses)"});
  if (options.goal && (static_cast<std::size_t>(options.goal->size()) != n || !options.goal->allFinite()))
    v.push_back({"goal", "needs " + std::to_string(n) + " finite joint values"});
  else if (options.hold_goal && !options.goal)
    v.push_back({"goal", "is held at the end, so it must be given"});
  else if (options.hold_goal && !poses.empty()) {
    const core::Vector6d e = pose_error(core::forward_kinematics(model, *options.goal), poses.back());
    if (e.head<3>().norm() > 1e-6 || e.tail<3>().norm() > 1e-6)
      v.push_back({"goal", "is held at the end but does not reach the last pose (" + core::number(e.head<3>().norm()) +
                               " m, " + core::number(e.tail<3>().norm()) + " rad off)"});
  }
  if (n <= 6)
    v.push_back({"robot", "has " + std::to_string(n) + " joints: a pose leaves it no self-motion to choose"});
  if (!v.empty()) return tl::make_unexpected(std::move(v));
  for (std::size_t k = 0; k < initial.size(); ++k) {
    const std::string field = "initial[" + std::to_string(k) + "]";
    if (static_cast<std::size_t>(initial[k].size()) != n || !initial[k].allFinite()) {
      v.push_back({field, "needs " + std::to_string(n) + " finite joint values"});
      break;
    }
    const core::Vector6d e = pose_error(core::forward_kinematics(model, initial[k]), poses[k]);
    if (e.head<3>().norm() > 1e-6 || e.tail<3>().norm() > 1e-6) {
      v.push_back({field, "does not reach its pose (" + core::number(e.head<3>().norm()) + " m, " +
                              core::number(e.tail<3>().norm()) + " rad off)"});
      break;
    }
  }
  if (!v.empty()) return tl::make_unexpected(std::move(v));

  const auto started = std::chrono::steady_clock::now();
  const std::size_t K = poses.size() - 1;
  const Scales s = scales_of(model, dt, options, initial[0]);
  RedundancyResult result;
  result.q = initial;
  result.report.objective_before = redundancy_objective(model, initial, dt, options);
  if (!std::isfinite(result.report.objective_before)) {  // a degenerate model or step: nothing to compare
    result.report.objective_before = result.report.objective_after = 0.0;
    result.report.status = OptimizerStatus::kFailed;
    result.report.message = "the criteria overflow on the given joints (dt " + core::number(dt) + " s)";
    return result;
  }

  // The start: the given joints, or with the goal held, their self-motion ramped from
  // nothing at the start to the goal's offset at the end (smoothstep), each sample projected
  // back onto its pose (kept as given where the IK does not).
  std::vector<JointVector> start = initial;
  if (options.hold_goal) {
    const JointVector offset = *options.goal - initial[K];
    core::IkOptions project;
    project.position_tolerance = project.orientation_tolerance = 1e-11;
    for (std::size_t k = 1; k < K; ++k) {
      const double u = static_cast<double>(k) / static_cast<double>(K), blend = u * u * (3.0 - 2.0 * u);
      const core::IkResult ik = core::solve_ik(model, poses[k], initial[k] + blend * offset, project);
      if (ik.converged && ik.within_limits) start[k] = ik.q;
    }
    start[K] = *options.goal;
  }
  std::vector<double> x(poses.size() * n);
  for (std::size_t k = 0; k <= K; ++k) std::copy(start[k].data(), start[k].data() + n, x.data() + k * n);
  const auto block = [&](std::size_t k) { return x.data() + k * n; };

  ceres::Problem problem;
  for (std::size_t k = 0; k <= K; ++k) problem.AddParameterBlock(block(k), static_cast<int>(n));
  problem.SetParameterBlockConstant(block(0));
  if (options.hold_goal) problem.SetParameterBlockConstant(block(K));
  for (std::size_t k = 1; k <= K; ++k) {
    if (k < K || !options.hold_goal) problem.SetManifold(block(k), new SelfMotion(model, poses[k]));
    if (!s.range.isZero()) problem.AddResidualBlock(new OffsetCost(s.mid, s.range), nullptr, block(k));
    if (s.manipulability > 0.0) problem.AddResidualBlock(new ManipulabilityCost(model, s.manipulability), nullptr, block(k));
  }
  // The derivative criteria (the stencils are kept: the rounds below add the limits' terms).
  const Differences d = differences(K);
  Units units = units_of(model, dt);
  const double c = options.limit_scale;  // the limits held: velocity x c, acceleration x c^2, jerk x c^3
  units.velocity /= c;
  units.acceleration /= c * c;
  units.jerk /= c * c * c;
  const Derivative derivatives[3] = {{&d.velocity, s.velocity, units.velocity},
                                     {&d.acceleration, s.acceleration, units.acceleration},
                                     {&d.jerk, s.jerk, units.jerk}};
  // Every stencil of `derivative` as a cost of `scale` and `power` (the costs, kept).
  const auto add_blocks = [&](const Derivative& derivative, const JointVector& scale, int power) {
    std::vector<DifferenceCost*> costs;
    for (const Stencil& st : *derivative.stencils) {
      std::vector<double*> blocks;
      for (const std::size_t k : st.samples) blocks.push_back(block(k));
      costs.push_back(new DifferenceCost(st, scale, power));
      problem.AddResidualBlock(costs.back(), nullptr, blocks);
    }
    return costs;
  };
  for (const Derivative& derivative : derivatives)
    if (!derivative.scale.isZero()) add_blocks(derivative, derivative.scale, 1);
  if (options.goal && !options.hold_goal) problem.AddResidualBlock(new OffsetCost(*options.goal, s.goal), nullptr, block(K));

  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // Gauss-Newton from the start: the differences make J^T J span some ten decades (the
  // smooth modes of a second difference over 1,000 samples), and the default radius damps
  // exactly the modes the self-motion needs, growing 3x per iteration. (1e9 takes fewer
  // iterations on the thesis's paths but leaves the Panda's seam with its roll free on a
  // joint's position limit.)
  so.initial_trust_region_radius = 1e12;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.sparse_linear_algebra_library_type = solver_available(ceres::SUITE_SPARSE) ? ceres::SUITE_SPARSE : ceres::EIGEN_SPARSE;
  so.num_threads = 1;
  // 1e-5: the thesis's paths end within 0.02 % of 1e-6's objective in half the iterations.
  so.function_tolerance = 1e-5;
  so.gradient_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  StopCallback stop(options.stopped);
  so.callbacks.push_back(&stop);

  const int max_iterations = std::max(1, options.max_iterations);
  const double budget_s = std::max(1e-3, options.time_budget_s);
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(); };
  const auto current = [&] {
    std::vector<JointVector> q(poses.size());
    for (std::size_t k = 0; k <= K; ++k) q[k] = Eigen::Map<const Eigen::VectorXd>(block(k), static_cast<Eigen::Index>(n));
    return q;
  };
  const std::vector<double> x_start = x;
  // The limits' terms of the rounds below, per derivative, added once its usage exceeds
  // kWatchedUsage (below, they weigh next to nothing and cost as much as a criterion), at the
  // rounds' weight lambda.
  std::vector<DifferenceCost*> peak_costs;
  std::array<bool, 3> watched{};
  double lambda = 1.0;
  const auto watch = [&](const Peaks& peaks) {
    const double usage[3] = {peaks.velocity, peaks.acceleration, peaks.jerk};
    for (std::size_t i = 0; i < 3; ++i) {
      if (watched[i] || derivatives[i].unit.isZero() || usage[i] <= kWatchedUsage) continue;
      for (DifferenceCost* cost : add_blocks(derivatives[i], derivatives[i].unit / kPeakUsage, kPeakPower)) {
        cost->set_weight(lambda);
        peak_costs.push_back(cost);
      }
      watched[i] = true;
    }
  };
  // A start that breaks the limits by less than kEarlyUsage has their terms from the first
  // solve (the least-squares optimum alone would only be the next round's start); further
  // off, the steep terms would drown the criteria and crawl: the least-squares optimum first.
  if (options.within_limits) {
    if (const Peaks at_start = peaks_of(derivatives, start, dt);
        at_start.worst() > kAcceptedUsage && at_start.worst() < kEarlyUsage) {
      watch(at_start);
      ++result.rounds;
    }
  }
  ceres::Solver::Summary summary;
  int iterations = 0, stalled = 0;
  // The rounds' lowest peak and its joints (a round out of the limits' reach can raise it),
  // and the peak the last gain was measured from.
  double lowest_peak = std::numeric_limits<double>::infinity(), stalled_from = lowest_peak;
  std::vector<double> x_lowest;
  for (;;) {
    so.max_num_iterations = std::max(1, max_iterations - iterations);
    if (result.rounds > 0) so.max_num_iterations = std::min(so.max_num_iterations, kRoundIterations);
    so.max_solver_time_in_seconds = std::max(1e-3, budget_s - elapsed());
    ceres::Solve(so, &problem, &summary);
    iterations += static_cast<int>(summary.iterations.size());
    if (summary.termination_type == ceres::FAILURE || stop.fired() || summary.termination_type == ceres::USER_SUCCESS)
      break;
    // The limits are constraints, the weights preferences: a least-squares optimum spreads the
    // usage but keeps peaks. Where it breaks a limit, every difference of a limited derivative
    // gets the term lambda (u / kPeakUsage)^kPeakPower (u its usage as the samples will move),
    // a smooth stand-in for the largest usage: nothing well below kPeakUsage, steep above;
    // solved again from there, lambda x4 each round while the peak falls (a penalty
    // continuation: one smooth objective per round, where raising single residuals' weights
    // made the peaks hop between neighbours).
    if (!options.within_limits || result.rounds >= kMaxRounds || iterations >= max_iterations || elapsed() >= budget_s)
      break;
    const Peaks now = peaks_of(derivatives, current(), dt);
    const double peak = now.worst();
    if (peak < lowest_peak) {
      lowest_peak = peak;
      x_lowest = x;
    }
    if (peak <= kAcceptedUsage) break;
    if (peak < (1.0 - kStallGain) * stalled_from) {
      stalled_from = peak;
      stalled = 0;
    } else if (++stalled >= kStalledRounds) {
      break;
    }
    if (peak_costs.empty()) {
      // The rounds start from the lower peak: the least-squares optimum, or the start (a
      // start within the limits that a strong criterion left far behind: from there the
      // limits' term keeps the iterates near the limits' side it starts on).
      if (peaks_of(derivatives, start, dt).worst() < peak) {
        std::copy(x_start.begin(), x_start.end(), x.begin());
        // From there the limits' term rejects the long steps towards the optimum, and Ceres's
        // radius, divided by 2^(k (k + 1) / 2) after k rejections, leaves a short step that
        // the looser tolerance would take for convergence.
        so.function_tolerance = 1e-6;
      }
    } else {
      lambda *= kPeakGrowth;
      for (DifferenceCost* cost : peak_costs) cost->set_weight(lambda);
    }
    watch(now);
    ++result.rounds;
  }
  if (!x_lowest.empty() && peaks_of(derivatives, current(), dt).worst() > lowest_peak)
    std::copy(x_lowest.begin(), x_lowest.end(), x.begin());  // (in place: Ceres holds x's blocks)

  // Every sample polished by the IK from the optimum (minimum-norm corrections, ~1e-8).
  std::vector<JointVector> q(poses.size());
  q[0] = initial[0];
  core::IkOptions polish;
  polish.position_tolerance = 1e-12;
  polish.orientation_tolerance = 1e-12;
  polish.max_iterations = 20;
  bool reached = true;
  for (std::size_t k = 1; k <= K; ++k) {
    if (options.hold_goal && k == K) {
      q[k] = *options.goal;
      continue;
    }
    const core::IkResult ik = core::solve_ik(model, poses[k], Eigen::Map<const Eigen::VectorXd>(block(k), static_cast<Eigen::Index>(n)), polish);
    q[k] = ik.q;
    result.worst_position_error = std::max(result.worst_position_error, ik.position_error);
    result.worst_orientation_error = std::max(result.worst_orientation_error, ik.orientation_error);
    reached = reached && ik.position_error <= 1e-9 && ik.orientation_error <= 1e-9 && ik.within_limits;
  }

  OptimizerReport& report = result.report;
  report.iterations = iterations;
  report.message = summary.message;
  report.seconds = elapsed();
  const Peaks peaks_before = peaks_of(derivatives, initial, dt);
  result.peaks = peaks_before;
  if (!reached || summary.termination_type == ceres::FAILURE) {
    report.status = OptimizerStatus::kFailed;
    if (!reached) report.message = "the optimum's joints do not all reach their poses after the IK's polish";
    report.objective_after = report.objective_before;
    return result;
  }
  // Better: closer to the limits where the start breaks them, else a lower objective.
  const double after = redundancy_objective(model, q, dt, options);
  const Peaks peaks_after = peaks_of(derivatives, q, dt);
  const double excess_before = std::max(0.0, peaks_before.worst() - 1.0);
  const double excess_after = std::max(0.0, peaks_after.worst() - 1.0);
  // With the goal held, the given joints break that constraint: the optimum is the answer.
  // Without the limits as constraints, a lower objective is better (the caller times the
  // motion again along the joints chosen: planner's retime_along_choices).
  const bool better = std::isfinite(after) &&
                      (options.hold_goal || options.take_optimum || excess_after < excess_before - 1e-9 ||
                       ((excess_after <= excess_before + 1e-9 || !options.within_limits) &&
                        after < report.objective_before));
  if (!better) {
    report.status = OptimizerStatus::kNoImprovement;
    report.objective_after = report.objective_before;
    return result;
  }
  report.objective_after = after;
  result.q = std::move(q);
  result.peaks = peaks_after;
  if (result.rounds > 0 && peaks_after.worst() > 1.0 && !options.take_optimum) {
    // Ceres's status is the penalised problem's: say plainly that the limits are not kept.
    const std::string of = c == 1.0 ? " of a limit" : " of the limits held (x " + core::number(c, 4) + ")";
    report.message = "the joints' limits stay broken: peak usage " + core::number(peaks_after.worst(), 4) + of +
                     " (from " + core::number(peaks_before.worst(), 4) + ") after " +
                     std::to_string(result.rounds) +
                     " rounds weighing the peaks; beyond the self-motion's reach at this timing: slow the motion (" +
                     summary.message + ")";
  } else if (result.rounds > 0) {
    // (An optimum taken whatever its peaks: its caller times the motion again along it.)
    report.message += "; " + std::to_string(result.rounds) + " rounds weighing the peaks beyond the limits" +
                      (c == 1.0 ? std::string() : " held (x " + core::number(c, 4) + ")") + ", peak usage " +
                      core::number(peaks_after.worst(), 4);
  }
  if (stop.fired() || summary.termination_type == ceres::USER_SUCCESS) {
    report.status = OptimizerStatus::kTimeLimit;
  } else if (options.within_limits && peaks_after.worst() > 1.0 && result.rounds >= kMaxRounds) {
    report.status = OptimizerStatus::kIterationLimit;
  } else if (summary.termination_type == ceres::CONVERGENCE) {
    report.status = OptimizerStatus::kConverged;
  } else {
    report.status = elapsed() >= budget_s ? OptimizerStatus::kTimeLimit : OptimizerStatus::kIterationLimit;
  }
  return result;
}

}  // namespace geotraj::optim
