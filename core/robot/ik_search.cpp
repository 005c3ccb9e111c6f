// Inverse kinematics: the search of the whole joint range for distinct solutions (search_ik),
// and the closest pose when none converges. See ik.hpp and serial_chain.hpp.
#include "core/robot/ik.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "core/error.hpp"
#include "core/robot/serial_chain.hpp"

namespace geotraj::core {
namespace detail {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

bool spans_turn(const JointBounds& bounds, std::size_t k) { return bounds.revolute[k] && bounds.range[k] >= kTwoPi; }

// a - b, modulo 2 pi into (-pi, pi] on a joint whose range spans a turn.
double joint_difference(const JointBounds& bounds, std::size_t k, double a, double b) {
  double d = a - b;
  if (spans_turn(bounds, k)) d = std::remainder(d, kTwoPi);
  return d;
}

// Each joint whose range spans a turn moved by whole turns to its value nearest the seed
// that stays within the limits (the same arm pose).
void nearest_representative(const JointBounds& bounds, const JointVector& seed, JointVector& q) {
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!spans_turn(bounds, k)) continue;
    const double nearest = seed(i) + std::remainder(q(i) - seed(i), kTwoPi);
    for (const double candidate : {nearest, nearest + kTwoPi, nearest - kTwoPi}) {
      if (candidate >= bounds.lo[k] && candidate <= bounds.hi[k]) {
        if (std::abs(candidate - seed(i)) < std::abs(q(i) - seed(i))) q(i) = candidate;
        break;
      }
    }
  }
}

// The inverse of SO(3)'s right Jacobian at the rotation vector phi (angle theta < pi):
// J_r^-1 = I + [phi]x / 2 + (1 / theta^2 - (1 + cos theta) / (2 theta sin theta)) [phi]x^2,
// the coefficient's series 1/12 + theta^2 / 720 below 1e-4 rad.
Matrix3d inverse_right_jacobian(const Vector3d& phi) {
  const double theta = phi.norm();
  Matrix3d hat;
  hat << 0.0, -phi.z(), phi.y(), phi.z(), 0.0, -phi.x(), -phi.y(), phi.x(), 0.0;
  const double c = theta < 1e-4 ? 1.0 / 12.0 + theta * theta / 720.0
                                : 1.0 / (theta * theta) - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  return Matrix3d::Identity() + 0.5 * hat + c * hat * hat;
}

// Levenberg-Marquardt on |e|^2 within the bounds (projected steps, accepted only when they
// reduce it): the closest pose to an unreachable target that q's basin holds. Steps
// dq = J^T (J J^T + mu I)^-1 e, mu adapted (x 4 on a rejected step, / 3 on an accepted one).
NewtonOutcome refine_closest(const SerialChain& chain, const JointBounds& bounds, const Matrix3d& R_target,
                             const Vector3d& p_target, int max_iterations, JointVector& q, NewtonWorkspace& ws) {
  const Eigen::Index n = chain.dof();
  Vector6d e;
  // The orientation error's exact derivative: phi = log(R_t R^T) moves by
  // J_r^-1(phi) (-d omega) when the tool turns by d omega (in W), where the Newton steps take
  // -d omega (exact only for small errors; far from the target, as here, the steps crawled:
  // a UR5 target 1.3 reaches away still moved after 5,000 of them).
  const auto error_at = [&](const JointVector& x) {
    chain.jacobian(x, ws.R, ws.p, ws.z, ws.o, ws.J);
    e.head<3>() = p_target - ws.p;
    e.tail<3>() = rotation_vector(R_target * ws.R.transpose());
    ws.J.bottomRows<3>() = inverse_right_jacobian(e.tail<3>()) * ws.J.bottomRows<3>();
    return e.squaredNorm();
  };
  NewtonOutcome out;
  double merit = error_at(q);
  JointJacobian J = ws.J;
  Vector6d e_q = e;
  double mu = 1e-3 * std::max(1e-12, (J * J.transpose()).trace() / 6.0);
  JointVector trial(n);
  for (int it = 0; it < max_iterations; ++it) {
    out.iterations = it + 1;
    // A joint at a limit that the descent direction J^T e pushes further out is held: its
    // column leaves the step (projecting a step that counted on it crawled along the limit).
    JointJacobian free_J = J;
    const JointVector descent = J.transpose() * e_q;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if ((q(i) >= bounds.hi[k] && descent(i) > 0.0) || (q(i) <= bounds.lo[k] && descent(i) < 0.0)) free_J.col(i).setZero();
    }
    ws.A.noalias() = free_J * free_J.transpose();
    ws.A.diagonal().array() += mu;
    ws.llt.compute(ws.A);
    trial = q + free_J.transpose() * ws.llt.solve(e_q);
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      trial(i) = std::clamp(trial(i), bounds.lo[k], bounds.hi[k]);
    }
    const double step = (trial - q).cwiseAbs().maxCoeff();
    const double trial_merit = error_at(trial);
    if (trial_merit < merit) {
      const bool small = merit - trial_merit <= 1e-14 * merit || step <= 1e-12;
      q = trial;
      merit = trial_merit;
      J = ws.J;
      e_q = e;
      mu = std::max(mu / 3.0, 1e-15);
      if (small) break;
    } else {
      mu *= 4.0;
      if (mu > 1e12 || step <= 1e-12) break;
    }
  }
  error_at(q);  // ws describes the returned q
  out.position_error = e.head<3>().norm();
  out.orientation_error = e.tail<3>().norm();
  return out;
}

}  // namespace

NewtonOutcome refine_closest_pose(const SerialChain& chain, const JointBounds& bounds, const Matrix3d& R_target,
                                  const Vector3d& p_target, int max_iterations, JointVector& q, NewtonWorkspace& ws) {
  return refine_closest(chain, bounds, R_target, p_target, max_iterations, q, ws);
}

IkSearchResult search(const SerialChain& chain, const JointBounds& bounds, const Matrix3d& R_target,
                      const Vector3d& p_target, const JointVector& seed, const IkSearchOptions& options) {
  const Eigen::Index n = chain.dof();
  IkSearchResult result;
  NewtonWorkspace ws;
  SplitMix64 random(options.newton.restart_seed);
  IkOptions measure_only = options.newton;
  measure_only.max_iterations = 0;
  JointVector q(n);
  // The best failed attempts, refined for the closest pose when nothing converges.
  constexpr std::size_t kRefined = 3;
  std::vector<std::pair<double, JointVector>> best_failed;
  const auto distinct = [&](const JointVector& x) {
    return std::none_of(result.solutions.begin(), result.solutions.end(), [&](const IkResult& s) {
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto k = static_cast<std::size_t>(i);
        if (std::abs(joint_difference(bounds, k, x(i), s.q(i))) >= options.distinct_tolerance) return false;
      }
      return true;
    });
  };
  for (int attempt = 0; attempt < options.max_attempts; ++attempt) {
    if (attempt % 64 == 63 && options.stopped && options.stopped()) {
      result.stopped = true;
      return result;
    }
    if (attempt == 0) {
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto k = static_cast<std::size_t>(i);
        q(i) = std::clamp(seed(i), bounds.lo[k], bounds.hi[k]);
      }
    } else {
      random_configuration(bounds, random, q);
    }
    // With fewer than 6 joints a general pose has no solution: the attempt only measures its
    // start (no iteration), and the refinement below finds the closest pose.
    const NewtonOutcome out = newton(chain, bounds, R_target, p_target, n >= 6 ? options.newton : measure_only, true, q, ws);
    result.attempts = attempt + 1;
    result.iterations += out.iterations;
    if (out.converged) {
      nearest_representative(bounds, seed, q);
      if (distinct(q)) {
        IkResult found;
        found.q = q;
        found.converged = true;
        found.iterations = out.iterations;
        found.position_error = out.position_error;
        found.orientation_error = out.orientation_error;
        found.within_limits = true;
        result.solutions.push_back(std::move(found));
      }
      if (!options.all_solutions) break;
      continue;
    }
    const double merit = out.position_error * out.position_error + out.orientation_error * out.orientation_error;
    if (best_failed.size() < kRefined || merit < best_failed.back().first) {
      if (best_failed.size() == kRefined) best_failed.pop_back();
      best_failed.emplace_back(std::isfinite(merit) ? merit : std::numeric_limits<double>::max(), q);
      std::sort(best_failed.begin(), best_failed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    }
  }
  const auto distance = [&](const IkResult& r) {
    double sum = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) sum += (r.q(i) - seed(i)) * (r.q(i) - seed(i));
    return sum;
  };
  std::stable_sort(result.solutions.begin(), result.solutions.end(),
                   [&](const IkResult& a, const IkResult& b) { return distance(a) < distance(b); });
  if (result.solutions.size() > options.max_solutions) result.solutions.resize(options.max_solutions);
  if (!result.solutions.empty()) {
    result.closest = result.solutions.front();
    return result;
  }
  // Out of reach (or every attempt failed): the closest pose from the best attempts.
  double best_merit = std::numeric_limits<double>::infinity();
  for (auto& [merit, start] : best_failed) {
    (void)merit;
    JointVector x = start;
    const NewtonOutcome out = refine_closest(chain, bounds, R_target, p_target, 200, x, ws);
    result.iterations += out.iterations;
    const double m = out.position_error * out.position_error + out.orientation_error * out.orientation_error;
    if (m < best_merit) {
      best_merit = m;
      nearest_representative(bounds, seed, x);
      result.closest.q = x;
      result.closest.iterations = out.iterations;
      result.closest.position_error = out.position_error;
      result.closest.orientation_error = out.orientation_error;
      result.closest.converged = out.position_error <= options.newton.position_tolerance &&
                                 out.orientation_error <= options.newton.orientation_tolerance;
      result.closest.within_limits = true;
    }
  }
  if (result.closest.converged) result.solutions.push_back(result.closest);  // the refinement reached it
  return result;
}

}  // namespace detail

IkSearchResult search_ik(const RobotModel& model, const Eigen::Isometry3d& X_WT_target, const JointVector& seed,
                         const IkSearchOptions& options) {
  GEOTRAJ_CHECK(seed.size() == static_cast<Eigen::Index>(model.dof()));
  GEOTRAJ_CHECK(options.max_attempts >= 1 && options.max_solutions >= 1);
  const detail::SerialChain& chain = detail::cached_chain(model);
  const detail::JointBounds& bounds = detail::cached_bounds(model);
  return detail::search(chain, bounds, X_WT_target.linear(), X_WT_target.translation(), seed, options);
}

IkResult closest_pose(const RobotModel& model, const Eigen::Isometry3d& X_WT_target, const JointVector& start,
                      int max_iterations, const IkOptions& options) {
  GEOTRAJ_CHECK(start.size() == static_cast<Eigen::Index>(model.dof()) && max_iterations >= 1);
  const detail::SerialChain& chain = detail::cached_chain(model);
  const detail::JointBounds& bounds = detail::cached_bounds(model);
  IkResult result;
  result.q = start;
  for (Eigen::Index i = 0; i < start.size(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    result.q(i) = std::clamp(result.q(i), bounds.lo[k], bounds.hi[k]);
  }
  detail::NewtonWorkspace ws;
  const detail::NewtonOutcome out = detail::refine_closest_pose(chain, bounds, X_WT_target.linear(),
                                                           X_WT_target.translation(), max_iterations, result.q, ws);
  result.iterations = out.iterations;
  result.position_error = out.position_error;
  result.orientation_error = out.orientation_error;
  result.converged = out.position_error <= options.position_tolerance && out.orientation_error <= options.orientation_tolerance;
  result.within_limits = true;
  return result;
}

}  // namespace geotraj::core
