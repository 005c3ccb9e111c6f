// Ipopt's solve of the tangent scales where each segment depends on its own two scales (lowest
// degree, the thesis's zeros): the NLP with exact derivatives (ScaleNlp) and Ipopt's options.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>
#include <vector>

#include <coin/IpIpoptApplication.hpp>
#include <coin/IpTNLP.hpp>

#include "optim/tangent_scales/tangent_scales_detail.hpp"

namespace geotraj::optim::tangent_scales_detail {
namespace {

// Ipopt, with the exact Hessian (see evaluate). tol 1e-6 on Ipopt's scaled KKT error; Ipopt stops earlier at the acceptable level (KKT
// error 1e-3) once the objective changes by less than 1e-4 relative on 2 successive
// iterations: below the fixed rules' own accuracy (kRuleAgreement) there is nothing to gain.
constexpr double kIpoptTol = 1e-6;
constexpr double kIpoptAcceptableTol = 1e-3;
constexpr int kIpoptAcceptableIter = 2;
constexpr double kIpoptAcceptableObjChange = 1e-4;

// Variables: y_i = ln(scale_i) (the scales span two decades and the objectives vary like
// powers of them: in logarithms Newton's quadratic model is far better conditioned).
// Objective: the integral, or the peaks' aggregate F (kAggregatePower). Rows: the regularity
// rows G_r >= 0 (regularity_rows), each depending on its segment's two scales. Hessian: exact,
// the lower triangle (dense for the peaks, whose aggregate couples every segment).
class ScaleNlp : public Ipopt::TNLP {
 public:
  ScaleNlp(const Problem& pb, Clock::time_point stop_at, std::stop_token stop)
      : pb_(pb), stop_at_(stop_at), stop_(std::move(stop)), n_(pb.scale_count),
        m_(static_cast<int>(pb.constraint_count())) {
    evaluate(pb_, pb_.start.data(), ev_);
    v0_ = ev_.largest;  // the aggregate's unit: the largest peak row at the start
    candidates_.reserve(256);
    // The Hessian's lower triangle: every pair for the peaks (the aggregate couples all
    // segments), else the diagonal and each segment's pair (its integral and its row).
    hess_index_.assign(static_cast<std::size_t>(n_) * n_, -1);
    const auto add = [&](int i, int j) {
      if (i < j) std::swap(i, j);
      if (hess_index_[i * n_ + j] >= 0) return;
      hess_index_[i * n_ + j] = static_cast<int>(hess_rows_.size());
      hess_rows_.push_back(i);
      hess_cols_.push_back(j);
    };
    for (int i = 0; i < n_; ++i)
      for (int j = 0; j <= i; ++j)
        if (i == j || pb_.peak()) add(i, j);
    for (const auto& sg : pb_.segments) add(sg.var0, sg.var1);
  }

  const std::vector<Candidate>& candidates() const { return candidates_; }
  const std::vector<double>& final_scales() const { return final_; }
  bool timed_out() const { return timed_out_; }
  int iterations() const { return iterations_; }

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac_g, Ipopt::Index& nnz_h_lag,
                    IndexStyleEnum& index_style) override {
    n = n_;
    m = m_;
    nnz_jac_g = 2 * static_cast<int>(pb_.regularity_count()) + (pb_.length_row() ? n_ : 0);
    nnz_h_lag = static_cast<Ipopt::Index>(hess_rows_.size());
    index_style = C_STYLE;
    return true;
  }

  bool get_bounds_info(Ipopt::Index, Ipopt::Number* x_l, Ipopt::Number* x_u, Ipopt::Index m, Ipopt::Number* g_l,
                       Ipopt::Number* g_u) override {
    for (int i = 0; i < pb_.scale_count; ++i) {
      x_l[i] = std::log(pb_.lower[i]);
      x_u[i] = std::log(pb_.upper[i]);
    }
    for (int j = 0; j < m; ++j) {
      g_l[j] = 0.0;
      g_u[j] = 2e19;  // unbounded for Ipopt (nlp_upper_bound_inf = 1e19)
    }
    return true;
  }

  bool get_starting_point(Ipopt::Index, bool init_x, Ipopt::Number* x, bool, Ipopt::Number*, Ipopt::Number*,
                          Ipopt::Index, bool, Ipopt::Number*) override {
    if (!init_x) return false;
    for (int i = 0; i < pb_.scale_count; ++i) x[i] = std::log(pb_.start[i]);  // the request's scales
    return true;
  }

  bool eval_f(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number& obj) override {
    if (!update(x)) return false;
    obj = ev_.f;
    return true;
  }

  bool eval_grad_f(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number* grad) override {
    if (!update(x)) return false;
    std::copy(ev_.grad.begin(), ev_.grad.end(), grad);
    return true;
  }

  bool eval_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Number* g) override {
    if (!update(x)) return false;
    const int reg = static_cast<int>(pb_.regularity_count());
    for (int j = 0; j < reg; ++j) g[j] = ev_.g[j].f;
    if (m > reg) g[reg] = ev_.length_row;
    return true;
  }

  bool eval_jac_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Index, Ipopt::Index* rows,
                  Ipopt::Index* cols, Ipopt::Number* values) override {
    const int reg = static_cast<int>(pb_.regularity_count());
    if (values == nullptr) {
      for (int j = 0; j < reg; ++j) {
        const auto& sg = pb_.segments[j / pb_.rows_per_segment];
        rows[2 * j] = rows[2 * j + 1] = j;
        cols[2 * j] = sg.var0;
        cols[2 * j + 1] = sg.var1;
      }
      for (int k = 0; m > reg && k < n_; ++k) {
        rows[2 * reg + k] = reg;
        cols[2 * reg + k] = k;
      }
      return true;
    }
    if (!update(x)) return false;
    for (int j = 0; j < reg; ++j) {
      values[2 * j] = ev_.g[j].g[0];
      values[2 * j + 1] = ev_.g[j].g[1];
    }
    for (int k = 0; m > reg && k < n_; ++k) values[2 * reg + k] = ev_.length_grad[k];
    return true;
  }

  // The exact Hessian of the Lagrangian obj_factor f + sum_j lambda_j G_j (lower triangle).
  bool eval_h(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number obj_factor, Ipopt::Index m,
              const Ipopt::Number* lambda, bool, Ipopt::Index, Ipopt::Index* rows, Ipopt::Index* cols,
              Ipopt::Number* values) override {
    if (values == nullptr) {
      std::copy(hess_rows_.begin(), hess_rows_.end(), rows);
      std::copy(hess_cols_.begin(), hess_cols_.end(), cols);
      return true;
    }
    if (!update(x)) return false;
    for (std::size_t k = 0; k < hess_rows_.size(); ++k) values[k] = obj_factor * ev_.hess[hess_rows_[k] * n_ + hess_cols_[k]];
    const int reg = static_cast<int>(pb_.regularity_count());
    for (int j = 0; j < reg; ++j) {
      const auto& sg = pb_.segments[j / pb_.rows_per_segment];
      const AD& G = ev_.g[j];
      values[hess_index_[sg.var0 * n_ + sg.var0]] += lambda[j] * G.h[0];
      values[hess_index_[sg.var1 * n_ + sg.var1]] += lambda[j] * G.h[2];
      values[hess_index_[std::max(sg.var0, sg.var1) * n_ + std::min(sg.var0, sg.var1)]] += lambda[j] * G.h[1];
    }
    if (m > reg) {  // the length row: -sum of the segments' lengths / max_length
      const double w = -lambda[reg] / pb_.max_length;
      for (std::size_t i = 0; i < pb_.segments.size(); ++i) {
        const auto& sg = pb_.segments[i];
        const AD& L = ev_.length[i];
        values[hess_index_[sg.var0 * n_ + sg.var0]] += w * L.h[0];
        values[hess_index_[sg.var1 * n_ + sg.var1]] += w * L.h[2];
        values[hess_index_[std::max(sg.var0, sg.var1) * n_ + std::min(sg.var0, sg.var1)]] += w * L.h[1];
      }
    }
    return true;
  }

  bool intermediate_callback(Ipopt::AlgorithmMode, Ipopt::Index iter, Ipopt::Number, Ipopt::Number, Ipopt::Number,
                             Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Index,
                             const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    iterations_ = iter;
    if (Clock::now() >= stop_at_ || stop_.stop_requested()) {
      timed_out_ = true;
      return false;  // User_Requested_Stop
    }
    return true;
  }

  void finalize_solution(Ipopt::SolverReturn, Ipopt::Index, const Ipopt::Number* x, const Ipopt::Number*,
                         const Ipopt::Number*, Ipopt::Index, const Ipopt::Number*, const Ipopt::Number*, Ipopt::Number,
                         const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    final_.resize(pb_.scale_count);
    for (int i = 0; i < pb_.scale_count; ++i) final_[i] = std::clamp(std::exp(x[i]), pb_.lower[i], pb_.upper[i]);
  }

 private:
  // Evaluates at x (its scales exp(y) clamped into the bounds, which Ipopt may leave by its
  // bound relaxation) unless x is the last point, and records it as a candidate if it is regular.
  bool update(const Ipopt::Number* x) {
    if (have_ && std::equal(x, x + pb_.scale_count, x_.begin())) return ev_ok_;
    x_.assign(x, x + pb_.scale_count);
    scales_.resize(pb_.scale_count);
    for (int i = 0; i < pb_.scale_count; ++i) scales_[i] = std::clamp(std::exp(x_[i]), pb_.lower[i], pb_.upper[i]);
    evaluate(pb_, scales_.data(), ev_, v0_);
    have_ = true;
    ev_ok_ = finite(ev_);
    if (ev_ok_ && ev_.regular) candidates_.push_back({scales_, pb_.peak() ? ev_.largest : ev_.f});
    return ev_ok_;
  }

  const Problem& pb_;
  Clock::time_point stop_at_;
  std::stop_token stop_;
  int n_, m_;
  Evaluation ev_;
  double v0_ = 0.0;
  std::vector<double> x_, scales_, final_;
  std::vector<int> hess_index_;                // n x n -> entry of the Hessian's lower triangle, or -1
  std::vector<Ipopt::Index> hess_rows_, hess_cols_;
  bool have_ = false, ev_ok_ = false;
  std::vector<Candidate> candidates_;
  bool timed_out_ = false;
  int iterations_ = 0;
};

const char* ipopt_status_name(Ipopt::ApplicationReturnStatus s) {
  switch (s) {
    case Ipopt::Solve_Succeeded: return "Ipopt: solve succeeded";
    case Ipopt::Solved_To_Acceptable_Level: return "Ipopt: solved to acceptable level";
    case Ipopt::Infeasible_Problem_Detected: return "Ipopt: infeasible problem detected";
    case Ipopt::Search_Direction_Becomes_Too_Small: return "Ipopt: search direction becomes too small";
    case Ipopt::Diverging_Iterates: return "Ipopt: diverging iterates";
    case Ipopt::User_Requested_Stop: return "Ipopt: stopped at the time limit";
    case Ipopt::Feasible_Point_Found: return "Ipopt: feasible point found";
    case Ipopt::Maximum_Iterations_Exceeded: return "Ipopt: maximum iterations exceeded";
    case Ipopt::Restoration_Failed: return "Ipopt: restoration failed";
    case Ipopt::Error_In_Step_Computation: return "Ipopt: error in step computation";
    case Ipopt::Maximum_CpuTime_Exceeded: return "Ipopt: maximum CPU time exceeded";
    case Ipopt::Invalid_Number_Detected: return "Ipopt: invalid number detected";
    default: return "Ipopt: internal failure";
  }
}

}  // namespace

SolverRun solve_ipopt(Problem& pb, Clock::time_point stop_at, const TangentScaleOptions& options,
                      OptimizerReport& report) {
  Ipopt::SmartPtr<ScaleNlp> nlp = new ScaleNlp(pb, stop_at, options.stop);
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  auto& opts = *app->Options();
  opts.SetIntegerValue("print_level", 0);
  opts.SetStringValue("sb", "yes");
  opts.SetIntegerValue("max_iter", options.max_iterations);
  opts.SetNumericValue("tol", kIpoptTol);
  opts.SetNumericValue("acceptable_tol", kIpoptAcceptableTol);
  opts.SetIntegerValue("acceptable_iter", kIpoptAcceptableIter);
  opts.SetNumericValue("acceptable_obj_change_tol", kIpoptAcceptableObjChange);
  opts.SetStringValue("mu_strategy", "adaptive");
  // The KKT systems have a few dozen rows: no iterative refinement unless the residual asks
  // for it (Ipopt's default always does one, a second MUMPS back-solve per solve).
  opts.SetIntegerValue("min_refinement_steps", 0);
  std::istringstream no_options_file;
  if (app->Initialize(no_options_file) != Ipopt::Solve_Succeeded) {
    report.status = OptimizerStatus::kFailed;
    report.message = "Ipopt did not initialise";
    return {};
  }
  Ipopt::ApplicationReturnStatus status = app->OptimizeTNLP(nlp);
  report.iterations = nlp->iterations();
  if ((status == Ipopt::Infeasible_Problem_Detected || status == Ipopt::Restoration_Failed) && !nlp->timed_out()) {
    // Again with one regularity row per sample (see kRegularityRows), same application.
    pb.rows_per_segment = kRegularitySamples;
    nlp = new ScaleNlp(pb, stop_at, options.stop);
    status = app->OptimizeTNLP(nlp);
    report.iterations += nlp->iterations();
  }
  report.message = ipopt_status_name(status);

  switch (status) {
    case Ipopt::Solve_Succeeded:
    case Ipopt::Solved_To_Acceptable_Level:
    case Ipopt::Search_Direction_Becomes_Too_Small:
    case Ipopt::Feasible_Point_Found: report.status = OptimizerStatus::kConverged; break;
    case Ipopt::Maximum_Iterations_Exceeded: report.status = OptimizerStatus::kIterationLimit; break;
    case Ipopt::User_Requested_Stop:
    case Ipopt::Maximum_CpuTime_Exceeded: report.status = OptimizerStatus::kTimeLimit; break;
    default: report.status = OptimizerStatus::kFailed; break;
  }
  if (nlp->timed_out()) report.status = OptimizerStatus::kTimeLimit;
  return {nlp->final_scales(), nlp->candidates()};
}

}  // namespace geotraj::optim::tangent_scales_detail
