// The fixed rules in u (Gauss-Legendre nodes, uniform and midpoint samples) and the Bernstein
// derivative weights at them, cached per degree (quadrature.hpp).
#include "optim/tangent_scales/quadrature.hpp"

#include <cmath>
#include <map>
#include <mutex>
#include <utility>

#include "core/geometry/bezier.hpp"
#include "optim/tangent_scales/tangent_scales.hpp"

namespace geotraj::optim::tangent_scales_detail {
namespace {

constexpr int kGaussNodes = 8;

// Gauss-Legendre nodes and weights on [-1, 1] by Newton's method on P_n (deterministic, to
// rounding).
std::pair<std::array<double, kGaussNodes>, std::array<double, kGaussNodes>> gauss_legendre() {
  std::array<double, kGaussNodes> x{}, w{};
  const int n = kGaussNodes;
  for (int i = 0; i < n; ++i) {
    double z = std::cos(M_PI * (i + 0.75) / (n + 0.5));
    double dp = 0.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1.0);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    x[i] = z;
    w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
  }
  return {x, w};
}

}  // namespace

Rule composite_rule(int intervals) {
  const auto [x, w] = gauss_legendre();
  Rule r;
  const double h = 1.0 / intervals;
  for (int j = 0; j < intervals; ++j) {
    for (int i = 0; i < kGaussNodes; ++i) {
      r.u.push_back(h * (j + 0.5 * (x[i] + 1.0)));
      r.w.push_back(0.5 * h * w[i]);
    }
  }
  return r;
}

namespace {

// `count` points uniform in [0, 1], both ends included.
std::vector<double> uniform_points(int count) {
  std::vector<double> u;
  for (int j = 0; j < count; ++j) u.push_back(static_cast<double>(j) / (count - 1));
  return u;
}

// `count` midpoints of `count` equal parts of [0, 1]: (j + 1/2) / count.
std::vector<double> midpoints(int count) {
  std::vector<double> u;
  for (int j = 0; j < count; ++j) u.push_back((j + 0.5) / count);
  return u;
}

// d^k/du^k of the Bernstein polynomial B_{i,d}(u) = C(d, i) u^i (1-u)^(d-i):
//   d!/(d-k)! sum_j (-1)^(k-j) C(k, j) B_{i-j, d-k}(u).
// Integer powers by repeated multiplication (std::pow dominated the set-up).
double int_pow(double x, int e) {
  double r = 1.0;
  for (int i = 0; i < e; ++i) r *= x;
  return r;
}

double bernstein_derivative(int d, int i, int k, double u) {
  if (k > d) return 0.0;
  double sum = 0.0;
  for (int j = 0; j <= k; ++j) {
    const int m = i - j, n = d - k;
    if (m < 0 || m > n) continue;
    const double b = core::binomial(n, m) * int_pow(u, m) * int_pow(1.0 - u, n - m);
    sum += ((k - j) % 2 ? -1.0 : 1.0) * core::binomial(k, j) * b;
  }
  return core::falling_factorial(d, k) * sum;
}

BasisTable basis_table(int d, const std::vector<double>& u) {
  BasisTable t;
  t.degree = d;
  t.points = u.size();
  for (int k = 1; k <= 3; ++k) {
    t.w[k].resize(u.size() * (d + 1));
    for (std::size_t j = 0; j < u.size(); ++j)
      for (int i = 0; i <= d; ++i) t.w[k][j * (d + 1) + i] = bernstein_derivative(d, i, k, u[j]);
  }
  return t;
}

}  // namespace

std::shared_ptr<const Tables> tables_for(int d) {
  static std::mutex mutex;
  static std::map<int, std::shared_ptr<const Tables>> cache;
  const std::lock_guard<std::mutex> lock(mutex);
  auto& entry = cache[d];
  if (!entry) {
    auto t = std::make_shared<Tables>();
    t->quad = basis_table(d, composite_rule(kQuadratureIntervals).u);
    t->peak = basis_table(d, uniform_points(kPeakSamples));
    t->regular = basis_table(d, midpoints(kRegularitySamples));
    t->audit_quad = basis_table(d, composite_rule(kAuditFactor * kQuadratureIntervals).u);
    t->audit_points = basis_table(d, uniform_points(kAuditFactor * (kPeakSamples - 1) + 1));
    entry = std::move(t);
  }
  return entry;
}

}  // namespace geotraj::optim::tangent_scales_detail
