#include "optim/timing/banded_cholesky.hpp"

#include <algorithm>
#include <cmath>

namespace geotraj::optim::detail {

std::vector<double> BandMatrix::multiply(const std::vector<double>& x) const {
  std::vector<double> y(n_, 0.0);
  for (std::size_t i = 0; i < n_; ++i) {
    const std::size_t j0 = i >= w_ ? i - w_ : 0;
    for (std::size_t j = j0; j < i; ++j) {
      y[i] += at(i, j) * x[j];
      y[j] += at(i, j) * x[i];
    }
    y[i] += at(i, i) * x[i];
  }
  return y;
}

bool BandedCholesky::factor(const BandMatrix& a, double shift) {
  const std::size_t n = a.size(), w = a.bandwidth();
  if (l_.size() != n || l_.bandwidth() != w) l_.resize(n, w);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k0 = i >= w ? i - w : 0;
    for (std::size_t j = k0; j <= i; ++j) {
      double sum = a.at(i, j);
      if (j == i) sum += shift;
      // L(i, k) L(j, k) over the columns k both rows share: k >= i - w (as j <= i).
      for (std::size_t k = k0; k < j; ++k) sum -= l_.at(i, k) * l_.at(j, k);
      if (j < i) {
        l_.at(i, j) = sum / l_.at(j, j);
        continue;
      }
      const double diag = std::abs(a.at(i, i) + shift);
      if (!std::isfinite(sum) || !(sum > 1e-14 * diag) || sum <= 0.0) return false;
      l_.at(i, i) = std::sqrt(sum);
    }
  }
  return true;
}

void BandedCholesky::solve(std::vector<double>& b) const {
  const std::size_t n = l_.size(), w = l_.bandwidth();
  for (std::size_t i = 0; i < n; ++i) {  // L y = b
    const std::size_t k0 = i >= w ? i - w : 0;
    double s = b[i];
    for (std::size_t k = k0; k < i; ++k) s -= l_.at(i, k) * b[k];
    b[i] = s / l_.at(i, i);
  }
  for (std::size_t i = n; i-- > 0;) {  // L^T x = y
    double s = b[i];
    for (std::size_t k = i + 1; k <= std::min(n - 1, i + w); ++k) s -= l_.at(k, i) * b[k];
    b[i] = s / l_.at(i, i);
  }
}

double BandedCholesky::log_determinant() const {
  double s = 0.0;
  for (std::size_t i = 0; i < l_.size(); ++i) s += 2.0 * std::log(l_.at(i, i));
  return s;
}

}  // namespace geotraj::optim::detail
