// A primal-dual interior point method for nonlinear programmes whose Newton systems are
// banded: min f(x) s.t. x_l <= x <= x_u, g_l <= g(x) <= g_u (inequalities only), where every
// row of g and every Hessian entry couples only variables within a small distance w of each
// other, so that the condensed Newton matrix H + A^T Sigma A is a band matrix of
// half-bandwidth w, factored by banded_cholesky.hpp in O(n w^2).
//
// It drives an Ipopt::TNLP (the same problem object Ipopt solves: the same evaluation code,
// the same derivatives). Method: Ipopt's (Waechter and Biegler 2006) in its simplest form,
// with the band exploited:
//  - the variables' bounds are kept strictly (x + alpha dx within the fraction to the
//    boundary; a start on or beyond one moves inside by Ipopt's bound push), every finite side of a row is an
//    inequality c_k(x) >= 0 with a slack s_k > 0 (c_k(x) - s_k = 0, so the start may break
//    the rows) and a multiplier z_k > 0; barrier function phi_mu = f - mu sum log (slacks);
//  - Newton step on the primal-dual equations, condensed to the band system
//      (H_L + A^T Sigma A + delta I) dx = -grad f + A^T (mu / s - Sigma (c - s)),
//    Sigma = Z S^-1 (the bounds: c itself for s), ds = A dx + c - s,
//    dz = mu / s - z - Sigma ds, H_L the exact Hessian of the Lagrangian (Ipopt's eval_h);
//    inertia correction: delta = 0 first, else grown by Ipopt's rule until the banded
//    Cholesky succeeds (the condensed matrix is positive definite exactly when the KKT
//    matrix has the right inertia);
//  - fraction to the boundary, tau = max(0.995, 1 - mu), on the bounds, the slacks and z;
//  - Ipopt's filter line search on (theta = |c - s|_1, phi_mu) with its switching condition
//    and Armijo rule, backtracking by halves, up to four second-order corrections when the
//    full step is refused (the jerk rows are nonlinear); no restoration phase: a line search
//    that fails ends the solve (kFailed, or kConverged at Ipopt's acceptable level 1e3 tol);
//  - slack reset s = max(s, c) after each step (both theta and phi only fall);
//  - monotone (Fiacco-McCormick) barrier: mu <- max(1e-11, min(0.2 mu, mu^1.5)) whenever
//    the barrier problem's error is below 10 mu (the filter is then reset); z kept within
//    [mu / (1e10 s), 1e10 mu / s] (Ipopt's kappa_sigma);
//  - convergence as Ipopt's: the optimality error max(dual infeasibility / s_d, |c - s|_inf,
//    complementarity / s_d) at most tol (s_d Ipopt's scaling by the mean multiplier), the
//    unscaled dual infeasibility at most 1 and complementarity at most 1e-4 (dual_inf_tol,
//    compl_inf_tol), every row within constr_viol_tol of its bounds, and the duality gap
//    sum s z at most 10 tol max(1, |f|) (for the objective's accuracy: Ipopt's per-element
//    complementarity test alone lets the gap grow with the number of rows);
//  - the deadline (wall clock) and the iteration limit are checked every iteration.
#pragma once

#include <chrono>
#include <stop_token>
#include <cstddef>
#include <string>
#include <vector>

namespace Ipopt {
class TNLP;  // <IpTNLP.hpp>: the problem's interface, included by the solver's source only
}  // namespace Ipopt

namespace geotraj::optim::detail {

struct BandedIpmOptions {
  double tol = 1e-8;              ///< Ipopt's tol on the scaled optimality error
  double constr_viol_tol = 1e-9;  ///< Ipopt's constr_viol_tol: largest row violation at convergence
  double mu_init = 0.1;           ///< Ipopt's mu_init
  double mu_min = 0.0;            ///< 0: 1e-11 (Ipopt's mu_min)
  int max_iterations = 500;
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  std::stop_token stop;  ///< requested: stop like at the deadline (checked every iteration)
  std::size_t max_bandwidth = 16;  ///< refuse problems with a wider band
  bool trace = false;              ///< one line per iteration on stdout
};

struct BandedIpmResult {
  enum class Status { kConverged, kIterationLimit, kTimeLimit, kFailed };
  Status status = Status::kFailed;
  int iterations = 0;
  std::vector<double> x;  ///< the last iterate (strictly feasible), empty when none
  double mu = 0.0;        ///< the last barrier parameter
  double error = 0.0;     ///< the last scaled optimality error
  std::string message;
};

BandedIpmResult solve_banded_ipm(Ipopt::TNLP& nlp, const BandedIpmOptions& options);

}  // namespace geotraj::optim::detail
