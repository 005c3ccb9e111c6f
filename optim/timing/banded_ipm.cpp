#include "optim/timing/banded_ipm.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include <IpTNLP.hpp>

#include "optim/timing/banded_cholesky.hpp"

namespace geotraj::optim::detail {

namespace {

using Ipopt::Index;
constexpr double kBoundInf = 1e19;  ///< Ipopt's nlp_lower/upper_bound_inf

/// One inequality c_k(x) = sign (v - bound) >= 0, v the variable or the row `index`.
struct Inequality {
  bool row = false;
  Index index = 0;
  double sign = 1.0;
  double bound = 0.0;
};

/// The functions at one point.
struct Point {
  std::vector<double> x, g, c, s;  ///< c: the bounds' then the rows' inequalities; s: the rows' slacks
  double f = 0.0;
};

}  // namespace

BandedIpmResult solve_banded_ipm(Ipopt::TNLP& nlp, const BandedIpmOptions& opt) {
  BandedIpmResult out;
  Index n = 0, m = 0, nnz_j = 0, nnz_h = 0;
  Ipopt::TNLP::IndexStyleEnum style = Ipopt::TNLP::C_STYLE;
  if (!nlp.get_nlp_info(n, m, nnz_j, nnz_h, style) || style != Ipopt::TNLP::C_STYLE || n <= 0) {
    out.message = "unsupported problem";
    return out;
  }
  const auto un = static_cast<std::size_t>(n), um = static_cast<std::size_t>(m);
  std::vector<double> xl(un), xu(un), gl(um), gu(um);
  nlp.get_bounds_info(n, xl.data(), xu.data(), m, gl.data(), gu.data());
  std::vector<Index> jr(static_cast<std::size_t>(nnz_j)), jc(jr.size()), hr(static_cast<std::size_t>(nnz_h)),
      hc(hr.size());
  if (!nlp.eval_jac_g(n, nullptr, false, m, nnz_j, jr.data(), jc.data(), nullptr) ||
      !nlp.eval_h(n, nullptr, false, 1.0, m, nullptr, false, nnz_h, hr.data(), hc.data(), nullptr)) {
    out.message = "no derivative structure";
    return out;
  }
  // The band: every Hessian entry and every pair of variables in one row within w.
  std::size_t w = 0;
  std::vector<Index> row_lo(um, n), row_hi(um, -1);
  for (std::size_t e = 0; e < jr.size(); ++e) {
    const auto r = static_cast<std::size_t>(jr[e]);
    row_lo[r] = std::min(row_lo[r], jc[e]);
    row_hi[r] = std::max(row_hi[r], jc[e]);
  }
  for (std::size_t r = 0; r < um; ++r)
    if (row_hi[r] >= row_lo[r]) w = std::max(w, static_cast<std::size_t>(row_hi[r] - row_lo[r]));
  for (std::size_t e = 0; e < hr.size(); ++e) w = std::max(w, static_cast<std::size_t>(std::abs(hr[e] - hc[e])));
  if (w > opt.max_bandwidth) {
    out.message = "half-bandwidth " + std::to_string(w) + " above " + std::to_string(opt.max_bandwidth);
    return out;
  }
  // The inequalities: the variables' bounds, kept strictly (b > 0 is needed to evaluate),
  // and the rows' sides, each with a slack s_k > 0 and the constraint c_k(x) - s_k = 0.
  std::vector<Inequality> bnd, rows;
  for (Index i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (xl[k] == xu[k]) {
      out.message = "fixed variables are not supported";
      return out;
    }
    if (xl[k] > -kBoundInf) bnd.push_back({false, i, 1.0, xl[k]});
    if (xu[k] < kBoundInf) bnd.push_back({false, i, -1.0, xu[k]});
  }
  for (Index r = 0; r < m; ++r) {
    const auto k = static_cast<std::size_t>(r);
    if (gl[k] == gu[k]) {
      out.message = "equality rows are not supported";
      return out;
    }
    if (gl[k] > -kBoundInf) rows.push_back({true, r, 1.0, gl[k]});
    if (gu[k] < kBoundInf) rows.push_back({true, r, -1.0, gu[k]});
  }
  // The smallest starting slack of each row side (Ipopt's bound_push 1e-2, relative to the
  // bound and at most 1e-2 of the row's width).
  std::vector<double> push;
  for (const Inequality& q : rows) {
    const auto k = static_cast<std::size_t>(q.index);
    const double width = gl[k] > -kBoundInf && gu[k] < kBoundInf ? gu[k] - gl[k] : kBoundInf;
    push.push_back(1e-2 * std::min(width, std::max(1.0, std::abs(q.bound))));
  }
  const std::size_t mb = bnd.size(), mr = rows.size();

  // Evaluates f, g and the inequalities' c at p.x; false where the problem cannot be evaluated.
  auto evaluate = [&](Point& p) {
    p.g.resize(um);
    p.c.resize(mb + mr);
    if (!nlp.eval_f(n, p.x.data(), true, p.f) || !std::isfinite(p.f)) return false;
    if (m > 0 && !nlp.eval_g(n, p.x.data(), false, m, p.g.data())) return false;
    for (std::size_t k = 0; k < mb; ++k)
      p.c[k] = bnd[k].sign * (p.x[static_cast<std::size_t>(bnd[k].index)] - bnd[k].bound);
    for (std::size_t k = 0; k < mr; ++k)
      p.c[mb + k] = rows[k].sign * (p.g[static_cast<std::size_t>(rows[k].index)] - rows[k].bound);
    return std::all_of(p.c.begin(), p.c.end(), [](double c) { return std::isfinite(c); });
  };
  // The barrier function f - mu sum log (the bounds' c and the rows' slacks).
  auto barrier_fn = [&](const Point& p, double mu) {
    double lb = 0.0;
    for (std::size_t k = 0; k < mb; ++k) lb += std::log(p.c[k]);
    for (std::size_t k = 0; k < mr; ++k) lb += std::log(p.s[k]);
    return p.f - mu * lb;
  };

  Point cur;
  cur.x.resize(un);
  nlp.get_starting_point(n, true, cur.x.data(), false, nullptr, nullptr, m, false, nullptr);
  // A start on or beyond a bound moves inside by Ipopt's bound push (1e-2 relative to the
  // bound, at most 1e-2 of the range); a start strictly inside stays.
  for (std::size_t i = 0; i < un; ++i) {
    const double range = xu[i] - xl[i];
    if (xl[i] > -kBoundInf && !(cur.x[i] > xl[i]))
      cur.x[i] = xl[i] + std::min(1e-2 * std::max(1.0, std::abs(xl[i])), 1e-2 * range);
    if (xu[i] < kBoundInf && !(cur.x[i] < xu[i]))
      cur.x[i] = xu[i] - std::min(1e-2 * std::max(1.0, std::abs(xu[i])), 1e-2 * range);
  }
  if (!evaluate(cur) ||
      !std::all_of(cur.c.begin(), cur.c.begin() + static_cast<std::ptrdiff_t>(mb), [](double c) { return c > 0.0; })) {
    out.message = "the problem cannot be evaluated at the start";
    return out;
  }
  cur.s.resize(mr);
  for (std::size_t k = 0; k < mr; ++k) cur.s[k] = std::max(cur.c[mb + k], push[k]);

  double mu = opt.mu_init;
  std::vector<std::pair<double, double>> filter;  // (theta, phi) margins, reset with mu
  double theta0 = -1.0;
  const double mu_min = opt.mu_min > 0.0 ? opt.mu_min : 1e-11;
  std::vector<double> z(mb + mr);
  for (std::size_t k = 0; k < mb; ++k) z[k] = mu / cur.c[k];
  for (std::size_t k = 0; k < mr; ++k) z[mb + k] = mu / cur.s[k];

  std::vector<double> grad(un), jac(jr.size()), hess(hr.size()), lambda(um), rd(un), rhs(un), jdx(um), dc(mb + mr),
      dz(mb + mr), row_weight(um), rp(mr), dx(un), dx_soc(un), dc_soc(mb + mr);
  BandMatrix M(un, w);
  BandedCholesky chol;
  double delta_last = 0.0;
  Point trial;
  trial.x.resize(un);
  trial.s.resize(mr);
  constexpr double kSigma = 1e10;  // Ipopt's kappa_sigma
  // The slack of inequality k (the bounds: c itself).
  auto slack = [&](const Point& p, std::size_t k) { return k < mb ? p.c[k] : p.s[k - mb]; };

  for (int iter = 0;; ++iter) {
    out.iterations = iter;
    out.mu = mu;
    out.x = cur.x;
    // Derivatives at the current point.
    if (!nlp.eval_grad_f(n, cur.x.data(), false, grad.data()) ||
        (nnz_j > 0 && !nlp.eval_jac_g(n, cur.x.data(), false, m, nnz_j, nullptr, nullptr, jac.data()))) {
      out.message = "evaluation failed";
      out.status = BandedIpmResult::Status::kFailed;
      return out;
    }
    // Dual infeasibility grad f - A^T z (A the Jacobian of c), primal infeasibility c - s.
    rd = grad;
    std::fill(lambda.begin(), lambda.end(), 0.0);  // Ipopt's row multipliers: -sum sign z
    for (std::size_t k = 0; k < mb; ++k) rd[static_cast<std::size_t>(bnd[k].index)] -= bnd[k].sign * z[k];
    for (std::size_t k = 0; k < mr; ++k) lambda[static_cast<std::size_t>(rows[k].index)] -= rows[k].sign * z[mb + k];
    for (std::size_t e = 0; e < jr.size(); ++e)
      rd[static_cast<std::size_t>(jc[e])] += lambda[static_cast<std::size_t>(jr[e])] * jac[e];
    double dual_inf = 0.0, z_sum = 0.0, primal_inf = 0.0, primal_l1 = 0.0;
    for (const double r : rd) dual_inf = std::max(dual_inf, std::abs(r));
    for (const double zk : z) z_sum += zk;
    for (std::size_t k = 0; k < mr; ++k) {
      const double r = std::abs(cur.c[mb + k] - cur.s[k]);
      primal_inf = std::max(primal_inf, r);
      primal_l1 += r;
    }
    const double s_d = std::max(100.0, z_sum / static_cast<double>(std::max<std::size_t>(1, z.size()))) / 100.0;
    auto complementarity = [&](double target) {
      double e = 0.0;
      for (std::size_t k = 0; k < z.size(); ++k) e = std::max(e, std::abs(slack(cur, k) * z[k] - target));
      return e;
    };
    const double compl0 = complementarity(0.0);
    out.error = std::max({dual_inf / s_d, primal_inf, compl0 / s_d});
    double gap = 0.0;  // sum s z: the objective's distance to the optimum of a convex problem
    for (std::size_t k = 0; k < z.size(); ++k) gap += slack(cur, k) * z[k];
    double violation = 0.0;  // of the rows themselves (the bounds hold strictly)
    for (std::size_t k = 0; k < mr; ++k) violation = std::max(violation, -cur.c[mb + k]);
    if (out.error <= opt.tol && dual_inf <= 1.0 && compl0 <= 1e-4 && violation <= opt.constr_viol_tol &&
        gap <= 10.0 * opt.tol * std::max(1.0, std::abs(cur.f))) {
      out.status = BandedIpmResult::Status::kConverged;
      out.message = "converged";
      return out;
    }
    // Barrier update (monotone).
    while (mu > mu_min && std::max({dual_inf / s_d, primal_inf, complementarity(mu) / s_d}) <= 10.0 * mu) {
      mu = std::max(mu_min, std::min(0.2 * mu, std::pow(mu, 1.5)));
      filter.clear();
    }
    if (theta0 < 0.0) theta0 = primal_l1;
    out.mu = mu;
    if (iter >= opt.max_iterations) {
      out.status = BandedIpmResult::Status::kIterationLimit;
      out.message = "iteration limit";
      return out;
    }
    if (std::chrono::steady_clock::now() >= opt.deadline || opt.stop.stop_requested()) {
      out.status = BandedIpmResult::Status::kTimeLimit;
      out.message = opt.stop.stop_requested() ? "stopped" : "time limit";
      return out;
    }

    // The condensed Newton matrix H_L + A^T Sigma A and its right-hand side
    // -grad f + A_b^T mu / c_b + A_r^T (mu / s - Sigma (c - s)).
    if (nnz_h > 0 &&
        !nlp.eval_h(n, cur.x.data(), false, 1.0, m, lambda.data(), true, nnz_h, nullptr, nullptr, hess.data())) {
      out.message = "Hessian evaluation failed";
      out.status = BandedIpmResult::Status::kFailed;
      return out;
    }
    M.set_zero();
    for (std::size_t e = 0; e < hr.size(); ++e) {
      const auto r = static_cast<std::size_t>(std::max(hr[e], hc[e])),
                 c = static_cast<std::size_t>(std::min(hr[e], hc[e]));
      M.at(r, c) += hess[e];
    }
    for (std::size_t k = 0; k < mb; ++k) {
      const auto i = static_cast<std::size_t>(bnd[k].index);
      M.at(i, i) += z[k] / cur.c[k];
    }
    std::fill(row_weight.begin(), row_weight.end(), 0.0);
    for (std::size_t k = 0; k < mr; ++k) row_weight[static_cast<std::size_t>(rows[k].index)] += z[mb + k] / cur.s[k];
    // A^T Sigma A row by row (a row's Jacobian entries are consecutive, as Ipopt's TNLP lists them).
    for (std::size_t e0 = 0; e0 < jr.size();) {
      std::size_t e1 = e0;
      while (e1 < jr.size() && jr[e1] == jr[e0]) ++e1;
      const double wr = row_weight[static_cast<std::size_t>(jr[e0])];
      for (std::size_t a = e0; a < e1; ++a)
        for (std::size_t b = e0; b < e1; ++b)
          if (jc[a] >= jc[b])
            M.at(static_cast<std::size_t>(jc[a]), static_cast<std::size_t>(jc[b])) += wr * jac[a] * jac[b];
      e0 = e1;
    }
    // Inertia correction (Ipopt's rule): delta = 0, else from 1e-4 (or a third of the last)
    // by factors of 100 (first time) or 8 until the factorisation succeeds.
    double delta = 0.0;
    while (!chol.factor(M, delta)) {
      delta = delta == 0.0 ? (delta_last == 0.0 ? 1e-4 : std::max(1e-20, delta_last / 3.0))
                           : delta * (delta_last == 0.0 ? 100.0 : 8.0);
      if (delta > 1e40) {
        out.status = BandedIpmResult::Status::kFailed;
        out.message = "inertia correction failed";
        return out;
      }
    }
    if (delta > 0.0) delta_last = delta;
    const double tau = std::max(0.995, 1.0 - mu);
    // The step for the rows' residual rp (c - s for the Newton step; a second-order
    // correction's otherwise): dx from the right-hand side
    // -grad f + A_b^T mu / c_b + A_r^T (mu / s - Sigma rp), dc = A dx (bounds) and
    // ds = A dx + rp (rows), and the largest step within the fraction to the boundary.
    auto direction = [&](const std::vector<double>& r_p, std::vector<double>& step, std::vector<double>& d,
                         double& alpha_max) {
      for (std::size_t i = 0; i < un; ++i) rhs[i] = -grad[i];
      for (std::size_t k = 0; k < mb; ++k) rhs[static_cast<std::size_t>(bnd[k].index)] += bnd[k].sign * mu / cur.c[k];
      std::fill(lambda.begin(), lambda.end(), 0.0);
      for (std::size_t k = 0; k < mr; ++k)
        lambda[static_cast<std::size_t>(rows[k].index)] +=
            rows[k].sign * (mu / cur.s[k] - z[mb + k] / cur.s[k] * r_p[k]);
      for (std::size_t e = 0; e < jr.size(); ++e)
        rhs[static_cast<std::size_t>(jc[e])] += lambda[static_cast<std::size_t>(jr[e])] * jac[e];
      step = rhs;
      chol.solve(step);
      std::fill(jdx.begin(), jdx.end(), 0.0);
      for (std::size_t e = 0; e < jr.size(); ++e)
        jdx[static_cast<std::size_t>(jr[e])] += jac[e] * step[static_cast<std::size_t>(jc[e])];
      d.resize(mb + mr);
      alpha_max = 1.0;
      for (std::size_t k = 0; k < mb + mr; ++k) {
        const Inequality& q = k < mb ? bnd[k] : rows[k - mb];
        const auto i = static_cast<std::size_t>(q.index);
        d[k] = k < mb ? q.sign * step[i] : q.sign * jdx[i] + r_p[k - mb];
        if (d[k] < 0.0) alpha_max = std::min(alpha_max, tau * slack(cur, k) / -d[k]);
      }
    };
    for (std::size_t k = 0; k < mr; ++k) rp[k] = cur.c[mb + k] - cur.s[k];
    double alpha = 1.0;
    direction(rp, dx, dc, alpha);
    double slope = 0.0;  // the barrier function's along (dx, ds)
    for (std::size_t i = 0; i < un; ++i) slope += grad[i] * dx[i];
    for (std::size_t k = 0; k < mb + mr; ++k) slope -= mu * dc[k] / slack(cur, k);
    // Filter line search (Waechter and Biegler 2006, Ipopt's constants): a trial point is
    // accepted when the filter accepts it and it either, where the step is a descent step
    // of the barrier function that outweighs the infeasibility (switching condition),
    // decreases the barrier function phi by Armijo's rule, or else decreases the
    // infeasibility theta = |c - s|_1 or phi sufficiently against the current point; second-
    // order corrections (up to four) when the full step is refused and raises theta (the
    // Maratos effect of the nonlinear jerk rows). Backtracking by halves.
    const double theta = primal_l1, phi = barrier_fn(cur, mu);
    constexpr double kGammaTheta = 1e-5, kGammaPhi = 1e-8, kEta = 1e-4, kSTheta = 1.1, kSPhi = 2.3;
    const double eps_phi = 10.0 * std::numeric_limits<double>::epsilon() * std::abs(phi);
    const double theta_min = 1e-4 * std::max(1.0, theta0), theta_max = 1e4 * std::max(1.0, theta0);
    auto acceptable = [&](double a, double theta_t, double phi_t, bool& is_f) {
      if (!std::isfinite(phi_t) || theta_t > theta_max) return false;
      for (const auto& [ft, fp] : filter)
        if (!(theta_t < ft || phi_t < fp)) return false;
      is_f = slope < 0.0 && a * std::pow(-slope, kSPhi) > std::pow(theta, kSTheta);
      if (is_f && theta <= theta_min) return phi_t <= phi + kEta * a * slope + eps_phi;
      if (is_f && phi_t <= phi + kEta * a * slope + eps_phi) return true;
      is_f = false;
      return theta_t <= (1.0 - kGammaTheta) * theta || phi_t <= phi - kGammaPhi * theta + eps_phi;
    };
    auto theta_of = [&](const Point& p) {
      double t = 0.0;
      for (std::size_t k = 0; k < mr; ++k) t += std::abs(p.c[mb + k] - p.s[k]);
      return t;
    };
    auto try_step = [&](const std::vector<double>& dxt, const std::vector<double>& dt, double a) {
      for (std::size_t i = 0; i < un; ++i) trial.x[i] = cur.x[i] + a * dxt[i];
      for (std::size_t k = 0; k < mr; ++k) trial.s[k] = cur.s[k] + a * dt[mb + k];
      if (!evaluate(trial)) return false;
      for (std::size_t k = 0; k < mb; ++k)
        if (!(trial.c[k] > 0.0)) return false;
      return true;
    };
    bool accepted = false, f_type = false;
    int socs = 0;
    const double alpha_max0 = alpha;
    int fails_eval = 0;
    for (int t = 0; t < 60 && alpha > 1e-16 && !accepted; ++t, alpha *= 0.5) {
      if (!try_step(dx, dc, alpha)) {
        ++fails_eval;
        continue;
      }
      const double theta_t = theta_of(trial);
      if (acceptable(alpha, theta_t, barrier_fn(trial, mu), f_type)) {
        accepted = true;
        break;
      }
      if (t > 0 || theta_t < theta) continue;
      std::vector<double> rp_soc(mr);
      double a_soc = alpha, theta_soc_old = theta, theta_soc = theta_t;
      for (std::size_t k = 0; k < mr; ++k) rp_soc[k] = alpha * rp[k] + (trial.c[mb + k] - trial.s[k]);
      for (int p = 0; p < 4 && (p == 0 || theta_soc <= 0.99 * theta_soc_old); ++p) {
        direction(rp_soc, dx_soc, dc_soc, a_soc);
        if (!try_step(dx_soc, dc_soc, a_soc)) break;
        theta_soc_old = theta_soc;
        theta_soc = theta_of(trial);
        if (acceptable(alpha, theta_soc, barrier_fn(trial, mu), f_type)) {
          accepted = true;
          ++socs;
          std::swap(dx, dx_soc);
          std::swap(dc, dc_soc);
          alpha = a_soc;
          break;
        }
        for (std::size_t k = 0; k < mr; ++k) rp_soc[k] = a_soc * rp_soc[k] + (trial.c[mb + k] - trial.s[k]);
      }
      if (accepted) break;
    }
    if (!accepted) {
      // No restoration phase: Ipopt's acceptable level (acceptable_tol = 1e3 tol) stops
      // here as converged, anything else as failed (the caller falls back to Ipopt).
      out.status = out.error <= 1e3 * opt.tol ? BandedIpmResult::Status::kConverged : BandedIpmResult::Status::kFailed;
      out.message = out.status == BandedIpmResult::Status::kConverged ? "converged to the acceptable level"
                                                                      : "line search failed";
      return out;
    }
    // An h-type step (not Armijo's) augments the filter with the current point's margins.
    if (!f_type) filter.emplace_back((1.0 - kGammaTheta) * theta, phi - kGammaPhi * theta);
    // The multipliers' step for the step taken, within the fraction to the boundary.
    double alpha_z = 1.0;
    for (std::size_t k = 0; k < mb + mr; ++k) {
      const double sk = slack(cur, k);
      dz[k] = mu / sk - z[k] - z[k] / sk * dc[k];
      if (dz[k] < 0.0) alpha_z = std::min(alpha_z, tau * z[k] / -dz[k]);
    }
    if (opt.trace)
      std::printf(
          "%3d f %.10f mu %.1e dual %.2e primal %.2e compl %.2e delta %.1e alpha %.2e (max %.2e) alpha_z %.2e "
          "soc %d slope %.2e %s evalfail %d filter %zu\n",
          iter, cur.f, mu, dual_inf, primal_inf, compl0, delta, alpha, alpha_max0, alpha_z, socs, slope,
          f_type ? "f" : "h", fails_eval, filter.size());
    std::swap(cur, trial);
    // Slack reset: a row side whose value is above its slack takes it as its slack (the
    // barrier function and the infeasibility only fall: -mu log s and |c - s| both do).
    for (std::size_t k = 0; k < mr; ++k) cur.s[k] = std::max(cur.s[k], cur.c[mb + k]);
    for (std::size_t k = 0; k < mb + mr; ++k) {
      z[k] += alpha_z * dz[k];
      const double zc = mu / slack(cur, k);
      z[k] = std::clamp(z[k], zc / kSigma, zc * kSigma);
    }
  }
}

}  // namespace geotraj::optim::detail
