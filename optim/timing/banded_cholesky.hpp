// A banded Cholesky factorisation A = L L^T of a symmetric positive definite matrix of
// half-bandwidth w (A(i, j) = 0 for |i - j| > w), in O(n w^2) time and O(n w) storage: the
// Newton systems of the banded interior point method (banded_ipm.hpp), whose matrices couple
// only neighbouring grid points (w = 2 for the jerk-limited timing). Private to geotraj_optim.
#pragma once

#include <cstddef>
#include <vector>

namespace geotraj::optim::detail {

/// A symmetric band matrix, lower triangle stored by rows: entry (i, i - k), k = 0 .. w, at
/// i (w + 1) + k (entries with i - k < 0 are unused and kept at zero).
class BandMatrix {
 public:
  BandMatrix() = default;
  BandMatrix(std::size_t n, std::size_t w) { resize(n, w); }
  void resize(std::size_t n, std::size_t w) {
    n_ = n, w_ = w;
    a_.assign(n * (w + 1), 0.0);
  }
  void set_zero() { a_.assign(a_.size(), 0.0); }
  std::size_t size() const { return n_; }
  std::size_t bandwidth() const { return w_; }
  /// Entry (i, j) of the lower triangle, j <= i <= j + w.
  double& at(std::size_t i, std::size_t j) { return a_[i * (w_ + 1) + (i - j)]; }
  double at(std::size_t i, std::size_t j) const { return a_[i * (w_ + 1) + (i - j)]; }
  /// Entry (i, j) of the full symmetric matrix (0 outside the band).
  double operator()(std::size_t i, std::size_t j) const {
    if (i < j) return (*this)(j, i);
    return i - j <= w_ ? at(i, j) : 0.0;
  }
  /// A x.
  std::vector<double> multiply(const std::vector<double>& x) const;
  std::vector<double>& data() { return a_; }

 private:
  std::size_t n_ = 0, w_ = 0;
  std::vector<double> a_;
};

/// The Cholesky factor L of a band matrix (same band).
class BandedCholesky {
 public:
  /// Factors A + shift I. False when a pivot is not positive (beyond relative 1e-14 of the
  /// diagonal entry) or not finite: A + shift I is not (numerically) positive definite.
  bool factor(const BandMatrix& a, double shift = 0.0);
  /// Solves A x = b in place (after a successful factor()).
  void solve(std::vector<double>& b) const;
  /// log det A = 2 sum log L_ii (after a successful factor()).
  double log_determinant() const;
  const BandMatrix& factor_matrix() const { return l_; }

 private:
  BandMatrix l_;
};

}  // namespace geotraj::optim::detail
