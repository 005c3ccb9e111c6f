// Joints chosen for a whole motion ahead of the samples. See joint_reference.hpp.
#include "core/planning/joint_reference.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "core/error.hpp"

namespace geotraj::core {

// The cubic spline: with h the step and M_k = q''(x_k), the conditions of C2 continuity
// are, per joint,
//   h M_{k-1} + 4 h M_k + h M_{k+1} = 6 (q_{k+1} - 2 q_k + q_{k-1}) / h   (0 < k < K)
// and at the ends either (in time, clamped: q'(0) = q'(T) = 0)
//   2 h M_0 + h M_1 = 6 (q_1 - q_0) / h,   h M_{K-1} + 2 h M_K = -6 (q_K - q_{K-1}) / h
// or (in arc length, natural) M_0 = M_K = 0: a tridiagonal system solved by the Thomas
// algorithm, every joint at once.
JointReference::JointReference(std::vector<JointVector> q, double dt, ReferenceParameter over)
    : q_(std::move(q)), dt_(dt), over_(over) {
  GEOTRAJ_CHECK(q_.size() >= 2 && dt > 0.0 && std::isfinite(dt));
  const std::size_t K = q_.size() - 1;
  const Eigen::Index n = q_[0].size();
  for (const JointVector& x : q_) GEOTRAJ_CHECK(x.size() == n);
  std::vector<double> diag(K + 1), upper(K + 1);
  std::vector<JointVector> rhs(K + 1, JointVector::Zero(n));
  const double h = dt;
  const bool natural = over == ReferenceParameter::kArcLength;
  std::vector<double> lower(K + 1, h);
  for (std::size_t k = 0; k <= K; ++k) {
    const bool end = k == 0 || k == K;
    diag[k] = !end ? 4.0 * h : natural ? 1.0 : 2.0 * h;
    upper[k] = k == 0 && natural ? 0.0 : h;
    if (k == K && natural) lower[k] = 0.0;
    if (end && natural) continue;  // M = 0
    if (k == 0) rhs[k] = 6.0 * (q_[1] - q_[0]) / h;
    else if (k == K) rhs[k] = -6.0 * (q_[K] - q_[K - 1]) / h;
    else rhs[k] = 6.0 * (q_[k + 1] - 2.0 * q_[k] + q_[k - 1]) / h;
  }
  // Forward elimination, then back substitution.
  for (std::size_t k = 1; k <= K; ++k) {
    const double f = lower[k] / diag[k - 1];
    diag[k] -= f * upper[k - 1];
    rhs[k] -= f * rhs[k - 1];
  }
  m_.assign(K + 1, JointVector::Zero(n));
  m_[K] = rhs[K] / diag[K];
  for (std::size_t k = K; k-- > 0;) m_[k] = (rhs[k] - upper[k] * m_[k + 1]) / diag[k];
}

void JointReference::at(double t, JointVector& q, JointVector& q_dot, JointVector& q_ddot) const {
  const std::size_t K = q_.size() - 1;
  t = std::clamp(t, 0.0, duration());
  const std::size_t k = std::min(static_cast<std::size_t>(t / dt_), K - 1);
  const double h = dt_;
  const double a = (static_cast<double>(k + 1) * h - t) / h;  // weight of sample k
  const double b = 1.0 - a;                                   // weight of sample k + 1
  const JointVector& q0 = q_[k];
  const JointVector& q1 = q_[k + 1];
  const JointVector& m0 = m_[k];
  const JointVector& m1 = m_[k + 1];
  q = a * q0 + b * q1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * (h * h / 6.0);
  q_dot = (q1 - q0) / h + ((1.0 - 3.0 * a * a) * m0 + (3.0 * b * b - 1.0) * m1) * (h / 6.0);
  q_ddot = a * m0 + b * m1;
}

}  // namespace geotraj::core
