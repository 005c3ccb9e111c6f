// The banded Cholesky of the jerk-limited timing's Newton systems (optim/timing/banded_cholesky.hpp),
// against LAPACK's dpbtrf + dpbtrs (Debian's reference LAPACK through LAPACKE) on the same
// matrices: factor and solve of an SPD band matrix of size n and half-bandwidth w. The
// interior point method factors one such matrix per iteration, w = 2 at 3 unknowns per grid
// point (1,000 grid points: n about 3,000). docs/performance.md has the figures and the
// choice they support.
#include <benchmark/benchmark.h>

#include <lapacke.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>
#include <stdexcept>
#include <vector>

#include "optim/timing/banded_cholesky.hpp"

namespace {

using geotraj::optim::detail::BandedCholesky;
using geotraj::optim::detail::BandMatrix;

// A random diagonally dominant (so SPD) band matrix.
BandMatrix random_spd(std::size_t n, std::size_t w) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> off(-1.0, 1.0);
  BandMatrix a(n, w);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j0 = i >= w ? i - w : 0;
    for (std::size_t j = j0; j < i; ++j) a.at(i, j) = off(rng);
    a.at(i, i) = 2.0 * static_cast<double>(w) + 1.0;
  }
  return a;
}

// LAPACK's upper band storage, column-major: column j holds A(j - w .. j, j), which is row j
// of geotraj's lower triangle in reverse order.
void to_lapack_upper(const BandMatrix& a, std::vector<double>& ab) {
  const std::size_t n = a.size(), w = a.bandwidth(), ld = w + 1;
  ab.assign(n * ld, 0.0);
  for (std::size_t j = 0; j < n; ++j) {
    const std::size_t i0 = j >= w ? j - w : 0;
    for (std::size_t i = i0; i <= j; ++i) ab[j * ld + (w + i - j)] = a.at(j, i);
  }
}

void BM_BandedCholeskyGeotraj(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto w = static_cast<std::size_t>(state.range(1));
  const BandMatrix a = random_spd(n, w);
  const std::vector<double> b(n, 1.0);
  BandedCholesky chol;
  std::vector<double> x;
  for (auto _ : state) {
    if (!chol.factor(a)) throw std::runtime_error("not positive definite");
    x = b;
    chol.solve(x);
    benchmark::DoNotOptimize(x.data());
  }
  state.SetComplexityN(static_cast<benchmark::IterationCount>(n));
}

// The copy into LAPACK's layout is counted: the interior point method would need it too.
void BM_BandedCholeskyLapack(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto w = static_cast<std::size_t>(state.range(1));
  const BandMatrix a = random_spd(n, w);
  const std::vector<double> b(n, 1.0);
  std::vector<double> ab, x;
  const auto ln = static_cast<lapack_int>(n), lw = static_cast<lapack_int>(w);
  for (auto _ : state) {
    to_lapack_upper(a, ab);
    if (LAPACKE_dpbtrf(LAPACK_COL_MAJOR, 'U', ln, lw, ab.data(), lw + 1) != 0) {
      throw std::runtime_error("not positive definite");
    }
    x = b;
    LAPACKE_dpbtrs(LAPACK_COL_MAJOR, 'U', ln, lw, 1, ab.data(), lw + 1, x.data(), ln);
    benchmark::DoNotOptimize(x.data());
  }
  state.SetComplexityN(static_cast<benchmark::IterationCount>(n));
}

// Both agree on the solution (checked once per run, outside the timing).
void BM_BandedCholeskyAgreement(benchmark::State& state) {
  const BandMatrix a = random_spd(3000, 2);
  std::vector<double> x(3000, 1.0), y(3000, 1.0), ab;
  BandedCholesky chol;
  chol.factor(a);
  chol.solve(x);
  to_lapack_upper(a, ab);
  LAPACKE_dpbtrf(LAPACK_COL_MAJOR, 'U', 3000, 2, ab.data(), 3);
  LAPACKE_dpbtrs(LAPACK_COL_MAJOR, 'U', 3000, 2, 1, ab.data(), 3, y.data(), 3000);
  double diff = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) diff = std::max(diff, std::abs(x[i] - y[i]));
  if (diff > 1e-12) throw std::runtime_error("geotraj and LAPACK disagree");
  for (auto _ : state) benchmark::DoNotOptimize(diff);
  state.counters["max_difference"] = diff;
}

void sizes(benchmark::internal::Benchmark* b) {
  for (const int w : {2, 4, 8}) {
    for (const int n : {300, 3000, 30000}) b->Args({n, w});
  }
}

BENCHMARK(BM_BandedCholeskyGeotraj)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BandedCholeskyLapack)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BandedCholeskyAgreement)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
