// NLopt's SLSQP on the smoothest reading, where each segment depends on every scale: the
// objective and rows in double, their derivatives by central differences (GlobalSolver).
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include <nlopt.h>

#include "optim/tangent_scales/tangent_scales_detail.hpp"

namespace geotraj::optim::tangent_scales_detail {
namespace {

// The smoothest reading on NLopt's SLSQP (sequential quadratic programming, bounds and the
// regularity rows as inequality constraints). Each segment depends on every scale through the
// global solve, so the derivatives are central differences in y = ln(scale) of the whole
// evaluation (objective and rows together, step kDifferenceStep): 2 n + 1 global solves per
// gradient for n scales. Ipopt's exact-Hessian model of the lowest-degree reading does not
// apply; SLSQP's quasi-Newton model needs no Hessian. NLopt is reentrant (no global state
// for SLSQP), so no lock is taken. Iterations count evaluations with their gradient.
constexpr double kSlsqpFtolRel = 1e-7;
constexpr double kSlsqpXtolRel = 1e-6;
constexpr double kFailedValue = 1e30;  // an evaluation that failed (singular solve): a bad point for SLSQP

class GlobalSolver {
 public:
  GlobalSolver(const Problem& pb, Clock::time_point stop_at, std::stop_token stop)
      : pb_(pb), stop_at_(stop_at), stop_(std::move(stop)), n_(pb.scale_count),
        m_(static_cast<int>(pb.constraint_count())) {
    GlobalEvaluation start;
    evaluate_global(pb_, pb_.start.data(), start, 0.0, points_);
    v0_ = start.largest;
  }

  // Runs SLSQP from the request's scales; returns NLopt's result.
  nlopt_result run(int max_evaluations) {
    nlopt_opt opt = nlopt_create(NLOPT_LD_SLSQP, static_cast<unsigned>(n_));
    opt_ = opt;
    std::vector<double> lo(n_), hi(n_), y(n_);
    for (int i = 0; i < n_; ++i) {
      lo[i] = std::log(pb_.lower[i]);
      hi[i] = std::log(pb_.upper[i]);
      y[i] = std::clamp(std::log(pb_.start[i]), lo[i], hi[i]);
    }
    nlopt_set_lower_bounds(opt, lo.data());
    nlopt_set_upper_bounds(opt, hi.data());
    nlopt_set_min_objective(opt, &GlobalSolver::objective, this);
    const std::vector<double> tol(m_, 0.0);
    nlopt_add_inequality_mconstraint(opt, static_cast<unsigned>(m_), &GlobalSolver::constraints, this, tol.data());
    nlopt_set_ftol_rel(opt, kSlsqpFtolRel);
    nlopt_set_xtol_rel(opt, kSlsqpXtolRel);
    nlopt_set_maxeval(opt, max_evaluations);
    double f = 0.0;
    const nlopt_result result = nlopt_optimize(opt, y.data(), &f);
    nlopt_destroy(opt);
    opt_ = nullptr;
    final_.resize(n_);
    for (int i = 0; i < n_; ++i) final_[i] = std::clamp(std::exp(y[i]), pb_.lower[i], pb_.upper[i]);
    return result;
  }

  const std::vector<Candidate>& candidates() const { return candidates_; }
  const std::vector<double>& final_scales() const { return final_; }
  bool timed_out() const { return timed_out_; }
  int iterations() const { return iterations_; }

 private:
  static double objective(unsigned, const double* y, double* grad, void* data) {
    auto& s = *static_cast<GlobalSolver*>(data);
    if (!s.update(y, grad != nullptr)) return kFailedValue;
    if (grad) std::copy(s.grad_.begin(), s.grad_.end(), grad);
    return s.ev_.f;
  }

  // NLopt's form c(y) <= 0: c = -G.
  static void constraints(unsigned m, double* result, unsigned n, const double* y, double* grad, void* data) {
    auto& s = *static_cast<GlobalSolver*>(data);
    if (!s.update(y, grad != nullptr)) {
      std::fill(result, result + m, kFailedValue);
      if (grad) std::fill(grad, grad + static_cast<std::size_t>(m) * n, 0.0);
      return;
    }
    for (unsigned j = 0; j < m; ++j) result[j] = -s.ev_.g[j];
    if (grad) {
      for (std::size_t k = 0; k < static_cast<std::size_t>(m) * n; ++k) grad[k] = -s.jac_[k];
    }
  }

  bool out_of_time() {
    if (Clock::now() >= stop_at_ || stop_.stop_requested()) {
      timed_out_ = true;
      if (opt_) nlopt_force_stop(opt_);
      return true;
    }
    return false;
  }

  // Evaluates at y (scales exp(y) clamped into the bounds) unless y is the last point, and its
  // derivatives if asked; records a regular point as a candidate.
  bool update(const double* y, bool derivatives) {
    const bool same = have_ && std::equal(y, y + n_, y_.begin());
    if (same && (!derivatives || have_derivatives_)) return ok_;
    if (out_of_time()) return false;
    if (!same) {
      y_.assign(y, y + n_);
      scales_.resize(n_);
      for (int i = 0; i < n_; ++i) scales_[i] = std::clamp(std::exp(y_[i]), pb_.lower[i], pb_.upper[i]);
      evaluate_global(pb_, scales_.data(), ev_, v0_, points_);
      have_ = true;
      have_derivatives_ = false;
      ok_ = ev_.ok;
      if (ok_ && ev_.regular) candidates_.push_back({scales_, pb_.peak() ? ev_.largest : ev_.f});
    }
    if (!ok_ || !derivatives) return ok_;
    ++iterations_;
    grad_.assign(n_, 0.0);
    jac_.assign(static_cast<std::size_t>(m_) * n_, 0.0);
    std::vector<double> probe = scales_;
    GlobalEvaluation plus, minus;
    for (int k = 0; k < n_; ++k) {
      if (out_of_time()) return false;
      probe[k] = scales_[k] * std::exp(kDifferenceStep);
      evaluate_global(pb_, probe.data(), plus, v0_, points_);
      probe[k] = scales_[k] * std::exp(-kDifferenceStep);
      evaluate_global(pb_, probe.data(), minus, v0_, points_);
      probe[k] = scales_[k];
      if (!plus.ok || !minus.ok) continue;  // a singular neighbour: no slope along k
      grad_[k] = (plus.f - minus.f) / (2.0 * kDifferenceStep);
      for (int j = 0; j < m_; ++j) jac_[j * n_ + k] = (plus.g[j] - minus.g[j]) / (2.0 * kDifferenceStep);
    }
    have_derivatives_ = true;
    return true;
  }

  const Problem& pb_;
  Clock::time_point stop_at_;
  std::stop_token stop_;
  int n_, m_;
  nlopt_opt opt_ = nullptr;
  double v0_ = 0.0;
  GlobalEvaluation ev_;
  std::vector<ControlPoints<double>> points_;
  std::vector<double> y_, scales_, grad_, jac_, final_;
  bool have_ = false, have_derivatives_ = false, ok_ = false;
  std::vector<Candidate> candidates_;
  bool timed_out_ = false;
  int iterations_ = 0;
};

const char* nlopt_status_name(nlopt_result r) {
  switch (r) {
    case NLOPT_SUCCESS: return "SLSQP: converged";
    case NLOPT_STOPVAL_REACHED: return "SLSQP: objective value reached";
    case NLOPT_FTOL_REACHED: return "SLSQP: converged (objective tolerance)";
    case NLOPT_XTOL_REACHED: return "SLSQP: converged (step tolerance)";
    case NLOPT_MAXEVAL_REACHED: return "SLSQP: evaluation limit reached";
    case NLOPT_MAXTIME_REACHED: return "SLSQP: time limit reached";
    case NLOPT_ROUNDOFF_LIMITED: return "SLSQP: stopped by rounding";
    case NLOPT_FORCED_STOP: return "SLSQP: stopped at the time limit";
    case NLOPT_INVALID_ARGS: return "SLSQP: invalid arguments";
    case NLOPT_OUT_OF_MEMORY: return "SLSQP: out of memory";
    default: return "SLSQP: failure";
  }
}

}  // namespace

SolverRun solve_slsqp(const Problem& pb, Clock::time_point stop_at, const TangentScaleOptions& options,
                      OptimizerReport& report) {
  GlobalSolver solver(pb, stop_at, options.stop);
  const nlopt_result result = solver.run(std::max(1, options.max_iterations));
  report.iterations = solver.iterations();
  report.message = nlopt_status_name(result);
  switch (result) {
    case NLOPT_SUCCESS:
    case NLOPT_STOPVAL_REACHED:
    case NLOPT_FTOL_REACHED:
    case NLOPT_XTOL_REACHED:
    case NLOPT_ROUNDOFF_LIMITED: report.status = OptimizerStatus::kConverged; break;
    case NLOPT_MAXEVAL_REACHED: report.status = OptimizerStatus::kIterationLimit; break;
    case NLOPT_FORCED_STOP:
    case NLOPT_MAXTIME_REACHED: report.status = OptimizerStatus::kTimeLimit; break;
    default: report.status = OptimizerStatus::kFailed; break;
  }
  if (solver.timed_out()) report.status = OptimizerStatus::kTimeLimit;
  return {solver.final_scales(), solver.candidates()};
}

}  // namespace geotraj::optim::tangent_scales_detail
