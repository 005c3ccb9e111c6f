// The tangent-scale optimiser's fixed rules in u: composite Gauss-Legendre rules and the
// Bernstein derivative weights at fixed points, built once per degree. Private to geotraj_optim.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <vector>

namespace geotraj::optim::tangent_scales_detail {

// The final verification measures on rules this many times finer than the solver's.
inline constexpr int kAuditFactor = 8;

struct Rule {
  std::vector<double> u, w;  // nodes in [0, 1] and weights summing to 1
};

// The composite Gauss-Legendre rule of `intervals` equal parts of [0, 1] (8 nodes each).
Rule composite_rule(int intervals);

// Weights of the control points in d^k p/du^k at fixed u's, for one degree:
// w[k][j * (d + 1) + i] for k = 1..3. Precomputed once per degree and point set, so that
// an evaluation is a short weighted sum of the control points per point and order.
struct BasisTable {
  int degree = 0;
  std::size_t points = 0;
  std::array<std::vector<double>, 4> w;
};

// The point sets of one degree: the solver's and the verification's.
struct Tables {
  BasisTable quad, peak, regular;           // solver
  BasisTable audit_quad, audit_points;      // verification (8 times finer)
};

// The tables of degree d, built once per process and shared (immutable once built; the
// set-up of the finer verification tables cost as much as a whole solve).
std::shared_ptr<const Tables> tables_for(int d);

}  // namespace geotraj::optim::tangent_scales_detail
