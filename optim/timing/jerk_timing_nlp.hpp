// The NLP of the jerk-limited timing (time_optimal_jerk.hpp) as an Ipopt::TNLP, which the banded
// interior point method (banded_ipm.hpp) and Ipopt both solve. Private to geotraj_optim.
#pragma once

#include <cstddef>
#include <vector>

#include <IpTNLP.hpp>

#include "core/planning/time_optimal.hpp"
#include "optim/common/second_order.hpp"
#include "optim/timing/time_optimal_jerk.hpp"

namespace geotraj::optim::detail {

/// A value with its gradient and Hessian in the three local variables (b_{i-1}, b_i,
/// b_{i+1}) of grid point i: forward-mode second derivatives of the per-point terms
/// (second_order.hpp; the Hessian's lower triangle at tri(r, c)).
using D3 = SecondOrder<3>;

/// The NLP of time_optimal_jerk.hpp. Variables x_k = b_{k+1}, k = 0 .. N - 2.
class JerkTimingNlp : public Ipopt::TNLP {
 public:
  using Index = Ipopt::Index;
  using Number = Ipopt::Number;

  JerkTimingNlp(const std::vector<core::GridPoint>& grid, const core::TimeOptimalLimits& lim,
                const JerkTimingOptions& opt);

  Index n_var() const { return N_ - 1; }
  double ds(Index i) const { return g_[static_cast<std::size_t>(i + 1)].s - g_[static_cast<std::size_t>(i)].s; }
  /// The variable of grid point p, or -1 for the rests.
  Index var(Index p) const { return p >= 1 && p <= N_ - 1 ? p - 1 : -1; }

  /// The objective T + w sum j^2 tau at x [s]; +infinity where some b <= 0.
  double objective(const Number* x);

  // The rows handed to Ipopt (select_jerk_rows): Ipopt's row k is full row active_[k], full
  // rows numbered linear rows first, then (N + 1) x jerk_rows_per_point_ jerk rows by point.
  Index n_rows() const { return n_lin() + (N_ + 1) * jerk_rows_per_point_; }
  std::size_t n_active() const { return active_.size(); }
  std::size_t n_jerk_rows() const { return static_cast<std::size_t>((N_ + 1) * jerk_rows_per_point_); }
  std::size_t n_implied() const { return static_cast<std::size_t>(n_rows()) - active_.size(); }

  /// The value and bounds of full row r at x (update(x) true).
  double row_value(Index r, const Number* x) const;
  void row_bounds(Index r, double& lo, double& hi) const;
  /// The jerk limits' factor at grid point p (JerkTimingOptions::jerk_scale; 1 without).
  double jerk_sigma(Index p) const {
    return opt_.jerk_scale.empty() ? 1.0 : opt_.jerk_scale[static_cast<std::size_t>(p)];
  }
  /// Largest excess of x over any bound or row, the left-out jerk rows included, in the
  /// limit's unit (0: feasible).
  double full_violation(const Number* x);

  bool get_nlp_info(Index& n, Index& m, Index& nnz_jac, Index& nnz_h, IndexStyleEnum& style) override;
  bool get_bounds_info(Index n, Number* xl, Number* xu, Index m, Number* gl, Number* gu) override;
  bool get_starting_point(Index n, bool init_x, Number* x, bool, Number*, Number*, Index, bool, Number*) override;
  bool eval_f(Index, const Number* x, bool, Number& f) override;
  bool eval_grad_f(Index n, const Number* x, bool, Number* gf) override;
  bool eval_g(Index, const Number* x, bool, Index m, Number* g) override;
  bool eval_jac_g(Index, const Number* x, bool, Index m, Index, Index* row, Index* col, Number* val) override;
  bool eval_h(Index, const Number* x, bool, Number sigma, Index m, const Number* lambda, bool, Index, Index* row,
              Index* col, Number* val) override;
  // A cancelled call stops Ipopt at its next iteration (User_Requested_Stop).
  bool intermediate_callback(Ipopt::AlgorithmMode, Index, Number, Number, Number, Number, Number, Number, Number,
                             Number, Index, const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override;
  void finalize_solution(Ipopt::SolverReturn, Index n, const Number* x, const Number*, const Number*, Index,
                         const Number*, const Number*, Number, const Ipopt::IpoptData*,
                         Ipopt::IpoptCalculatedQuantities*) override;

  /// The jerk j_i at every grid point [m/s^3] of x (update(x) true).
  std::vector<double> jerk(const Number* x);

  std::vector<double> x0_, x_;  ///< Ipopt's start and its result

 private:
  /// Per grid point: the objective's share tau + w j^2 tau [s] with derivatives, and j.
  struct Terms {
    D3 obj;
    double j = 0.0;
  };

  Index n_lin() const { return static_cast<Index>(lin_lo_.size()); }
  Index point_vars(Index p) const;
  Index row_nnz(Index r) const {
    return r < n_lin() ? lin_begin_[r + 1] - lin_begin_[r] : point_vars((r - n_lin()) / jerk_rows_per_point_);
  }

  /// sigma of grid point p (JerkTimingOptions::limit_scale; 1 without).
  double sigma(Index p) const {
    return opt_.limit_scale.empty() ? 1.0 : opt_.limit_scale[static_cast<std::size_t>(p)];
  }

  double point_cap(Index p) const;
  // The rows and the per-point terms at x (jerk_timing_nlp.cpp has how they are built).
  void select_jerk_rows();
  void build_linear_rows();
  bool update(const Number* x);

  const std::vector<core::GridPoint>& g_;
  const core::TimeOptimalLimits& lim_;
  const JerkTimingOptions& opt_;
  Index N_ = 0;
  std::vector<core::JointVector> q_sss_;
  std::vector<Index> jerk_joints_;
  bool cart_jerk_ = false;
  Index jerk_rows_per_point_ = 0;
  // Linear rows (compressed by row): columns, coefficients, bounds.
  std::vector<Index> lin_begin_, lin_col_;
  std::vector<double> lin_coef_, lin_lo_, lin_hi_;
  std::vector<Index> hess_offset_;  ///< row k of the banded lower triangle starts here
  std::vector<Index> active_;       ///< the rows handed to Ipopt (full row ids, ascending)
  // Cache of update().
  std::vector<double> cached_x_;
  bool have_ = false, ok_ = false;
  std::vector<Terms> terms_;
  std::vector<D3> jerk_rows_;
};

}  // namespace geotraj::optim::detail
